"""Machine time against the ideal bound, with a stop at every vertex and with junction
speeds, side by side in one run (docs/motion.md §5.7, issue 33).

    python3 bench/bench_motion.py                    # corpus copper (ink, centre) + DXF
    python3 bench/bench_motion.py --quick            # the samples only
    python3 bench/bench_motion.py --files 'kicad/*' --modes ink
    python3 bench/bench_motion.py --deviation 0.02 --axis-change 2.5 --json /tmp/m.json
    python3 bench/bench_motion.py --quick --modes ink --breakdown   # where the time goes
    python3 bench/bench_motion.py --quick --start-factor 2   # moves start at half the feed

Per file and mode the job is planned once (`plan_file`, the default MachineConfig with
2 m of travel so every board fits) and its moves are timed on the reference machine
(vector.last_event_ticks: the trace's ticks without the steps):

- ideal: every move at its cruise interval, no ramps (pen-down length at the feed,
  travel at the rapid feed, Z moves at the Z feed) plus the dwells: no machine with
  these feeds is faster;
- stops: today's machine, every move from rest to rest (with `--start-factor`, moves
  start at that factor in this column too);
- junction: the same moves with the junction speeds planned (`--deviation` mm, GRBL's
  $11, and `--axis-change` mm/s, the largest per-axis speed change at a vertex).

Columns: whole-job seconds and their ratio to the ideal; pen-down time (XY moves not at
the rapid feed) against pen-down length / feed; junction / stops for the whole job.
`--breakdown` adds per file where the junction-speed time over the ideal goes
(`breakdown`): pen-down time lost at the strokes' ends, turns back, turns of 45-90
degrees and gentle vertices (each move's loss split between its two ends), the share
in moves shorter than a ramp, and travel and Z time. Numbers are printed, never
asserted.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

from corpus import CORPUS, DXF_CORPUS, manifest  # noqa: E402

from galileo_cnc.config.hardware import TICKS_PER_S  # noqa: E402
from galileo_cnc.config.machine import MachineConfig  # noqa: E402
from galileo_cnc.machine import ReferenceMachine, vector  # noqa: E402
from galileo_cnc.machine.blocks import ArcMove, LineMove, Pause  # noqa: E402
from galileo_cnc.machine.junctions import JunctionLimits, plan_junctions  # noqa: E402
from galileo_cnc.machine.ramps import RHO_ONE, SUBTICKS_PER_S  # noqa: E402
from galileo_cnc.plan.pipeline import PlanOptions, plan_file  # noqa: E402

SAMPLES = ("samples/led-blinker.gbr", "samples/square-and-circle.nc")


def copper_layers() -> list[Path]:
    """The corpus's Gerber copper layers, as bench_ink_union.py picks them."""
    from bench_ink_union import copper_layers as relative_paths

    return [CORPUS / path for path in relative_paths()]


def dxf_drawings() -> list[Path]:
    return [DXF_CORPUS / row["path"] for row in manifest(DXF_CORPUS) if row["kind"] == "real"]


def _line_feed(move: LineMove) -> int:
    length_q15 = math.sqrt(sum(d * d for d in move.delta)) * RHO_ONE / move.n
    return round(SUBTICKS_PER_S * length_q15 / RHO_ONE / move.base_sub)


def pen_down(items, config: MachineConfig) -> list[bool]:
    """Which items draw: XY moves (no Z) not at the rapid feed."""
    rapid = config.rapid_steps_per_s
    return [isinstance(it, ArcMove)
            or (isinstance(it, LineMove) and not it.delta[2] and _line_feed(it) != rapid)
            for it in items]


def item_seconds(items) -> tuple[list[float], float]:
    """Each item's time (from the previous item's end; a pause's time lands in the next
    move) and the job's end, in seconds."""
    last, end = vector.last_event_ticks(items, 0)
    seconds, before = [], 0
    for tick in last.tolist():
        seconds.append((tick - before) / TICKS_PER_S if tick >= 0 else 0.0)
        before = tick if tick >= 0 else before
    return seconds, end / TICKS_PER_S


