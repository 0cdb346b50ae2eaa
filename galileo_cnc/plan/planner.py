"""The planner: a Program (ops in nm) becomes a Job (machine commands in steps).

One pass over the op table (docs/plan.md). Gerber artwork with more than one
aperture is first grouped by aperture (`order/apertures.py`), so each pen is
inserted once; G-code keeps its file order, where feeds and pen moves are modal.

- subtract the offset from every coordinate, then nm -> steps with
  `MachineConfig.nm_to_steps` (nearest step, halves away from zero);
- MOVE -> Rapid (the machine lifts the pen itself), LINE -> PenDown if the pen is
  not known to be down, then LineTo; ARC_CW/CCW -> PenDown if needed, then ArcTo
  with the centre rounded to the nearest step and given relative to the rounded
  start (an arc farther than the machine's MAX_ARC_COORD steps from its centre is
  drawn as chords within half a step; one whose chord is within half a step of it is
  a LineTo: docs/motion.md, "Short arcs"); FLASH -> Rapid to the point (unless there),
  Flash; PEN_UP/PEN_DOWN,
  DWELL, FEED (nm/s -> steps/s) as themselves; SELECT, POLARITY and the REGION
  markers emit nothing (region contours are drawn as outlines);
- a MOVE or LINE that lands on the step it starts from is dropped;
- at the first draw, flash or pen-down of each aperture (when there are several) the
  pen is lifted and `Job.pen_changes` records the command where the user swaps pens;
- the job ends with PenUp and EndJob;
- soft limits: the finished command list is planned (not stepped) by the reference
  machine, whose travel check is the firmware's; a refusal becomes a PlanError that
  names the op's file:line:col and the axis, and no Job is returned.

Every command carries the index of the op it came from (-1 for the closing
PenUp/EndJob) and the aperture in force, for progress, resume and pen changes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.errors import GalileoError, SourcePos
from galileo_cnc.job import (NO_OP, ArcTo, Command, Dwell, EndJob, Flash, Job, LineTo,
                             MachineError, PenDown, PenUp, Rapid, SetFeed)
from galileo_cnc.machine import ReferenceMachine
from galileo_cnc.machine.arcs import MAX_ARC_COORD, arc_setup
from galileo_cnc.plan.curves import arc_angles, arc_points
from galileo_cnc.plan.order import gcode_order, paths
from galileo_cnc.plan.order.apertures import (DRAWING_KINDS, PATH_KINDS, OrderedRows,
                                              drawing_apertures, group_by_aperture,
                                              optimized_order, pure_geometry)
from galileo_cnc.plan.widths import aperture_width, mm_text
from galileo_cnc.protocol.codec import first_range_problem
from galileo_cnc.protocol.spec import COORD
from galileo_cnc.program.describe import describe_op
from galileo_cnc.program.ops import (COLUMNS, I, J, KIND, LINE, COL, NO_TOOL, POSITIONED_KINDS,
                                     TOOL, VALUE, X, Y, OpKind, Program)


#: ops between two progress reports while planning
PROGRESS_OPS = 2000


class PlanError(GalileoError):
    """The job cannot run (e.g. leaves the travel); names the op's source position."""

    def __init__(self, message: str, pos: SourcePos | None = None, axis: str = "",
                 op_index: int = NO_OP):
        self.pos = pos
        self.axis = axis
        self.op_index = op_index
        self.message = message
        super().__init__(f"{pos}: {message}" if pos else message)


# op kinds as plain ints: compared a few times per row in the planner's loop
(_MOVE, _LINE, _ARC_CW, _ARC_CCW, _FLASH, _PEN_UP, _PEN_DOWN, _SELECT, _DWELL,
 _FEED) = (int(OpKind[name]) for name in ("MOVE", "LINE", "ARC_CW", "ARC_CCW", "FLASH",
                                         "PEN_UP", "PEN_DOWN", "SELECT", "DWELL", "FEED"))
