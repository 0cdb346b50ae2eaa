"""What a preview costs on top of its planning, on a 1 MB board with two pens (issue
31, item 15: "a preview costs its planning plus a few seconds"): the PNG as
`preview` draws it (the job's path from its commands, preview/job_path.py), the PNG
from the stepped trace (JobSteps: what it cost before, and what the path stands in
for), and the SVG (from the job's commands, vector).

    python bench/bench_preview_svg.py                     # LimeSDR top copper, 0.3,0.8 mm
    python bench/bench_preview_svg.py --file kicad/... --pens 0.3,0.8

The board is planned once (plan_file, as `preview` does); each render is timed in
wall and CPU seconds (this process's own; the planning's helper processes are not
counted in its CPU). Numbers are printed, never asserted: each render's time over
the SVG's, and the whole preview over the planning alone.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from corpus import CORPUS  # noqa: E402  (tests/corpus.py: where the corpus lives)

# 1.18 MB, 202.4 mm wide with its travel: run with 300 mm of travel
DEFAULT_FILE = "altium/limesdr-qpcie/LimeSDR-QPCIe_1v2.GTL"
BIG_TRAVEL = "[machine]\nx_travel_mm = 300.0\ny_travel_mm = 300.0\n"


def child(path: str, pens: str, profile: str, out: str) -> None:
    from galileo_cnc.config.machine import pen_widths_from_text
    from galileo_cnc.config.profile import load_profile
    from galileo_cnc.machine.planner import JobSteps
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file
    from galileo_cnc.preview.job_path import JobPath
    from galileo_cnc.preview.render import render_preview
    from galileo_cnc.preview.svg import render_svg

    config = load_profile(profile).config
    config = config.replace(pen_widths_mm=pen_widths_from_text(pens))

    def timed(work):
        wall, cpu = time.perf_counter(), time.process_time()
        result = work()
        return result, time.perf_counter() - wall, time.process_time() - cpu

    def png(source, name):
        return render_preview(planned.program, source(planned.job.commands, config), config,
                              planned.offset_nm, f"{out}-{name}.png", job=planned.job,
                              copper=planned.copper)

    planned, *plan = timed(lambda: plan_file(path, config, options=PlanOptions(mode="ink")))
    svg, *svg_t = timed(lambda: render_svg(planned.program, planned.job, config,
                                           planned.offset_nm, f"{out}.svg",
                                           copper=planned.copper))
    path_png, *path_t = timed(lambda: png(JobPath, "path"))
    stepped_png, *stepped_t = timed(lambda: png(JobSteps, "stepped"))
    print(f"  {len(planned.job)} commands, {len(planned.program)} ink rows")
    print(f"  {'plan':24s} {plan[0]:7.1f} s wall {plan[1]:7.1f} s CPU")
    for name, (wall, cpu), info, file in (
            ("PNG (path, `preview`)", path_t, path_png, f"{out}-path.png"),
            ("PNG (stepped trace)", stepped_t, stepped_png, f"{out}-stepped.png"),
            ("SVG", svg_t, svg, f"{out}.svg")):
        size = Path(file).stat().st_size / 1e6
        print(f"  {name:24s} {wall:7.1f} s wall {cpu:7.1f} s CPU  {size:5.1f} MB  "
              f"{wall / svg_t[0]:5.1f}x the SVG's wall")
        print(f"      {info.summary()}")
    print(f"preview = planning + {path_t[0]:.1f} s (PNG) or + {svg_t[0]:.1f} s (SVG); "
          f"whole PNG preview / planning alone: {(plan[0] + path_t[0]) / plan[0]:.2f}x wall "
          f"(from the stepped trace: {(plan[0] + stepped_t[0]) / plan[0]:.2f}x)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--file", default=DEFAULT_FILE, help="a corpus path")
    ap.add_argument("--pens", default="0.3,0.8")
    args = ap.parse_args(argv)
    source = CORPUS / args.file
    if not source.is_file():
        print(f"no {source}", file=sys.stderr)
        return 2
    print(f"{args.file}: {source.stat().st_size / 1e6:.2f} MB, pens {args.pens} mm, "
          f"{os.cpu_count()} cpus")
    with tempfile.TemporaryDirectory() as tmp:
        profile = Path(tmp) / "big-travel.toml"
        profile.write_text(BIG_TRAVEL)
        child(str(source), args.pens, str(profile), f"{tmp}/preview")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