def _turn_class(a, b) -> str:
    """A blended-or-not vertex between two drawing moves, by its turn."""
    dot = sum(x * y for x, y in zip(a, b))
    if dot < -1e-9:
        return "reversal"
    if dot < 0.7071:
        return "sharp"          # 45-90 degrees, right angles included
    return "gentle"


def breakdown(items, planned, config: MachineConfig) -> dict[str, float]:
    """Where the machine time over the ideal goes (seconds): each pen-down move's time
    above its cruise time is split between its two ends, and each end is charged to the
    kind of vertex it has (a stroke's end at a pen lift, a reversal, a sharp turn of
    45-90 degrees, a gentle one); moves whose whole length is shorter than one ramp are
    also counted apart ("short", a share of the rest). Travel and Z moves: their whole
    time, ideal and loss."""
    from galileo_cnc.machine.junctions import move_ends

    drawing = pen_down(items, config)
    ideal_items = [it if isinstance(it, Pause) else replace(it, ramp=0, step_sub=0)
                   for it in items]
    ideal, _ = item_seconds(ideal_items)
    actual, _ = item_seconds(planned)
    out = {k: 0.0 for k in ("pen_down_ideal", "stroke_end", "reversal", "sharp", "gentle",
                            "short", "travel_ideal", "travel_loss", "z_ideal", "z_loss",
                            "pause")}
    counts = {k: 0 for k in ("stroke_end", "reversal", "sharp", "gentle", "short")}
    moves = [i for i, it in enumerate(items) if not isinstance(it, Pause) and it.n]
    nxt = {a: b for a, b in zip(moves, moves[1:])}
    prv = {b: a for a, b in zip(moves, moves[1:])}

    def kind(a, b) -> str:
        if a is None or b is None or not (drawing[a] and drawing[b]):
            return "stroke_end"
        if any(isinstance(items[j], Pause) for j in range(a + 1, b)):
            return "stroke_end"
        return _turn_class(move_ends(items[a])[1].direction, move_ends(items[b])[0].direction)

    for i, it in enumerate(items):
        if isinstance(it, Pause):
            out["pause"] += actual[i]
            continue
        loss = actual[i] - ideal[i]
        if drawing[i]:
            out["pen_down_ideal"] += ideal[i]
            ends = (kind(prv.get(i), i), kind(i, nxt.get(i)))
            for end in ends:
                out[end] += loss / 2
            if it.n < it.ramp:
                out["short"] += loss
                counts["short"] += 1
            if i in nxt:
                counts[ends[1]] += 1
        elif isinstance(it, LineMove) and it.delta[2]:
            out["z_ideal"] += ideal[i]
            out["z_loss"] += loss
        else:
            out["travel_ideal"] += ideal[i]
            out["travel_loss"] += loss
    out.update({f"n_{k}": v for k, v in counts.items()})
    return out


def print_breakdown(b: dict) -> None:
    lost = ", ".join(f"{k} {b[k]:.1f} s ({b['n_' + k]})"
                     for k in ("stroke_end", "reversal", "sharp", "gentle"))
    print(f"    pen-down ideal {b['pen_down_ideal']:.1f} s, lost at ends: {lost}; "
          f"of it in moves shorter than a ramp {b['short']:.1f} s ({b['n_short']})")
    print(f"    travel {b['travel_ideal']:.1f} + {b['travel_loss']:.1f} s, "
          f"Z {b['z_ideal']:.1f} + {b['z_loss']:.1f} s, pauses {b['pause']:.1f} s")


