"""Both sides of every corpus board with drill files, measured from the reference steps
(issue 32's third "Must show" line).

    python3 bench/bench_boards.py                          # every board (15+ minutes)
    python3 bench/bench_boards.py --quick                  # four boards, a minute or two
    python3 bench/bench_boards.py --board mchck --board arduino-uno --pads 5

A board is the Gerber folder <corpus>/<tool>/<board>/ and its drill folder
<corpus>/drill/<tool>/<board>/, linked into one temporary folder (as
tests/readers/test_board.py does). Each side with a copper file (the top and the
bottom; the bottom alone on a board whose folder has no top copper) is planned as
`plot BOARD --side top|bottom` plans it (plan_board: the default profile, ink mode,
the default drill marks), stepped by the reference machine (machine.simulate), and
measured. A board wider or taller than the default 200 mm travel is planned for a
BIG_TRAVEL_MM machine (the row says so); a folder holding two files of one copper
role is planned with the --layer override in LAYERS (the row says which).

- turn-over: every bottom hole, turned over about the axis where the side's line says
  it lies on the machine, against its top hole: the worst distance in steps, from the
  planned holes and the job's offset ("holes"); and from the steps themselves: both
  sides planned again with registration=True, the crosses found in the pen-down runs
  as tests/plan/test_sides.py finds them ("crosses"; "n/m" when only n of m crosses are
  drawn whole on both sides);
- ink in the marks: the pen-down steps near the marks swept by the pen
  (tests/drilled.py's ink_near), 10 um pixels inside a mark (0 expected);
- the copper outside the marks inked as before: round each mark (0.8 mm, its pad, as
  tests/plan/test_drill_marks.py does) the copper less the marks and their clearance,
  the share of it the steps ink with the marks and with the side planned again with
  drill_marks="none": all pads together and the worst pad, with / without (99 %
  expected with marks; a pad under it without marks too is the ink's, not the marks');
  `--pads N` lists each side's N pads the marks lower most;
- islands bridged: islands of the side's copper that the ink near the marks joins or
  brings within 30 um (tests/inked.py's joined_islands; 0 expected), and with the
  crosses, the ink near them ("isl+x").

One row per board and side with the planning time of the default plan, and total
lines. A board whose side takes over --limit seconds (90) to plan, or that plan_board
refuses, is skipped with the reason. Numbers are printed, never asserted. The ink near
the marks is taken tile by tile (5 mm), from the steps near each tile, so a board of
thousands of vias needs neither one huge sweep nor a pass over every step per pad.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import signal
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "tests" / "plan"))

from corpus import CORPUS  # noqa: E402
from drilled import ink_near, pixels_inside  # noqa: E402
from inked import joined_islands  # noqa: E402
from test_sides import crosses_in_steps  # noqa: E402

from galileo_cnc.config.machine import MachineConfig  # noqa: E402
from galileo_cnc.machine import simulate  # noqa: E402
from galileo_cnc.plan import sides  # noqa: E402
from galileo_cnc.plan.board_plan import BoardChoice, plan_board, side_options  # noqa: E402
from galileo_cnc.plan.ink import clip  # noqa: E402
from galileo_cnc.plan.planner import PlanError  # noqa: E402
from galileo_cnc.program.drills import Hole  # noqa: E402
from galileo_cnc.program.extents import extents  # noqa: E402
from galileo_cnc.readers.board import open_board  # noqa: E402

PAD_NM = 800_000        # round each mark: its pad (tests/plan/test_drill_marks.py)
TILE_NM = 5_000_000
GAP_NM = 30_000         # islands closer than this count as joined (tests/inked.py)
#: a board bigger than the default travel is planned for a machine this big
BIG_TRAVEL_MM = 400.0
#: --quick: a board of each kind of trouble (pads of every shape, a cross by a long
#: trace, marks 0.5 mm apart, a bottom-only board)
#: boards whose folder holds two files of one copper role (pcb-tools-example: two
#: revisions of the top, copper.GTL and top_copper.GTL, over the same box): the bench
#: plans the set named like the rest (top_copper, bottom_copper), as the user would
LAYERS = {"eagle/pcb-tools-example": ("copper.GTL=other",)}
QUICK = ("kicad/flashpads-x2ap", "eagle/8bit-mixtape", "upverter/sportiduino",
         "diptrace/panel")


class TooSlow(Exception):
    pass


def _alarm(_signum, _frame):
    raise TooSlow


def timed_plan(folder: Path, config: MachineConfig, choice: BoardChoice, limit_s: int):
    """plan_board within `limit_s` seconds: (planned, seconds); TooSlow past it."""
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(limit_s)
    start = time.perf_counter()
    try:
        planned = plan_board(folder, config, choice=choice)
    finally:
        signal.alarm(0)
    return planned, time.perf_counter() - start


class Stepped:
    """A trace's steps, worked out once and bucketed on a CELL_NM grid, so the ink near
    a tile is taken from the steps near it (and their neighbours) rather than from the
    whole board's: `near(box)` is a trace of those stretches, each cut off from the
    next by a pen-up row, that ink_near reads as it reads the whole trace."""

    CELL_NM = 2_000_000

    def __init__(self, trace, config: MachineConfig, offset_nm: tuple[int, int]):
        self._where = trace.positions()
        self._up = config.pen_down_z_steps + 1
        points = self._where[:, :2] * config.nm_per_step + np.asarray(offset_nm)
        cells = points // self.CELL_NM
        self._origin = cells.min(axis=0) if len(cells) else np.zeros(2, dtype=np.int64)
        cells -= self._origin
        self._width = int(cells[:, 0].max()) + 1 if len(cells) else 1
        keys = cells[:, 1] * self._width + cells[:, 0]
        self._order = np.argsort(keys, kind="stable")
        self._keys = keys[self._order]

    def near(self, box: tuple[int, int, int, int]) -> "_Part":
        x0, y0, x1, y1 = (np.array(box).reshape(2, 2) // self.CELL_NM - self._origin).ravel()
        x0, x1 = max(x0, 0), min(x1, self._width - 1)
        chosen = []
        for row in range(max(y0, 0), y1 + 1):
            lo = np.searchsorted(self._keys, row * self._width + x0)
            hi = np.searchsorted(self._keys, row * self._width + x1, side="right")
            chosen.append(self._order[lo:hi])
        index = np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.int64)
        total = len(self._where)
        index = np.unique(np.concatenate([index - 1, index, index + 1]))
        index = index[(index >= 0) & (index < total)]
        breaks = np.flatnonzero(np.diff(index) > 1) + 1
        pieces = np.split(index, breaks)
        rows = []
        for piece in pieces:
            rows.append(self._where[piece])
            rows.append(np.array([[0, 0, self._up]], dtype=self._where.dtype))
        return _Part(np.concatenate(rows) if rows else np.zeros((0, 3), dtype=np.int64))


class _Part:
    def __init__(self, where):
        self._where = where

    def positions(self, start=(0, 0, 0)):
        return self._where


def board_folders(corpus: Path) -> list[str]:
    drill = corpus / "drill"
    return [f"{tool.name}/{board.name}" for tool in sorted(drill.iterdir()) if tool.is_dir()
            for board in sorted(tool.iterdir()) if board.is_dir()]


def link_board(corpus: Path, name: str, into: Path) -> Path:
    folder = into / name.replace("/", "_")
    folder.mkdir()
    for source in (corpus / name, corpus / "drill" / name):
        if source.is_dir():
            for path in sorted(source.iterdir()):
                if path.is_file() and not path.name.startswith("UPSTREAM") \
                        and not (folder / path.name).exists():
                    os.symlink(path, folder / path.name)
    return folder


def tiles(marks: list) -> list[list]:
    """The marks' components grouped by the TILE_NM square their centre is in."""
    groups: dict[tuple[int, int], list] = {}
    for outer, holes in clip.components(marks):
        cx, cy = outer.mean(axis=0)
        groups.setdefault((int(cx // TILE_NM), int(cy // TILE_NM)), []).append((outer, holes))
    return [[ring for outer, holes in group for ring in (outer, *holes)]
            for _key, group in sorted(groups.items())]


def box_of(polygons: list, grow_nm: int) -> tuple[int, int, int, int]:
    outers = [outer for outer, _holes in clip.components(polygons)]
    low = np.min([o.min(axis=0) for o in outers], axis=0) - grow_nm
    high = np.max([o.max(axis=0) for o in outers], axis=0) + grow_nm
    return int(low[0]), int(low[1]), int(high[0]), int(high[1])


def measure_marks(planned, before, config: MachineConfig, pen_nm: int) -> dict:
    """Ink in the marks; each pad's copper outside the marks inked with the marks and
    without them (the same side planned with drill_marks="none"); islands joined by
    the ink near them."""
    if not planned.marks:
        return {"marks": 0, "pixels": 0, "pads": [], "joined": 0}
    stepped = Stepped(simulate(planned.job.commands, config), config, planned.offset_nm)
    stepped_before = Stepped(simulate(before.job.commands, config), config, before.offset_nm)
    copper = planned.ink.copper.native
    reach = pen_nm + 4 * config.nm_per_step
    # the copper round the marks less the marks (and their clearance), once; each tile
    # takes the pieces whose box meets its own
    outside = clip.components(clip.difference(
        clip.intersection(copper, clip.offset(planned.marks, PAD_NM, 1000)), planned.ink.bare))
    low = np.array([outer.min(axis=0) for outer, _holes in outside]).reshape(-1, 2)
    high = np.array([outer.max(axis=0) for outer, _holes in outside]).reshape(-1, 2)
    pixels, pads, near = 0, [], []
    for tile_marks in tiles(planned.marks):
        window = clip.offset(tile_marks, PAD_NM, 1000)
        box = box_of(window, reach)
        ink = ink_near(stepped.near(box), config, planned.offset_nm, pen_nm, window)
        ink_before = ink_near(stepped_before.near(box), config, before.offset_nm, pen_nm,
                              window)
        near.append(ink)
        pixels += pixels_inside(clip.intersection(ink, tile_marks)) if ink else 0
        x0, y0, x1, y1 = box
        meets = (high[:, 0] >= x0) & (low[:, 0] <= x1) & (high[:, 1] >= y0) & (low[:, 1] <= y1)
        copper_here = [ring for k in np.flatnonzero(meets)
                       for ring in (outside[k][0], *outside[k][1])]
        for outer, _holes in clip.components(tile_marks):
            pad = clip.intersection(copper_here, clip.offset([outer], PAD_NM, 1000))
            area = clip.area_nm2(pad) if pad else 0.0
            if not area:
                continue
            had = clip.area_nm2(clip.intersection(ink_before, pad)) if ink_before else 0.0
            has = clip.area_nm2(clip.intersection(ink, pad)) if ink else 0.0
            pads.append(Pad(tuple(outer.mean(axis=0).round().astype(int).tolist()),
                            area, has, had))
    ink = clip.union(*[piece for piece in near if piece]) if any(near) else []
    return {"marks": len(clip.components(planned.marks)), "pixels": pixels, "pads": pads,
            "joined": len(joined_islands(ink, copper, GAP_NM))}


@dataclass(frozen=True)
class Pad:
    """The copper round one mark (PAD_NM) less the marks: its area and how much of it
    the ink covers with the marks and without them (nm^2)."""

    centre_nm: tuple[int, int]
    area: float
    inked: float
    inked_before: float

    @property
    def share(self) -> float:
        return self.inked / self.area

    @property
    def share_before(self) -> float:
        return self.inked_before / self.area


def pads_summary(pads: list[Pad]) -> dict:
    """All pads together with and without marks, and the worst pad with marks."""
    if not pads:
        return {"with": None, "without": None, "worst": None}
    area = sum(p.area for p in pads)
    return {"with": sum(p.inked for p in pads) / area,
            "without": sum(p.inked_before for p in pads) / area,
            "worst": min(pads, key=lambda p: (p.share, -p.share_before))}


def on_machine(point, offset_nm, step_nm) -> tuple[float, float]:
    return ((point[0] - offset_nm[0]) / step_nm, (point[1] - offset_nm[1]) / step_nm)


def turned_over(axis, offset_nm, step_nm, point) -> tuple[float, float]:
    """A machine point (steps) turned over about the axis where it lies on the machine."""
    x, y = point
    if axis.axis == "x":
        return (2 * (axis.twice_nm / 2 - offset_nm[0]) / step_nm - x, y)
    return (x, 2 * (axis.twice_nm / 2 - offset_nm[1]) / step_nm - y)


def drill_points(drills) -> list[tuple[int, int]]:
    points = []
    for drill in drills:
        if isinstance(drill, Hole):
            points.append((drill.x_nm, drill.y_nm))
        else:
            points += [(drill.x0_nm, drill.y0_nm), (drill.x1_nm, drill.y1_nm)]
    return points


def holes_turned_over(top, bottom, step_nm) -> float:
    """The worst distance (steps) from a bottom hole turned over to its top hole."""
    if top.offset_nm != bottom.offset_nm:
        return math.inf
    worst = 0.0
    for t, b in zip(drill_points(top.holes), drill_points(bottom.holes)):
        tx, ty = on_machine(t, top.offset_nm, step_nm)
        bx, by = turned_over(bottom.axis, bottom.offset_nm, step_nm,
                             on_machine(b, bottom.offset_nm, step_nm))
        worst = max(worst, math.hypot(bx - tx, by - ty))
    return worst


def crosses_of(planned, crosses_nm, config) -> tuple[list, object]:
    """Each cross as the steps drew it (None: not drawn whole), and the trace."""
    trace = simulate(planned.job.commands, config)
    found = []
    for cross in crosses_nm:
        try:
            found += crosses_in_steps(trace, [on_machine(cross, planned.offset_nm,
                                                         config.nm_per_step)])
        except AssertionError:
            found.append(None)
    return found, trace


def measure_crosses(folder: Path, config: MachineConfig, pen_nm: int, limit_s: int,
                    copper_sides: tuple[str, ...], layers: tuple[str, ...]) -> dict:
    """The sides with registration crosses: each bottom cross from the steps, turned
    over, against its top cross (both sides only); islands the ink near the crosses
    joins."""
    board = open_board(folder, layers)
    try:
        _copper, options = side_options(board, BoardChoice(side=copper_sides[0],
                                                           registration=True, layers=layers))
    finally:
        board.close()
    outline_box = extents(options.outline_program) if options.outline_program else None
    board_crosses = sides.registration_points(options.holes, outline_box)
    found, joined = {}, 0
    for side in copper_sides:
        planned, _seconds = timed_plan(folder, config, BoardChoice(
            side=side, registration=True, layers=layers), limit_s)
        crosses = board_crosses if side == "top" else \
            [planned.axis.point(x, y) for x, y in board_crosses]
        found[side], trace = crosses_of(planned, crosses, config)
        around = clip.union(*[clip.stroke([[list(c)]], sides.CROSS_ARM_NM, 1000)
                              for c in crosses])
        ink = ink_near(trace, config, planned.offset_nm, pen_nm, around)
        joined += len(joined_islands(ink, planned.ink.copper.native, GAP_NM))
        found[side + "_offset"], found[side + "_axis"] = planned.offset_nm, planned.axis
    both = len(copper_sides) == 2
    pairs = [(t, b) for t, b in zip(found.get("top", []), found.get("bottom", []))
             if t is not None and b is not None]
    worst = None
    for t, b in pairs:
        bx, by = turned_over(found["bottom_axis"], found["bottom_offset"],
                             config.nm_per_step, b)
        worst = max(worst or 0.0, math.hypot(bx - t[0], by - t[1]))
    if both and found["top_offset"] != found["bottom_offset"]:
        worst = math.inf
    return {"crosses": len(board_crosses), "paired": len(pairs), "worst": worst,
            "joined": joined, "both": both}


def percent(share) -> str:
    return "-" if share is None else f"{100 * share:.2f}"


def steps(value) -> str:
    return "-" if value is None else ("offsets differ" if value == math.inf else f"{value:.2f}")


def plan_sides(folder: Path, config: MachineConfig, copper_sides: tuple[str, ...],
               layers: tuple[str, ...], limit_s: int) -> tuple[dict, dict, MachineConfig]:
    """Each side planned as `plot BOARD --side` plans it: (plans, seconds, config). A
    board wider or taller than the default travel is planned with BIG_TRAVEL_MM of
    travel (a bigger machine's profile), so it is measured too."""
    planned, seconds = {}, {}
    for side in copper_sides:
        try:
            planned[side], seconds[side] = timed_plan(
                folder, config, BoardChoice(side=side, layers=layers), limit_s)
        except PlanError as problem:
            # refused before planning (the box), or by the planner (a move past an end)
            beyond = ("the machine's travel is", "beyond the travel's end",
                      "below the travel's start")
            if not any(words in str(problem) for words in beyond) \
                    or config.x_travel_mm >= BIG_TRAVEL_MM:
                raise
            return plan_sides(folder, dataclasses.replace(
                config, x_travel_mm=BIG_TRAVEL_MM, y_travel_mm=BIG_TRAVEL_MM),
                copper_sides, layers, limit_s)
    return planned, seconds, config


def pad_text(pad: Pad | None) -> str:
    if pad is None:
        return "-"
    x, y = pad.centre_nm
    return (f"{percent(pad.share)}/{percent(pad.share_before)} at "
            f"{x / 1e6:.2f},{y / 1e6:.2f}")


def bench_board(name, args, scratch, pen_nm, totals, skipped) -> None:
    """One board's rows (or the reason it is skipped)."""
    folder = link_board(args.corpus, name, Path(scratch))
    layers = LAYERS.get(name, ())
    board = open_board(folder, layers)
    copper_sides = tuple(side for side in ("top", "bottom") if board.files(f"{side}-copper"))
    board.close()
    if not copper_sides:
        skipped.append((name, "no copper file, top or bottom"))
        print(f"{name:34} skipped: no copper file, top or bottom")
        return
    config = MachineConfig()
    try:
        planned, seconds, config = plan_sides(folder, config, copper_sides, layers,
                                              args.limit)
    except TooSlow:
        skipped.append((name, f"a side took over {args.limit} s to plan"))
        print(f"{name:34} skipped: a side took over {args.limit} s to plan")
        return
    except Exception as problem:  # noqa: BLE001 - a bench reports and goes on
        skipped.append((name, f"{type(problem).__name__}: {problem}"))
        print(f"{name:34} skipped: {type(problem).__name__}: {problem}")
        return
    note = "" if config.x_travel_mm == MachineConfig().x_travel_mm else \
        f" (travel {config.x_travel_mm:g} mm)"
    note += "".join(f" (--layer {layer})" for layer in layers)
    try:
        registration = measure_crosses(folder, config, pen_nm, args.limit, copper_sides,
                                       layers)
    except TooSlow:
        registration = None
    both = len(copper_sides) == 2
    turn = holes_turned_over(planned["top"], planned["bottom"], config.nm_per_step) \
        if both else None
    for side, plan in planned.items():
        try:
            before, _s = timed_plan(folder, config,
                                    BoardChoice(side=side, drill_marks="none", layers=layers),
                                    args.limit)
            got = measure_marks(plan, before, config, pen_nm)
        except TooSlow:
            got = None
        last_row = side == copper_sides[-1]
        cross = "-"
        if last_row and registration is None:
            cross = "too slow"
        elif last_row and registration["both"]:
            cross = steps(registration["worst"])
            if registration["paired"] < registration["crosses"]:
                cross += f" {registration['paired']}/{registration['crosses']}"
        row = (f"{name:34} {side:6} {seconds[side]:6.1f} {len(plan.holes):5} ")
        if got is None:
            row += f"{'none-marks plan too slow':>52}"
        else:
            summary = pads_summary(got["pads"])
            row += (f"{got['marks']:5} {got['pixels']:6} {percent(summary['with']):>6} "
                    f"{percent(summary['without']):>6} {pad_text(summary['worst']):>30} "
                    f"{got['joined']:3}")
            totals["pixels"] += got["pixels"]
            totals["joined"] += got["joined"]
            if summary["with"] is not None:
                totals["sides"].append((summary["with"], summary["without"], name, side))
                totals["pads"] += [(p, name, side) for p in got["pads"]]
        row += f" {steps(turn) if side == 'bottom' else '-':>10} {cross:>12}"
        row += f" {registration['joined'] if registration and last_row else '-':>5}{note}"
        print(row, flush=True)
        if got is not None and args.pads:
            for pad in sorted(got["pads"], key=lambda p: p.share - p.share_before)[:args.pads]:
                print(f"    pad {pad_text(pad)} mm: {pad.area / 1e12:.3f} mm2 of copper "
                      "outside the marks")
        totals["rows"] += 1
        totals["plan_s"] += seconds[side]
    if turn is not None:
        totals["turn"] = max(totals["turn"], turn)
    if registration is not None:
        totals["joined_x"] += registration["joined"]
        if registration["worst"] is not None:
            totals["cross"] = max(totals["cross"], registration["worst"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--board", action="append", default=[],
                        help="NAME (tool/board or board), repeated; default: every board")
    parser.add_argument("--boards", default="", help="NAME,... as --board")
    parser.add_argument("--quick", action="store_true",
                        help=f"only {', '.join(QUICK)}: a minute's check")
    parser.add_argument("--pads", type=int, default=0,
                        help="list each side's N pads the marks lower most")
    parser.add_argument("--corpus", type=Path, default=CORPUS)
    parser.add_argument("--limit", type=int, default=90,
                        help="skip a board whose side takes longer to plan (s)")
    args = parser.parse_args()
    names = board_folders(args.corpus)
    wanted = args.board + [n for n in args.boards.split(",") if n] + \
        (list(QUICK) if args.quick else [])
    if wanted:
        unknown = [w for w in wanted
                   if not any(n == w or n.split("/")[1] == w for n in names)]
        if unknown:
            parser.error(f"no board {', '.join(unknown)} in {args.corpus / 'drill'}")
        names = [n for n in names if n in wanted or n.split("/")[1] in wanted]
    config = MachineConfig()
    pen_nm = min(config.pen_widths_nm)
    print(f"corpus {args.corpus}, {len(names)} boards; default profile, ink mode, "
          f"drill marks small; pen {pen_nm / 1e6:.2f} mm, step {config.nm_per_step} nm")
    print("inked %: the copper round the marks (0.8 mm) less the marks, inked with "
          "marks / without (drill marks none)")
    header = (f"{'board':34} {'side':6} {'plan s':>6} {'holes':>5} {'marks':>5} "
              f"{'ink px':>6} {'with %':>6} {'w/o %':>6} {'worst pad with/w/o % at mm':>30} "
              f"{'isl':>3} {'holes turn':>10} {'crosses turn':>12} {'isl+x':>5}")
    print(header)
    totals = {"rows": 0, "pixels": 0, "joined": 0, "joined_x": 0, "sides": [], "pads": [],
              "turn": 0.0, "cross": 0.0, "plan_s": 0.0}
    skipped = []
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        for name in names:
            try:
                bench_board(name, args, scratch, pen_nm, totals, skipped)
            except Exception as problem:  # noqa: BLE001 - a bench reports and goes on
                skipped.append((name, f"{type(problem).__name__}: {problem}"))
                print(f"{name:34} failed: {type(problem).__name__}: {problem}", flush=True)
    print_totals(totals, len(names) - len(skipped), time.perf_counter() - started)
    for name, why in skipped:
        print(f"skipped {name}: {why}")


def print_totals(totals: dict, boards: int, run_s: float) -> None:
    print(f"total: {totals['rows']} sides of {boards} boards planned in "
          f"{totals['plan_s']:.1f} s (run {run_s:.0f} s); ink pixels in marks "
          f"{totals['pixels']}; islands joined {totals['joined']} near the marks, "
          f"{totals['joined_x']} near the crosses; turn-over worst {steps(totals['turn'])} "
          f"steps (holes), {steps(totals['cross'])} steps (crosses)")
    if totals["sides"]:
        worst = min(totals["sides"])
        print(f"worst side: {worst[2]} {worst[3]}, {percent(worst[0])} % inked with marks, "
              f"{percent(worst[1])} % without")
    if totals["pads"]:
        pad, name, side = min(totals["pads"], key=lambda entry: entry[0].share)
        below = [p for p, _n, _s in totals["pads"] if p.share < 0.99]
        print(f"worst pad: {name} {side} {pad_text(pad)} mm (with/without marks); "
              f"{len(below)} of {len(totals['pads'])} pads under 99 % with marks, "
              f"{sum(p.share_before < 0.99 for p in below)} of them under 99 % without")
        pad, name, side = min(totals["pads"],
                              key=lambda entry: entry[0].share - entry[0].share_before)
        print(f"most lowered by the marks: {name} {side} {pad_text(pad)} mm")


if __name__ == "__main__":
    main()
