"""Time the ink planner alone (read, then ink_program) on a few copper layers.

    python3 bench/bench_ink_plan.py                       # the biggest corpus layers
    python3 bench/bench_ink_plan.py FILE [FILE ...] --pens 0.3,0.8

Prints, per file: read and ink seconds, rows of the ink program, the share of the
copper inked (exact geometry, not the steps: bench_ink.py measures the steps), narrow
features and bridges avoided. Numbers are printed, never asserted.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from galileo_cnc.plan.ink.inking import ink_program
from galileo_cnc.readers import read_file

CORPUS = Path(__file__).resolve().parents[2] / "shared" / "corpus" / "gerber"
BIGGEST = ["geda-pcb/hellboard/hellboard.group1.gbr", "altium/limesdr-qpcie/LimeSDR-QPCIe_1v2.GTL",
           "allegro/minnowmax-reva1/MinnowMax_lyr1_GAF.art", "eagle/pcb-tools-example/copper.GTL",
           "allegro/tracespace-371/l1_primary.art"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", help="Gerber files (default: the biggest layers)")
    parser.add_argument("--pens", default="0.3", help="pen widths in mm, e.g. 0.3,0.8")
    args = parser.parse_args()
    pens = tuple(round(float(w) * 1_000_000) for w in args.pens.split(","))
    files = [Path(f) for f in args.files] or [CORPUS / f for f in BIGGEST]
    for path in files:
        began = time.perf_counter()
        program = read_file(path)
        read_s = time.perf_counter() - began
        plan = ink_program(program, pens)
        share = 100 * plan.inked_nm2 / plan.copper_nm2 if plan.copper_nm2 else 100.0
        print(f"{path.name}: read {read_s:.1f} s, ink {plan.seconds:.1f} s, "
              f"{len(plan.program)} rows, {share:.2f} % inked, {len(plan.narrow)} narrow, "
              f"{len(plan.bridges)} bridges avoided", flush=True)


if __name__ == "__main__":
    main()
