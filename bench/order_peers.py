"""vpype for bench_order.py: its own virtual environment, and the child that runs it.

vpype is never installed into the environment the package runs in (it would bring
its own numpy, shapely, scipy and click pins). `vpype_python()` makes, once, a venv
under ~/.cache/galileo-cnc-bench/vpype-venv (GALILEO_BENCH_CACHE moves the cache) with
`python3 -m venv` and `pip install vpype`, and returns its interpreter; later runs
reuse it. This file is also that interpreter's script: it imports nothing but the
standard library at the top, and numpy and vpype only in the child.

The child (`python order_peers.py --child IN OUT LISTING TIMEOUT JOIN`) reads, per file
k of the listing, IN/k.npz written by bench_order.py:

    start       (2,) float, the common start point (nm)
    groups      number of pens (groups), drawn one after another
    p{g}        (m, 2) float, the points of group g's paths, concatenated (nm)
    o{g}        (n + 1,) int, path i is p{g}[o[i]:o[i+1]]
    f{g}        (n,) bool, path i is a flash (two equal points)

and for each group, with the machine where vpype's previous group ended (the start for
the first one):

    lc = vp.LineCollection(paths)            # flashes left out: a flash never continues
    lc.merge(tolerance=JOIN, flip=True)      # = `linemerge --tolerance JOIN`
    sorted = linesort([anchor] + lc + flashes, no_flip=False, two_opt=True, passes=250)
                                             # = `linesort --two-opt`

`linesort` is the vpype_cli command's own function (the click command's callback
unwrapped), so the numbers are those of `vpype ... linemerge linesort --two-opt`.
vpype's linesort keeps its first line first and starts its nearest neighbour at that
line's end; the anchor, a 4-point zero-length line at the start point, is put first so
that vpype starts where ours does. Its 2-opt may still move the anchor (vpype's own
objective does not count the travel from the start); the child removes it wherever it
ends up, counts the groups where it moved and sums their first legs (from the start to
vpype's first line, which vpype did not try to shorten). Output OUT/k.npz has the same layout as the
input (the sorted paths, flashes told apart by matching zero-length 2-point lines
against the input's flash points), and one JSON line per file goes to stdout: merge_s,
sort_s, anchor_moved, first_leg, or timeout / error. TIMEOUT (s) bounds each file's
merge+sort through SIGALRM.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

CACHE = Path(os.environ.get("GALILEO_BENCH_CACHE",
                            Path.home() / ".cache" / "galileo-cnc-bench"))
VENV = CACHE / "vpype-venv"
PASSES = 250          # vpype's default for --two-opt


def _venv_python() -> Path:
    return VENV / "bin" / "python"


def _probe(python: Path) -> str | None:
    """vpype's version in that interpreter, None if it does not import."""
    if not python.exists():
        return None
    done = subprocess.run([str(python), "-c", "import vpype, vpype_cli; print(vpype.__version__)"],
                          capture_output=True, text=True, check=False)
    return done.stdout.strip() if done.returncode == 0 else None


def vpype_python(say=print) -> tuple[Path, str] | None:
    """(interpreter, vpype version) of the cached venv, made on first use; None (and
    `say` tells why) when it cannot be made, e.g. without network."""
    version = _probe(_venv_python())
    if version:
        return _venv_python(), version
    say(f"making the vpype venv at {VENV} (python3 -m venv; pip install vpype) ...")
    started = time.perf_counter()
    if VENV.exists():
        shutil.rmtree(VENV)            # a half-made venv of an earlier, failed try
    VENV.parent.mkdir(parents=True, exist_ok=True)
    steps = ([sys.executable, "-m", "venv", str(VENV)],
             [str(_venv_python()), "-m", "pip", "install", "--quiet", "vpype"])
    for command in steps:
        try:
            done = subprocess.run(command, capture_output=True, text=True, check=False,
                                  timeout=900)
        except (OSError, subprocess.TimeoutExpired) as problem:
            say(f"cannot make the vpype venv: {' '.join(command[:4])}: {problem}")
            return None
        if done.returncode:
            tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
            say(f"cannot make the vpype venv: {' '.join(command[:4])} exited "
                f"{done.returncode}: {' | '.join(tail)}")
            return None
    version = _probe(_venv_python())
    if not version:
        say("cannot make the vpype venv: vpype does not import after pip install")
        return None
    say(f"vpype {version} installed in {time.perf_counter() - started:.0f} s")
    return _venv_python(), version