#: how an arc row is sent (_machine_points)
_AS_LINE, _AS_ARC, _AS_CHORDS = 0, 1, 2


@dataclass
class _MachineRows:
    """Every row (in plotting order) as the machine takes it (_machine_points): its
    point in steps, for an arc how it is sent, and the command of each draw."""

    xs: list[int]
    ys: list[int]
    how: np.ndarray             # _AS_LINE, _AS_ARC or _AS_CHORDS for an arc, else -1
    #: per arc drawn as chords (its row): its start in steps and in program nm
    chords_from: dict[int, tuple[tuple[int, int], tuple[int, int]]]
    emits: np.ndarray           # per row: whether its draw makes a LineTo or an ArcTo
    made: list[Command]         # those LineTos and ArcTos, in row order
    surely_fine: bool           # the job these rows make surely passes check_job


def _machine_points(table: np.ndarray, config: MachineConfig, offset_nm: tuple[int, int]
                    ) -> _MachineRows:
    """For every row (in plotting order): its point in steps (offset subtracted, the
    nearest step) and, for an arc, how the machine draws it, all rows at once:

    - _AS_LINE: a LineTo to the end, unless the end is the start. The
      straight line from start to end stays within half a step of the arc (steps;
      never a full circle), so its steps are within a step of the arc, as the arc's
      own are. Such arcs are sent as lines: an arc costs the firmware a band table and
      setup (several ms), so runs of 1-step arcs fell behind the reference
      (docs/motion.md, "Short arcs"). When both ends round to one step (Altium writes
      arcs of 0.4 um) the file's own arc (nm) decides: under half a turn it is a point,
      not the whole circle that an arc ending where it starts means to the machine;
    - _AS_ARC: an ArcTo, centre rounded to the nearest step and given relative
      to the rounded start;
    - _AS_CHORDS: farther than the machine's MAX_ARC_COORD steps from its centre
      (machine/arcs.py): chords within half a step of it (plan_program draws them).

    The start of an arc is the point of the positioned row before it, or the
    program's origin (the offset) at the start. A LINE draws a LineTo unless it ends
    where the positioned row before it did (`emits`, `made`: the commands of every
    draw, made at once; plan_program adds the PenDown and pen changes around them)."""
    ox, oy = offset_nm
    count = len(table)
    kinds = table[:, KIND]
    x_nm, y_nm = table[:, X] - ox, table[:, Y] - oy
    xs, ys = config.nm_to_steps_array(x_nm), config.nm_to_steps_array(y_nm)
    how = np.full(count, -1, dtype=np.int64)
    chords_from = {}
    rows = np.flatnonzero((kinds == OpKind.ARC_CW) | (kinds == OpKind.ARC_CCW))
    positioned = np.isin(kinds, POSITIONED_KINDS)
    # the positioned row before each row (-1: none), where the head is when it starts
    last = np.maximum.accumulate(np.where(positioned, np.arange(count), -1))
    before = np.concatenate(([-1], last[:-1]))[:count].astype(np.int64)
    moved = (before < 0) | (xs != xs[np.maximum(before, 0)]) | (ys != ys[np.maximum(before, 0)])
    emits = (kinds == OpKind.LINE) & moved
    centre_i, centre_j = np.zeros(count, dtype=np.int64), np.zeros(count, dtype=np.int64)
    circles = (np.zeros(0, dtype=np.int64),) * 8
    if len(rows):
        before = before[rows]
        # the program point each arc starts from (nm, offset applied), and in steps
        sx_nm = np.where(before >= 0, x_nm[np.maximum(before, 0)], -ox)
        sy_nm = np.where(before >= 0, y_nm[np.maximum(before, 0)], -oy)
        sx, sy = config.nm_to_steps_array(sx_nm), config.nm_to_steps_array(sy_nm)
        cx = config.nm_to_steps_array(sx_nm + table[rows, I])
        cy = config.nm_to_steps_array(sy_nm + table[rows, J])
        ex, ey = xs[rows], ys[rows]
        cw = kinds[rows] == OpKind.ARC_CW
        # from the centre: start (a, b) and end (c, d)
        a, b, c, d = sx - cx, sy - cy, ex - cx, ey - cy
        cross = a * d - b * c
        flat = np.where(cw, cross <= 0, cross >= 0)         # over half a turn: a bulge
        radius = np.array([math.hypot(p, q) for p, q in zip(a.tolist(), b.tolist())])
        chord2 = (ex - sx) ** 2 + (ey - sy) ** 2
        half = 0.5
        # sagitta r - sqrt(r^2 - c^2/4) < h  <=>  c^2 < 4h(2r - h)   (a choice: floats)
        as_line = flat & (chord2 < 4 * half * (2 * radius - half))
        same = (sx == ex) & (sy == ey)
        for k in np.flatnonzero(same).tolist():
            row = rows[k]
            sweep = arc_angles(int(sx_nm[k]), int(sy_nm[k]), int(x_nm[row]), int(y_nm[row]),
                               int(sx_nm[k] + table[row, I]), int(sy_nm[k] + table[row, J]),
                               bool(cw[k]))[1]
            as_line[k] = abs(sweep) < math.pi
        in_range = np.maximum.reduce([np.abs(a), np.abs(b), np.abs(c), np.abs(d)]) \
            <= MAX_ARC_COORD
        how[rows] = np.where(as_line, _AS_LINE, np.where(in_range, _AS_ARC, _AS_CHORDS))
        for k in np.flatnonzero(~as_line & ~in_range).tolist():
            chords_from[int(rows[k])] = ((int(sx[k]), int(sy[k])),
                                         (int(sx_nm[k]), int(sy_nm[k])))
        # an arc sent as a line draws unless it ends on its start's step
        emits[rows] = np.where(as_line, ~same, in_range)
        centre_i[rows], centre_j[rows] = cx - sx, cy - sy
        sent = ~as_line
        # per ArcTo: its centre, and its start and end from the centre (steps); the
        # direction as the machine takes it (arc_setup's ccw)
        circles = None if (before < 0).any() or not in_range[sent].all() else (
            cx[sent], cy[sent], a[sent], b[sent], c[sent], d[sent], ~cw[sent],
            np.maximum(a * a + b * b, c * c + d * d)[sent])
    drawn = np.flatnonzero(emits)
    arc_of = how[drawn] == _AS_ARC
    made: list[Command] = [
        ArcTo(x, y, i, j, kind == _ARC_CW) if arc else LineTo(x, y)
        for x, y, arc, i, j, kind in zip(
            xs[drawn].tolist(), ys[drawn].tolist(), arc_of.tolist(), centre_i[drawn].tolist(),
            centre_j[drawn].tolist(), kinds[drawn].tolist())]
    return _MachineRows(xs.tolist(), ys.tolist(), how, chords_from, emits, made,
                        _rows_surely_fine(kinds, xs[positioned], ys[positioned], circles,
                                          config))


