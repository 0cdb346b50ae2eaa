"""Work done in a forked child while the caller goes on: the fill's second CPU.

The fill of a large pour spends seconds in Clipper, which holds the GIL, so threads
cannot share it out. Where the platform can fork, `Deferred(fn, *args)` runs
fn(*args) in a child that starts as a copy of this process (nothing to import or
send there) and sends back only the pickled result; elsewhere (Windows), or for
small work (`fork=False`), fn runs when the result is asked for. The answer is the
same either way. A forked copy of the process that made a Deferred (another
Deferred's child) has no child of its own to wait for: asked there, fn runs there.
"""

from __future__ import annotations

import os
import pickle
import signal
import traceback
import warnings
from typing import Any, Callable


class Deferred:
    """fn(*args), run in a forked child or here; `result()` waits for it."""

    def __init__(self, fn: Callable[..., Any], *args: Any, fork: bool = True):
        self._fn, self._args = fn, args
        self._owner = os.getpid()
        self._pid: int | None = None
        self._reader: int | None = None
        if fork and hasattr(os, "fork"):
            self._start()

    def _start(self) -> None:
        reader, writer = os.pipe()
        try:
            with warnings.catch_warnings():
                # Python 3.12+ warns when a process with threads (the console's, a
                # sim:// machine's) forks: the child touches nothing of theirs
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
        except OSError:                 # no memory or process left: run it here
            os.close(reader)
            os.close(writer)
            return
        if pid == 0:                    # the child: compute, send, leave at once
            code = 0
            try:
                os.close(reader)
                try:
                    payload = pickle.dumps((True, self._fn(*self._args)), protocol=5)
                except BaseException as problem:        # noqa: BLE001 - sent to the parent
                    payload = pickle.dumps((False, (problem, traceback.format_exc())))
                with os.fdopen(writer, "wb") as out:
                    out.write(payload)
            except BaseException:                       # noqa: BLE001
                code = 1
            finally:
                # no cleanup of the parent's objects (ports, files, threads) here
                os._exit(code)
        os.close(writer)
        self._pid, self._reader = pid, reader

    def result(self) -> Any:
        if self._pid is None or os.getpid() != self._owner:
            return self._fn(*self._args)
        with os.fdopen(self._reader, "rb") as source:
            payload = source.read()
        os.waitpid(self._pid, 0)
        self._pid = self._reader = None
        if not payload:                 # the child died without a word: do it here
            return self._fn(*self._args)
        ok, value = pickle.loads(payload)
        if ok:
            return value
        problem, _text = value
        raise problem

    def __del__(self) -> None:
        self.cancel()

    def cancel(self) -> None:
        """Stop a child whose result is no longer wanted (the caller failed, or the
        result was never asked for)."""
        if self._pid is not None and os.getpid() == self._owner:
            try:
                os.kill(self._pid, signal.SIGKILL)
                os.waitpid(self._pid, 0)
            except OSError:
                pass
            os.close(self._reader)
            self._pid = self._reader = None
