"""Both sides of every corpus board with drill files, measured from the reference steps
(issue 32's third "Must show" line).

    python3 bench/bench_boards.py                          # every board
    python3 bench/bench_boards.py --boards kicad/mchck,flashpads-x2ap

A board is the Gerber folder <corpus>/<tool>/<board>/ and its drill folder
<corpus>/drill/<tool>/<board>/, linked into one temporary folder (as
tests/readers/test_board.py does). Each side with a copper file (the top; the bottom
where there is one) is planned as `plot BOARD --side top|bottom` plans it (plan_board:
the default profile, ink mode, the default drill marks), stepped by the reference
machine (machine.simulate), and measured:

- turn-over: every bottom hole, turned over about the axis where the side's line says
  it lies on the machine, against its top hole: the worst distance in steps, from the
  planned holes and the job's offset ("holes"); and from the steps themselves: both
  sides planned again with registration=True, the crosses found in the pen-down runs
  as tests/plan/test_sides.py finds them ("crosses"; "n/m" when only n of m crosses are
  drawn whole on both sides);
- ink in the marks: the pen-down steps near the marks swept by the pen
  (tests/drilled.py's ink_near), 10 um pixels inside a mark (0 expected);
- the copper outside the marks inked as before: the side planned again with
  drill_marks="none"; round each mark (0.8 mm, its pad, as tests/plan/test_drill_marks.py
  does) the copper less the marks and their clearance inked by the steps, against the
  same copper inked without marks: the worst pad and all pads together (99 % expected);
- islands bridged: islands of the side's copper that the ink near the marks joins or
  brings within 30 um (tests/inked.py's joined_islands; 0 expected), and with the
  crosses, the ink near them ("+x").

One row per board and side with the planning time of the default plan, and a total line.
A board whose side takes over --limit seconds (90) to plan, or that plan_board refuses
(two files of one copper role, no top copper), is skipped with the reason. Numbers are
printed, never asserted. The ink near the marks is taken tile by tile (5 mm), from
the steps near each tile, so a board of thousands of vias needs neither one huge sweep
nor a pass over every step per pad.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import tempfile
import time
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
from galileo_cnc.program.drills import Hole  # noqa: E402
from galileo_cnc.program.extents import extents  # noqa: E402
from galileo_cnc.readers.board import open_board  # noqa: E402

PAD_NM = 800_000        # round each mark: its pad (tests/plan/test_drill_marks.py)
TILE_NM = 5_000_000
GAP_NM = 30_000         # islands closer than this count as joined (tests/inked.py)


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
    """Ink in the marks, the copper round them inked against the plan without marks,
    islands joined by the ink near them."""
    if not planned.marks:
        return {"marks": 0, "pixels": 0, "worst": None, "overall": None, "joined": 0}
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
    pixels, inked, inked_before, worst, near = 0, 0.0, 0.0, math.inf, []
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
            had = clip.area_nm2(clip.intersection(ink_before, pad)) if ink_before else 0.0
            if not had:
                continue
            has = clip.area_nm2(clip.intersection(ink, pad)) if ink else 0.0
            inked, inked_before, worst = inked + has, inked_before + had, min(worst, has / had)
    ink = clip.union(*[piece for piece in near if piece]) if any(near) else []
    return {"marks": len(clip.components(planned.marks)), "pixels": pixels,
            "worst": None if worst == math.inf else worst,
            "overall": inked / inked_before if inked_before else None,
            "joined": len(joined_islands(ink, copper, GAP_NM))}


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
                    has_bottom: bool) -> dict:
    """Both sides with registration crosses: each bottom cross from the steps, turned
    over, against its top cross; islands the ink near the crosses joins."""
    board = open_board(folder)
    try:
        _copper, options = side_options(board, BoardChoice(side="top", registration=True))
    finally:
        board.close()
    outline_box = extents(options.outline_program) if options.outline_program else None
    board_crosses = sides.registration_points(options.holes, outline_box)
    found, joined = {}, 0
    for side in ("top", "bottom") if has_bottom else ("top",):
        planned, _seconds = timed_plan(folder, config, BoardChoice(side=side, registration=True),
                                       limit_s)
        crosses = board_crosses if side == "top" else \
            [planned.axis.point(x, y) for x, y in board_crosses]
        found[side], trace = crosses_of(planned, crosses, config)
        around = clip.union(*[clip.stroke([[list(c)]], sides.CROSS_ARM_NM, 1000)
                              for c in crosses])
        ink = ink_near(trace, config, planned.offset_nm, pen_nm, around)
        joined += len(joined_islands(ink, planned.ink.copper.native, GAP_NM))
        found[side + "_offset"], found[side + "_axis"] = planned.offset_nm, planned.axis
    pairs = [(t, b) for t, b in zip(found["top"], found.get("bottom", []))
             if t is not None and b is not None]
    worst = None
    if has_bottom:
        for t, b in pairs:
            bx, by = turned_over(found["bottom_axis"], found["bottom_offset"],
                                 config.nm_per_step, b)
            worst = max(worst or 0.0, math.hypot(bx - t[0], by - t[1]))
    if has_bottom and found["top_offset"] != found["bottom_offset"]:
        worst = math.inf
    return {"crosses": len(board_crosses), "paired": len(pairs), "worst": worst,
            "joined": joined}


def percent(share) -> str:
    return "-" if share is None else f"{100 * share:.2f}"


def steps(value) -> str:
    return "-" if value is None else ("offsets differ" if value == math.inf else f"{value:.2f}")


def bench_board(name, args, scratch, config, pen_nm, totals, skipped) -> None:
    """One board's rows (or the reason it is skipped)."""
    folder = link_board(args.corpus, name, Path(scratch))
    board = open_board(folder)
    has_top, has_bottom = bool(board.files("top-copper")), \
        bool(board.files("bottom-copper"))
    board.close()
    if not has_top:
        skipped.append((name, "no top copper file"))
        print(f"{name:34} skipped: no top copper file")
        return
    planned, seconds = {}, {}
    try:
        for side in ("top", "bottom") if has_bottom else ("top",):
            planned[side], seconds[side] = timed_plan(
                folder, config, BoardChoice(side=side), args.limit)
    except TooSlow:
        skipped.append((name, f"the {side} took over {args.limit} s to plan"))
        print(f"{name:34} skipped: the {side} side took over {args.limit} s to plan")
        return
    except Exception as problem:  # noqa: BLE001 - a bench reports and goes on
        skipped.append((name, f"{type(problem).__name__}: {problem}"))
        print(f"{name:34} skipped: {type(problem).__name__}: {problem}")
        return
    try:
        registration = measure_crosses(folder, config, pen_nm, args.limit, has_bottom)
    except TooSlow:
        registration = None
    turn = holes_turned_over(planned["top"], planned["bottom"], config.nm_per_step) \
        if has_bottom else None
    for side, plan in planned.items():
        try:
            before, _s = timed_plan(folder, config,
                                    BoardChoice(side=side, drill_marks="none"),
                                    args.limit)
            got = measure_marks(plan, before, config, pen_nm)
        except TooSlow:
            got = None
        bottom_row = side == "bottom" or not has_bottom
        cross = "-"
        if bottom_row and registration is not None and has_bottom:
            cross = steps(registration["worst"])
            if registration["paired"] < registration["crosses"]:
                cross += f" {registration['paired']}/{registration['crosses']}"
        elif bottom_row and registration is None:
            cross = "too slow"
        row = (f"{name:34} {side:6} {seconds[side]:6.1f} {len(plan.holes):5} ")
        if got is None:
            row += f"{'none-marks plan too slow':>30}"
        else:
            row += (f"{got['marks']:5} {got['pixels']:6} {percent(got['worst']):>9} "
                    f"{percent(got['overall']):>6} {got['joined']:3}")
            totals["pixels"] += got["pixels"]
            totals["joined"] += got["joined"]
            if got["worst"] is not None:
                totals["worst_pad"] = got["worst"] if totals["worst_pad"] is None \
                    else min(totals["worst_pad"], got["worst"])
                totals["inked"].append(got["overall"])
        row += f" {steps(turn) if side == 'bottom' else '-':>10} {cross:>12}"
        row += f" {registration['joined'] if registration and bottom_row else '-':>5}"
        print(row, flush=True)
        totals["rows"] += 1
        totals["plan_s"] += seconds[side]
    if turn is not None:
        totals["turn"] = max(totals["turn"], turn)
    if registration is not None:
        totals["joined"] += registration["joined"]
        if registration["worst"] is not None:
            totals["cross"] = max(totals["cross"], registration["worst"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--boards", default="",
                        help="NAME,... (tool/board or board; default: every board)")
    parser.add_argument("--corpus", type=Path, default=CORPUS)
    parser.add_argument("--limit", type=int, default=90,
                        help="skip a board whose side takes longer to plan (s)")
    args = parser.parse_args()
    names = board_folders(args.corpus)
    if args.boards:
        wanted = args.boards.split(",")
        names = [n for n in names if n in wanted or n.split("/")[1] in wanted]
    config = MachineConfig()
    pen_nm = min(config.pen_widths_nm)
    print(f"corpus {args.corpus}, {len(names)} boards; default profile, ink mode, "
          f"drill marks small; pen {pen_nm / 1e6:.2f} mm, step {config.nm_per_step} nm")
    header = (f"{'board':34} {'side':6} {'plan s':>6} {'holes':>5} {'marks':>5} "
              f"{'ink px':>6} {'pad min %':>9} {'all %':>6} {'isl':>3} "
              f"{'holes turn':>10} {'crosses turn':>12} {'isl+x':>5}")
    print(header)
    totals = {"rows": 0, "pixels": 0, "joined": 0, "worst_pad": None, "inked": [],
              "turn": 0.0, "cross": 0.0, "plan_s": 0.0}
    skipped = []
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        for name in names:
            try:
                bench_board(name, args, scratch, config, pen_nm, totals, skipped)
            except Exception as problem:  # noqa: BLE001 - a bench reports and goes on
                skipped.append((name, f"{type(problem).__name__}: {problem}"))
                print(f"{name:34} failed: {type(problem).__name__}: {problem}", flush=True)
    print(f"total: {totals['rows']} sides of {len(names) - len(skipped)} boards planned in "
          f"{totals['plan_s']:.1f} s (run {time.perf_counter() - started:.0f} s); ink pixels "
          f"in marks {totals['pixels']}; worst pad {percent(totals['worst_pad'])} %, worst "
          f"side overall {percent(min(totals['inked'], default=None))} %; islands joined "
          f"{totals['joined']}; turn-over worst {steps(totals['turn'])} steps (holes), "
          f"{steps(totals['cross'])} steps (crosses)")
    for name, why in skipped:
        print(f"skipped {name}: {why}")


if __name__ == "__main__":
    main()