def measure(path: Path, mode: str, config: MachineConfig, limits: JunctionLimits,
            explain: bool = False) -> dict:
    started = time.perf_counter()
    job = plan_file(path, config, "auto", options=PlanOptions(mode=mode)).job
    items = ReferenceMachine(config).plan(job.commands)
    drawing = pen_down(items, config)
    ideal_items = [it if isinstance(it, Pause) else replace(it, ramp=0, step_sub=0)
                   for it in items]
    record = {"file": str(path), "mode": mode, "moves": sum(drawing)}
    junction = plan_junctions(items, limits)
    for name, planned in (("ideal", ideal_items), ("stops", items), ("junction", junction)):
        seconds, total = item_seconds(planned)
        record[name] = total
        record[f"{name}_pen_down"] = sum(s for s, d in zip(seconds, drawing) if d)
    if explain:
        record["breakdown"] = breakdown(items, junction, config)
    record["seconds"] = time.perf_counter() - started
    return record


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the samples only")
    parser.add_argument("--files", default="*", help="glob over corpus paths")
    parser.add_argument("--modes", default="ink,centre")
    parser.add_argument("--no-dxf", action="store_true")
    parser.add_argument("--deviation", type=float, default=0.01, help="mm (GRBL's $11)")
    parser.add_argument("--axis-change", type=float, default=None,
                        help="mm/s, the largest per-axis speed change at a vertex")
    parser.add_argument("--start-factor", type=int, default=None,
                        help="the ramp's start (ramp_start_factor: a move starts at this "
                             "x its period; 3 by default)")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--breakdown", action="store_true",
                        help="where the junction-speed time over the ideal goes, per file")
    args = parser.parse_args()
    config = MachineConfig(x_travel_mm=2000.0, y_travel_mm=2000.0)
    if args.start_factor is not None:
        config = config.replace(ramp_start_factor=args.start_factor)
    tuned = config.replace(junction_deviation_mm=args.deviation)
    if args.axis_change is not None:
        tuned = tuned.replace(vertex_speed_change_mm_s=args.axis_change)
    limits = JunctionLimits.of(tuned)
    modes = args.modes.split(",")
    jobs: list[tuple[Path, str]] = []
    if args.quick:
        jobs = [(REPO / p, m) for p in SAMPLES for m in (modes if p.endswith(".gbr") else ["centre"])]
    else:
        for path in copper_layers():
            if fnmatch.fnmatch(str(path.relative_to(CORPUS)), args.files):
                jobs += [(path, m) for m in modes]
        if not args.no_dxf:
            jobs += [(p, "centre") for p in dxf_drawings()
                     if fnmatch.fnmatch(str(p.relative_to(DXF_CORPUS)), args.files)]
    print(f"junction deviation {args.deviation:g} mm, per-axis change "
          f"{tuned.vertex_speed_change_mm_s:g} mm/s, accel {config.accel_mm_s2:g} mm/s2, "
          f"feed {config.feed_mm_s:g} mm/s, ramps from {config.ramp_start_factor}x the period")
    head = (f"{'file':52} {'mode':6} {'moves':>7} {'ideal s':>9} {'stops':>7} {'junct.':>7}"
            f" {'pd stops':>8} {'pd junct':>8} {'j/stops':>7}")
    print(head)
    records = []
    totals = {"ink": [0.0] * 5, "centre": [0.0] * 5}
    for path, mode in jobs:
        try:
            r = measure(path, mode, config, limits, args.breakdown)
        except Exception as problem:  # a file the planner refuses costs that file only
            print(f"{str(path)[-52:]:52} {mode:6} failed: {type(problem).__name__}: "
                  f"{str(problem)[:60]}")
            continue
        records.append(r)
        pd = r["ideal_pen_down"] or math.nan
        print(f"{str(path)[-52:]:52} {mode:6} {r['moves']:7d} {r['ideal']:9.1f} "
              f"{r['stops'] / r['ideal']:6.2f}x {r['junction'] / r['ideal']:6.2f}x "
              f"{r['stops_pen_down'] / pd:7.2f}x {r['junction_pen_down'] / pd:7.2f}x "
              f"{r['junction'] / r['stops']:7.2f}", flush=True)
        if args.breakdown:
            print_breakdown(r["breakdown"])
        t = totals[mode]
        for i, key in enumerate(("ideal", "stops", "junction", "ideal_pen_down",
                                 "junction_pen_down")):
            t[i] += r[key]
    for mode, (ideal, stops, junction, pd_ideal, pd_junction) in totals.items():
        if ideal:
            print(f"total {mode}: ideal {ideal:.0f} s, stops {stops / ideal:.3f}x, junction "
                  f"{junction / ideal:.3f}x (pen-down {pd_junction / max(pd_ideal, 1e-9):.3f}x), "
                  f"junction / stops {junction / stops:.3f}")
    if args.json:
        args.json.write_text(json.dumps(records, indent=1))


if __name__ == "__main__":
    main()