#: arcs near the travel's edges whose own box _rows_surely_fine works out at most
#: (one arc_setup each); past that check_job decides
_ARC_BOXES = 10_000
#: op kinds whose commands _rows_surely_fine knows (others leave it to check_job)
_PLAIN_KINDS = [int(OpKind[name]) for name in ("MOVE", "LINE", "ARC_CW", "ARC_CCW", "FLASH",
                                               "PEN_UP", "PEN_DOWN", "SELECT", "POLARITY",
                                               "REGION_BEGIN", "REGION_END")]


def _rows_surely_fine(kinds: np.ndarray, xs: np.ndarray, ys: np.ndarray,
                      circles: tuple | None, config: MachineConfig) -> bool:
    """Whether the job of these rows surely passes check_job, from the rows' arrays
    (check_job's own two walks over the commands take 0.2 s of hellboard's plan):
    only moves, draws, flashes and pen moves; every positioned row's point (each
    Rapid, LineTo and ArcTo goes to one) inside the travel and on the wire; every
    ArcTo's circle inside the travel (else the box the machine works out for the arc,
    as _surely_inside does), its centre offset on the wire. `circles`: per ArcTo its
    centre, start and end from the centre, direction (ccw) and larger squared radius
    (steps); None where an arc is drawn as chords or starts the job. Any doubt is
    False: check_job then walks the commands as before."""
    if circles is None or not _shortcut_holds(config) \
            or not np.isin(kinds, _PLAIN_KINDS).all():
        return False
    x_min, y_min, _ = config.travel_min_steps
    x_max, y_max, _ = config.travel_max_steps
    if len(xs) and not (max(x_min, COORD.lo) <= xs.min() and xs.max() <= min(x_max, COORD.hi)
                        and max(y_min, COORD.lo) <= ys.min()
                        and ys.max() <= min(y_max, COORD.hi)):
        return False
    cx, cy, a, b, c, d, ccw, radius2 = circles
    if not len(cx):
        return True
    i, j = -a, -b                          # the centre from the start
    if not (COORD.lo <= min(i.min(), j.min()) and max(i.max(), j.max()) <= COORD.hi):
        return False
    # as _surely_inside: the circle's box (its radius rounded down, plus 2 steps),
    # else the box the machine works out for the arc itself
    radius = np.array([math.isqrt(int(r)) for r in radius2.tolist()], dtype=np.int64) + 2
    outside = np.flatnonzero((cx - radius < x_min) | (cx + radius > x_max)
                             | (cy - radius < y_min) | (cy + radius > y_max))
    if len(outside) > _ARC_BOXES:
        return False
    return all(_arc_box_inside(int(cx[k]), int(cy[k]), (int(a[k]), int(b[k])),
                               (int(c[k]), int(d[k])), bool(ccw[k]), config)
               for k in outside.tolist())


