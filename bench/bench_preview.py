"""Preview time and peak memory on the largest copper layers of the corpus.

    python bench/bench_preview.py            # the four files below
    python bench/bench_preview.py --quick    # the largest copper layer only
    python bench/bench_preview.py --files geda-pcb/hellboard/hellboard.group1.gbr

Each file is previewed twice, each time in a fresh child process, so a peak RSS
belongs to one run only:

* `cli`: `python -m galileo_cnc preview FILE -o OUT.png` exactly as a user runs it
  (read, plan, simulate, render, save); wall time and the child's peak RSS
  (`os.wait4`'s rusage, ru_maxrss);
* `phases`: the same steps timed one by one in a child: plan (read + plan_file),
  simulate (the step trace) and render (render_preview, image saved included).
  Before render the child returns freed memory to the OS (glibc `malloc_trim`) and
  resets its peak RSS (Linux: `/proc/self/clear_refs` 5), so "render peak" is the
  highest RSS while rendering, the trace included, and "+MB" is that minus the RSS
  the render started from: what rendering adds.

Numbers are printed, never asserted; the ratios compare with the numbers measured
with this script on the code before the streaming renderer (BEFORE, commit af44b24,
same machine; docs/preview.md). The corpus files are read in place.

The LimeSDR top layer is 202.4 mm wide with its travel moves, over the 200 mm of
the default machine: it runs with a profile of 300 mm travel (written to a
temporary directory). It has the longest trace of the corpus's copper layers
(48.6 M steps).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

from corpus import CORPUS  # noqa: E402  (tests/corpus.py: where the corpus lives)

BIG_TRAVEL = "[machine]\nx_travel_mm = 300.0\ny_travel_mm = 300.0\n"

# (corpus path, needs the big-travel profile); largest copper layers first.
FILES = [
    ("geda-pcb/hellboard/hellboard.group1.gbr", False),              # 1.62 MB, the largest
    ("altium/limesdr-qpcie/LimeSDR-QPCIe_1v2.GTL", True),            # 1.18 MB, 48.6 M steps
    ("kicad/atmega328-motor-board/ATMEGA328_Motor_Board-F.Cu.gtl", False),  # 721 kB
    ("geda-pcb/hellboard/hellboard.back.gbr", False),                # 711 kB, 12.6 M steps
]

# Measured with this script on the code before the streaming renderer (commit
# af44b24's galileo_cnc/preview, 2 cpus), mean of 4 runs: cli seconds, cli peak
# MB, render seconds, render + MB.
BEFORE = {
    "geda-pcb/hellboard/hellboard.group1.gbr": (4.81, 553, 2.80, 412),
    "altium/limesdr-qpcie/LimeSDR-QPCIe_1v2.GTL": (17.94, 3148, 10.77, 2542),
    "kicad/atmega328-motor-board/ATMEGA328_Motor_Board-F.Cu.gtl": (2.74, 565, 1.86, 439),
    "geda-pcb/hellboard/hellboard.back.gbr": (4.42, 988, 3.45, 781),
}

MB = 2 ** 20


# --------------------------------------------------------------------------- child


def _rss_now() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


def _rss_peak() -> int:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _trim() -> None:
    """Hand the memory simulate freed back to the OS (glibc keeps it otherwise, and
    the render would reuse it unseen): the RSS is then what is live, the trace."""
    import ctypes
    import gc

    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def child(path: str, profile: str | None, out: str) -> None:
    from galileo_cnc.config.profile import load_profile
    from galileo_cnc.machine import simulate
    from galileo_cnc.plan.pipeline import plan_file
    from galileo_cnc.preview.render import render_preview
    from galileo_cnc.program.ops import NM_PER_MM

    config = load_profile(profile).config
    t0 = time.perf_counter()
    planned = plan_file(path, config, "auto", margin_nm=round(1.0 * NM_PER_MM), group=True)
    t1 = time.perf_counter()
    trace = simulate(planned.job.commands, config)
    t2 = time.perf_counter()
    before_peak = _rss_peak()
    _trim()
    try:  # reset the peak so the one after render is the render's own
        with open("/proc/self/clear_refs", "w") as clear:
            clear.write("5")
        reset = True
    except OSError:
        reset = False
    start_rss = _rss_now()
    t3 = time.perf_counter()
    info = render_preview(planned.program, trace, config, planned.offset_nm, out)
    t4 = time.perf_counter()
    print(json.dumps({"plan_s": t1 - t0, "sim_s": t2 - t1, "render_s": t4 - t3,
                      "steps": len(trace), "sim_peak": before_peak, "render_start": start_rss,
                      "render_peak": _rss_peak() if reset else None,
                      "summary": info.summary()}), flush=True)


# --------------------------------------------------------------------------- parent


def run_child(argv: list[str]) -> tuple[float, int, str, int]:
    """(wall s, peak RSS bytes, output, exit status) of one child process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            cwd=REPO)
    out = proc.stdout.read()
    proc.stdout.close()
    _, status, usage = os.wait4(proc.pid, 0)   # this child's own rusage
    proc.returncode = os.waitstatus_to_exitcode(status)
    return time.perf_counter() - t0, usage.ru_maxrss * 1024, out, proc.returncode


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the largest copper layer only")
    ap.add_argument("--files", nargs="+", help="corpus paths instead of the default list")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        path, profile, out = args.child
        child(path, None if profile == "-" else profile, out)
        return 0

    if not (CORPUS / "MANIFEST.tsv").exists():
        print(f"no corpus at {CORPUS}", file=sys.stderr)
        return 2
    files = [(f, f in dict(FILES) and dict(FILES)[f]) for f in args.files] if args.files \
        else FILES[:1] if args.quick else FILES
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cpus; one child process per run")
    head = (f"{'file':44s} {'kB':>6s} {'Msteps':>6s} | {'cli s':>6s} {'peak MB':>7s} | "
            f"{'plan s':>6s} {'sim s':>6s} {'sim MB':>6s} | {'render s':>8s} {'peak MB':>7s} "
            f"{'+MB':>5s} | {'cli x':>6s} {'peak x':>6s} {'rend x':>6s} {'+MB x':>6s}")
    print(head)
    print("-" * len(head))
    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "big-travel.toml"
        big.write_text(BIG_TRAVEL)
        for rel, needs_big in files:
            source = CORPUS / rel
            profile = ["--profile", str(big)] if needs_big else []
            out = str(Path(tmp) / "preview.png")
            wall, peak, text, status = run_child(
                [sys.executable, "-m", "galileo_cnc", "preview", str(source), "-o", out, *profile])
            if status:
                print(f"{rel}: preview failed ({status}): {text.strip()[-300:]}")
                continue
            _, _, text, status = run_child(
                [sys.executable, __file__, "--child", str(source),
                 str(big) if needs_big else "-", out])
            if status:
                print(f"{rel}: phases failed ({status}): {text.strip()[-300:]}")
                continue
            phase = json.loads(text.strip().splitlines()[-1])
            render_peak = phase["render_peak"]
            extra = None if render_peak is None else render_peak - phase["render_start"]
            ratios = ""
            if rel in BEFORE:
                b_wall, b_peak, b_render, b_extra = BEFORE[rel]
                ratios = (f"{b_wall / wall:5.1f}x {b_peak / (peak / MB):5.1f}x "
                          f"{b_render / phase['render_s']:5.1f}x "
                          + (f"{b_extra / max(extra / MB, 1):5.1f}x" if extra is not None else ""))
            name = rel if len(rel) <= 44 else "..." + rel[-41:]
            print(f"{name:44s} {source.stat().st_size / 1000:6.0f} {phase['steps'] / 1e6:6.1f} | "
                  f"{wall:6.2f} {peak / MB:7.0f} | {phase['plan_s']:6.2f} {phase['sim_s']:6.2f} "
                  f"{phase['sim_peak'] / MB:6.0f} | {phase['render_s']:8.2f} "
                  + (f"{render_peak / MB:7.0f} {extra / MB:5.0f}" if render_peak else
                     f"{'?':>7s} {'?':>5s}")
                  + f" | {ratios}", flush=True)
            print(f"{'':44s} {phase['summary']}", flush=True)
    print("x = before / now (BEFORE: this script on commit af44b24); cli = the whole command; "
          "+MB = what rendering adds to the RSS it starts from")
    return 0


if __name__ == "__main__":
    sys.exit(main())