# --------------------------------------------------------------------------- child


class _Timeout(Exception):
    pass


def _alarm(_signum, _frame):
    raise _Timeout()


def child(in_dir: Path, out_dir: Path, listing: list[int], timeout_s: float,
          join_nm: float) -> None:
    from collections import Counter

    import numpy as np
    import vpype as vp
    from vpype_cli.operations import linesort as command

    linesort = command.callback.__wrapped__      # the function behind `linesort`
    signal.signal(signal.SIGALRM, _alarm)
    for k in listing:
        record: dict = {"k": k}
        try:
            data = np.load(in_dir / f"{k}.npz")
            here = complex(*data["start"])
            out, merge_s, sort_s, moved, first_leg = {}, 0.0, 0.0, 0, 0.0
            signal.setitimer(signal.ITIMER_REAL, timeout_s)
            try:
                for g in range(int(data["groups"])):
                    points, offsets, flash = data[f"p{g}"], data[f"o{g}"], data[f"f{g}"]
                    line = points[:, 0] + 1j * points[:, 1]
                    paths = [line[offsets[i]:offsets[i + 1]] for i in range(len(flash))
                             if not flash[i]]
                    flashes = [line[offsets[i]:offsets[i + 1]] for i in range(len(flash))
                               if flash[i]]
                    lc = vp.LineCollection(paths)
                    t0 = time.perf_counter()
                    lc.merge(tolerance=join_nm, flip=True)
                    t1 = time.perf_counter()
                    anchor = np.full(4, here, dtype=complex)
                    todo = vp.LineCollection([anchor])
                    todo.extend(lc)
                    todo.extend(flashes)
                    t2 = time.perf_counter()
                    done = linesort(todo, no_flip=False, two_opt=True, passes=PASSES)
                    t3 = time.perf_counter()
                    merge_s += t1 - t0
                    sort_s += t3 - t2
                    lines = list(done)
                    at = next(i for i, ln in enumerate(lines)
                              if len(ln) == 4 and (ln == here).all())
                    del lines[at]
                    if at != 0:
                        moved += 1
                        first_leg += abs(lines[0][0] - here)
                    left = Counter(complex(f[0]) for f in flashes)
                    is_flash = []
                    for ln in lines:
                        mark = len(ln) == 2 and ln[0] == ln[1] and left[complex(ln[0])] > 0
                        if mark:
                            left[complex(ln[0])] -= 1
                        is_flash.append(mark)
                    joined = np.concatenate(lines) if lines else np.zeros(0, dtype=complex)
                    out[f"p{g}"] = np.stack([joined.real, joined.imag], axis=1)
                    out[f"o{g}"] = np.cumsum([0] + [len(ln) for ln in lines])
                    out[f"f{g}"] = np.array(is_flash, dtype=bool)
                    if lines:
                        here = complex(lines[-1][-1])
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            np.savez(out_dir / f"{k}.npz", groups=int(data["groups"]), **out)
            record.update(merge_s=merge_s, sort_s=sort_s, seconds=merge_s + sort_s,
                          anchor_moved=int(moved), first_leg=float(first_leg))
        except _Timeout:
            record["timeout"] = timeout_s
        except Exception as problem:  # noqa: BLE001 (a failure is a result too)
            record["error"] = f"{type(problem).__name__}: {problem}"[:200]
        print(json.dumps(record), flush=True)


if __name__ == "__main__":
    if len(sys.argv) == 7 and sys.argv[1] == "--child":
        child(Path(sys.argv[2]), Path(sys.argv[3]), json.loads(Path(sys.argv[4]).read_text()),
              float(sys.argv[5]), float(sys.argv[6]))
    else:
        found = vpype_python()
        print(found if found else "no vpype venv")