def _shortcut_holds(config: MachineConfig) -> bool:
    """What both travel shortcuts (_surely_inside, _rows_surely_fine) assume of the
    machine: flashes without a dwell of their own, the pen's heights and the origin
    (where the machine starts) inside the travel."""
    x_min, y_min, z_min = config.travel_min_steps
    _, _, z_max = config.travel_max_steps
    return (config.flash_dwell_ms >= 0 and x_min <= 0 and y_min <= 0
            and all(z_min <= z <= z_max for z in (0, config.pen_up_z_steps,
                                                  config.pen_down_z_steps)))


def _arc_box_inside(cx: int, cy: int, start: tuple[int, int], end: tuple[int, int],
                    ccw: bool, config: MachineConfig) -> bool:
    """Whether the box the machine works out for an arc (arc_setup; start and end from
    the centre (cx, cy), steps) lies inside the travel."""
    x_min, y_min, _ = config.travel_min_steps
    x_max, y_max, _ = config.travel_max_steps
    low_x, high_x, low_y, high_y = arc_setup(start, end, ccw)[1]
    return (x_min <= cx + low_x and cx + high_x <= x_max
            and y_min <= cy + low_y and cy + high_y <= y_max)


def plotting_order(program: Program, config: MachineConfig, offset_nm: tuple[int, int],
                   group: bool = True, optimize: bool = False
                   ) -> tuple[list[tuple[int, list[int]]], bool, bool]:
    """The (op index, row) pairs in the order they are plotted, and whether they were
    grouped by aperture and ordered for travel (see plan_program)."""
    several_pens = len(drawing_apertures(program)) > 1
    if optimize and program.format == "gcode":
        # asked for (--optimize): pen drawings only, refused with the line otherwise
        problem = gcode_order.refusal(program)
        if problem is not None:
            raise PlanError(f"--optimize: cannot reorder this G-code: {problem[1]} "
                            f"(without --optimize it is drawn in its own order)", problem[0])
        lead, rows = gcode_order.pen_rows(program)
        start = (int(offset_nm[0]), int(offset_nm[1]))
        return lead + paths.optimize(rows, start, config.nm_per_step)[0], False, True
    if optimize and group and program.format in ("gerber", "dxf") and pure_geometry(program):
        # one pen per aperture, each pen's paths chained and ordered (plan/order/paths.py);
        # the program point at the work origin is where the head starts
        start = (int(offset_nm[0]), int(offset_nm[1]))
        return optimized_order(program, start, config.nm_per_step, several_pens), True, True
    if group and several_pens and program.format == "gerber":
        return group_by_aperture(program), True, False
    return list(enumerate(program.table.tolist())), False, False


