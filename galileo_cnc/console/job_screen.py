"""A streamed job on screen: progress bar (lines, %, ETA), pen changes, q/Ctrl-C to stop.

The console's Operator (backends/base.py): what a job run by the Machine needs from
the user. The job streams in the calling thread; prompt_toolkit's ProgressBar runs
its own application in a second thread and owns the keyboard meanwhile, so the stop
and continue keys arrive here as key bindings and reach the streaming thread through
events. The machine's messages and the pen-change requests print above the bar.
"""

from __future__ import annotations

import threading
from typing import Callable

from prompt_toolkit.application.current import get_app_session
from prompt_toolkit.key_binding import KeyBindings
from prompt_toolkit.shortcuts import ProgressBar
from prompt_toolkit.shortcuts.progress_bar import formatters

from galileo_cnc.backends import JobResult
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.stream.streamer import (PenChange, Progress, StreamAborted,
                                         head_position_text)

BELL = "\a"
#: How often a pen-change wait looks for a stop request.
_WAIT_POLL_S = 0.1

RunJob = Callable[["JobScreen"], JobResult]     # the machine's run_job, with this Operator
STOP_HINT = "   (q or Ctrl-C stops, the machine ramps down)"
SHORT_STOP_HINT = "  (q stops)"


def fit_title(title: str, columns: int) -> str:
    """The bar's title within the terminal's width: the hint shortened first, then the
    file's path cut from the left (its name is what tells jobs apart)."""
    if len(title) + len(STOP_HINT) < columns:
        return title + STOP_HINT
    room = columns - 1 - len(SHORT_STOP_HINT)
    if len(title) > room:
        title = "..." + title[len(title) - max(room - 3, 1):]
    return title + SHORT_STOP_HINT


class ConsoleOperator:
    """The console as an Operator outside the progress bar (finding a resumed job's
    position): lines printed, questions asked at the prompt."""

    def __init__(self, console):
        self.console = console

    def say(self, text: str) -> None:
        self.console.say(text)

    def confirm(self, question: str) -> bool:
        return self.console.confirm(f"{BELL}{question}. Is it there?", default=False)

    def progress(self, p: Progress) -> None:
        pass

    def pen_change(self, change: PenChange) -> None:
        pass


class _MachineEta(formatters.Formatter):
    """ETA from the reference machine's timing (the streamer's), not from the rate so far."""

    def __init__(self, screen: "JobScreen"):
        self.screen = screen

    def format(self, progress_bar, progress, width):
        eta = self.screen.eta_s
        return f"ETA {duration_text(eta)}" if eta is not None else "ETA ?"

    def get_width(self, progress_bar):
        return 12


class _HeadPosition(formatters.Formatter):
    """Where the machine reports the head while it streams (GRBL answers `?` during a
    job); nothing from a machine that reports no position meanwhile."""

    def __init__(self, screen: "JobScreen"):
        self.screen = screen

    def format(self, progress_bar, progress, width):
        return head_position_text(self.screen.position_nm)

    def get_width(self, progress_bar):
        return len(head_position_text(self.screen.position_nm))


class JobScreen(ConsoleOperator):
    def __init__(self, console, title: str, total: int, start: int = 0):
        super().__init__(console)
        self.title = title
        self.total = total
        self.start = start
        self.eta_s: float | None = None
        self.position_nm: tuple[int, int, int] | None = None
        self.stop_requested = threading.Event()
        self._continue = threading.Event()
        self._abort_stream: Callable[[], None] | None = None
        self._counter = None

    def run(self, run_job: RunJob, abort_stream: Callable[[], None]) -> JobResult:
        """`run_job(self)` with the bar showing; `abort_stream` is called (from the key
        thread) when the user stops the job."""
        self._abort_stream = abort_stream
        columns = get_app_session().output.get_size().columns
        bar = ProgressBar(title=fit_title(self.title, columns),
                          formatters=self._formatters(), key_bindings=self._key_bindings(),
                          cancel_callback=self.request_stop)
        with bar:
            self._counter = bar(label="lines", total=self.total)
            self._counter.items_completed = self.start
            result = run_job(self)
            if result.completed:
                self._counter.items_completed = self.total
                self._counter.done = True
            else:
                self._counter.stopped = True
        return result

    def request_stop(self) -> None:
        if not self.stop_requested.is_set():
            self.stop_requested.set()
            self._continue.set()              # wakes a pen-change wait
            if self._abort_stream is not None:
                self._abort_stream()

    # ---- the Operator, called by the job in the streaming thread ---------------------------
    def progress(self, progress: Progress) -> None:
        self.eta_s = progress.eta_s
        self.position_nm = progress.position_nm
        self._counter.total = progress.total
        self._counter.items_completed = progress.confirmed
        self._counter.progress_bar.invalidate()

    def pen_change(self, change: PenChange) -> None:
        """With the machine idle and the pen up: ask for the pen, wait for Enter."""
        self._continue.clear()
        if not self.stop_requested.is_set():   # q may have come while the machine stopped
            self.console.say(f"{BELL}{change.prompt}, then press Enter (q stops)")
        while not (self.stop_requested.is_set() or self._continue.wait(_WAIT_POLL_S)):
            pass
        if self.stop_requested.is_set():
            raise StreamAborted("stopped by the user")

    # ---- layout and keys ------------------------------------------------------------------------
    def _formatters(self) -> list[formatters.Formatter]:
        return [formatters.Label(), formatters.Text(" "), formatters.Percentage(),
                formatters.Text(" "), formatters.Bar(sym_a="#", sym_b=">", sym_c="."),
                formatters.Text(" "), formatters.Progress(), formatters.Text("  "),
                _MachineEta(self), _HeadPosition(self)]

    def _key_bindings(self) -> KeyBindings:
        keys = KeyBindings()

        @keys.add("q")
        @keys.add("Q")
        def _stop(event) -> None:
            self.request_stop()

        @keys.add("enter")
        @keys.add("c-j")   # Enter typed while a message prints (cooked mode) arrives as \n
        def _go_on(event) -> None:
            self._continue.set()

        return keys