def plan_program(program: Program, config: MachineConfig | None = None,
                 offset_nm: tuple[int, int] = (0, 0), group: bool = True,
                 on_progress: Callable[[int, int], None] | None = None,
                 optimize: bool = False,
                 ordered: list[tuple[int, list[int]]] | OrderedRows | None = None) -> Job:
    """Plan `program` for the machine `config` with `offset_nm` subtracted (see module
    doc); `group=False` keeps a Gerber file's own order. `on_progress(done, total)`
    hears about every PROGRESS_OPS ops, so a front end can show a long plan moving.
    `optimize` chains and orders each pen's paths (plan/order/paths.py; Gerber and DXF
    of pure geometry; G-code only if it draws with a pen and nothing else, else
    PlanError: plan/order/gcode_order.py; plan_file asks for it for Gerber and DXF
    unless the user wants file order, for G-code when the user gives --optimize).
    `ordered`: the rows in the order `optimize` gives them, worked out already, as (op
    index, row) pairs or OrderedRows (the ink's: plan/ink/walk_order.py)."""
    config = config or MachineConfig()
    steps = config.nm_to_steps_function()
    ox, oy = offset_nm
    job = Job(program.source, (int(ox), int(oy)))
    several_pens = len(drawing_apertures(program)) > 1
    if ordered is None:
        ordered, job.grouped, job.ordered = plotting_order(program, config, offset_nm, group,
                                                           optimize)
    else:
        job.grouped = job.ordered = True
    aperture = NO_TOOL
    pen = None                         # the aperture whose pen is in the holder
    pen_down: bool | None = None       # unknown until the job sets it
    at: tuple[int, int] | None = None  # position in steps; unknown at the start
    index = NO_OP

    commands, op_indices, apertures = job.commands, job.op_index, job.aperture

    def add(command: Command) -> None:
        """The command into the job (Job.add), from the op `index` with `aperture` in force."""
        commands.append(command)
        op_indices.append(index)
        apertures.append(aperture)

    total = len(ordered)
    if isinstance(ordered, OrderedRows):
        table, indices = ordered.table, ordered.indices.tolist()
    else:
        table = np.array([row for _index, row in ordered], dtype=np.int64).reshape(
            -1, len(COLUMNS))
        indices = [op for op, _row in ordered]
    rows = _machine_points(table, config, (int(ox), int(oy)))
    kinds, tools = table[:, KIND], table[:, TOOL]
    # a draw that follows a draw of the same aperture (or of none) finds the pen down
    # and the right pen in: its command alone, and such runs are copied in whole
    drawing = np.isin(kinds, PATH_KINDS) & (rows.how != _AS_CHORDS)
    plain = np.zeros(total, dtype=bool)
    plain[1:] = drawing[1:] & drawing[:-1] & ((tools[1:] == NO_TOOL) | (tools[1:] == tools[:-1]))
    run_end = np.minimum.accumulate(np.where(plain, total, np.arange(total))[::-1])[::-1]
    made_before = np.concatenate([[0], np.cumsum(rows.emits)]).tolist()
    made_ops = [indices[k] for k in np.flatnonzero(rows.emits).tolist()]
    plain, run_end, how = plain.tolist(), run_end.tolist(), rows.how.tolist()
    kinds, tools, values = kinds.tolist(), tools.tolist(), table[:, VALUE].tolist()
    done = 0
    while done < total:
        if plain[done]:                 # the run of plain draws from here
            end = run_end[done]
            first, last = made_before[done], made_before[end]
            commands.extend(rows.made[first:last])
            op_indices.extend(made_ops[first:last])
            apertures.extend([aperture] * (last - first))
            at = (rows.xs[end - 1], rows.ys[end - 1])
            if on_progress is not None:
                for mark in range(-(-done // PROGRESS_OPS) * PROGRESS_OPS, end, PROGRESS_OPS):
                    on_progress(mark, total)
            done = end
            continue
        if on_progress is not None and done % PROGRESS_OPS == 0:
            on_progress(done, total)
        index, kind, x, y = indices[done], kinds[done], rows.xs[done], rows.ys[done]
        if kind == _SELECT:
            aperture = tools[done]
            done += 1
            continue
        if kind in DRAWING_KINDS and tools[done] != NO_TOOL:
            aperture = tools[done]
        # the pen changes before it is first lowered: at a PEN_DOWN (G-code's M3 after
        # T, Gerber's D01 after a move) as at a draw, else the old pen dips first
        if several_pens and (kind in DRAWING_KINDS or kind == _PEN_DOWN) \
                and aperture != pen and aperture != NO_TOOL:
            if pen_down is not False:
                add(PenUp())
                pen_down = False
            job.pen_changes[len(job)] = aperture
            pen = aperture
        target = (x, y)

        if kind == _MOVE:
            if target != at:
                add(Rapid(x, y))
                pen_down = False
            at = target
        elif kind == _LINE or kind == _ARC_CW or kind == _ARC_CCW:
            if pen_down is not True:
                add(PenDown())
                pen_down = True
            if how[done] == _AS_CHORDS:
                # the machine's arcs reach MAX_ARC_COORD steps from the centre (204.8 mm
                # on the seed's machine): a flatter arc is drawn as chords within half a
                # step of it
                point, (sx, sy) = rows.chords_from[done]
                row = table[done].tolist()
                chords = arc_points(sx, sy, row[X] - ox, row[Y] - oy, row[I], row[J],
                                    kind == _ARC_CW, max(config.nm_per_step // 2, 1))
                for cx, cy in chords[1:].tolist():
                    if (step := (steps(cx), steps(cy))) != point:
                        add(LineTo(*step))
                        point = step
            elif rows.emits[done]:
                add(rows.made[made_before[done]])
            at = target
        elif kind == _FLASH:
            if target != at:
                add(Rapid(x, y))
            add(Flash())
            pen_down = False
            at = target
        elif kind == _PEN_UP:
            add(PenUp())
            pen_down = False
        elif kind == _PEN_DOWN:
            add(PenDown())
            pen_down = True
        elif kind == _DWELL:
            add(Dwell(values[done]))
        elif kind == _FEED:
            add(SetFeed(steps(values[done])))
        # POLARITY, REGION_BEGIN, REGION_END: nothing to do on a pen plotter.
        done += 1

    job.add(PenUp(), NO_OP, aperture)
    job.add(EndJob(), NO_OP, aperture)
    _label_pens(job, program)
    if not rows.surely_fine:
        check_job(job, program, config)
    if on_progress is not None:
        on_progress(total, total)
    return job


def _label_pens(job: Job, program: Program) -> None:
    """What each pen change asks for, and each pen's width (for previews and benches):
    ink pens by their width, Gerber apertures by their D code and shape."""
    ink = program.metadata.get("ink", False)
    for key in set(job.aperture) - {NO_TOOL}:       # pen changes name these too
        aperture = program.apertures.get(key)
        if aperture is None:
            job.pen_labels[key] = f"D{key}"
            job.pen_widths_nm[key] = 0
            continue
        width = aperture_width(aperture) if aperture.shape != "block" else 0
        job.pen_widths_nm[key] = width
        job.pen_labels[key] = (f"the {mm_text(width)} mm pen" if ink
                               else f"pen for aperture D{key} ({aperture.describe()})")


def check_job(job: Job, program: Program, config: MachineConfig) -> None:
    """Soft limits (and feed range) by the reference machine's own checks, from a
    machine at its origin; raises PlanError naming the op behind the refused command."""
    found = first_range_problem(job.commands, config.steps_per_mm)  # what the wire cannot carry
    if found is not None:
        at, problem = found
        op = job.op_index[at]
        row = program.table[op] if op != NO_OP else None
        pos = SourcePos(program.source, int(row[LINE]), int(row[COL])) \
            if row is not None and row[LINE] else None
        what = describe_op(program, op) if row is not None else "the end of the job"
        raise PlanError(f"{what}: {problem}", pos, "", op)
    if _surely_inside(job.commands, config):
        return
    try:
        ReferenceMachine(config).plan(job.commands)
    except MachineError as problem:
        at = problem.index if problem.index is not None else NO_OP
        op = job.op_index[at] if 0 <= at < len(job) else NO_OP
        pos = None
        if op != NO_OP:
            row = program.table[op]
            # ink rings come from many objects: they have no line of their own
            pos = SourcePos(program.source, int(row[LINE]), int(row[COL])) if row[LINE] else None
            what = describe_op(program, op)
        else:
            what = "the end of the job"
        detail = (config.travel_refusal(problem.axis, problem.value, problem.limit)
                  if problem.value is not None else str(problem).split(": ", 1)[-1])
        raise PlanError(f"{what}: {detail}", pos, problem.axis, op) from None


def _surely_inside(commands: list[Command], config: MachineConfig) -> bool:
    """Whether the reference machine cannot refuse the job: moves, arcs, pen moves and
    flashes only, every point within the travel, and every arc's circle too (its
    steps stay within a step of the circle whatever its ends: machine/arcs.py) or
    else the box the machine itself works out for it. Planning 300k ink commands
    takes the machine 5-9 s, this 0.1 s; any doubt leaves the answer to the machine."""
    if not _shortcut_holds(config):
        return False
    x_min, y_min, _ = config.travel_min_steps
    x_max, y_max, _ = config.travel_max_steps
    x = y = 0                                   # the machine starts at its origin
    last = len(commands) - 1
    for at, command in enumerate(commands):
        kind = type(command)
        if kind is LineTo or kind is Rapid:
            if kind is LineTo and command.z_steps is not None:
                return False
            x, y = command.x_steps, command.y_steps
            if not (x_min <= x <= x_max and y_min <= y <= y_max):
                return False
        elif kind is ArcTo:
            cx, cy = x + command.i_steps, y + command.j_steps
            start = (x - cx, y - cy)
            x, y = command.x_steps, command.y_steps
            end = (x - cx, y - cy)
            if max(abs(start[0]), abs(start[1]), abs(end[0]), abs(end[1])) > MAX_ARC_COORD:
                return False
            radius = math.isqrt(max(start[0] ** 2 + start[1] ** 2, end[0] ** 2 + end[1] ** 2)) + 2
            if x_min <= cx - radius and cx + radius <= x_max \
                    and y_min <= cy - radius and cy + radius <= y_max:
                continue
            if not _arc_box_inside(cx, cy, start, end, not command.cw, config):
                return False
        elif kind is EndJob:
            if at != last:
                return False
        elif not (kind is PenUp or kind is PenDown or (kind is Flash and command.dwell_ms is None)):
            return False
    return True
