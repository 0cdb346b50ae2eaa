"""The one pipeline every front end calls: file -> Program -> offset -> Job.

`load_artwork` reads a file and works out where it sits: the box of everything
the machine will visit (drawn, flashed and travelled to), the offset that brings
it to the origin plus a margin, and whether it fits the machine at all.
`plan_file` plans it with the offset the front end chose. `info` stops after
the first step; `plot`, `preview`, the console's `getg` and `resume` take both.
A scale, rotation or fit the user asks for (transform.py) is applied as the file is
read, before the box and the offset are worked out; the feeds are checked before
planning (feeds.py): above the machine's limits refused, above the warning feed
said in `PlannedFile.feed_warnings`.

A board's side (`PlanOptions.side`, docs/boards.md): the bottom is
mirrored about the axis (sides.py) as it is read, its holes with it, and both sides
take one offset; the holes' drill marks are left bare in the ink (drill_marks.py), and
registration crosses drawn after the copper; then the outline and the silkscreen as
centre lines, each with a pen of its own, kept off the copper (board_lines.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence, Union

import numpy as np

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import Job
from galileo_cnc.plan.collector import collector_paused
from galileo_cnc.plan.feeds import check_feeds
from galileo_cnc.plan import sides
from galileo_cnc.plan.board_lines import (PEN_NAMES, OUTLINE, SILK, BoardLines, centre_lines,
                                          clear_of, keep_out, with_lines)
from galileo_cnc.plan.drill_marks import (DEFAULT_DRILL_MARK_NM, DRILL_MARK_MODES, MarkCutter,
                                          clear_centre_lines, clear_strokes, marks_for,
                                          ring_flashes)
from galileo_cnc.plan.ink.islands import CLEARANCE_NM
from galileo_cnc.plan.ink.geometry import dark_geometry
from galileo_cnc.plan.ink.inking import (DEFAULT_EDGE_MARGIN_NM, INK_TOLERANCE_NM, InkPlan,
                                         ink_paths)
from galileo_cnc.plan.order.apertures import OrderedRows
from galileo_cnc.plan.offsets import (DEFAULT_MARGIN_NM, OffsetError, OffsetRangeError,
                                      offset_for_box, offset_from_text)
from galileo_cnc.plan.planner import PlanError, plan_program
from galileo_cnc.plan.widths import mm_text
from galileo_cnc.plan.transform import (NO_TRANSFORM, Transform, TransformError,
                                        apply_transform, reach_box)
from galileo_cnc.program.drills import Hole, Slot, drills_box
from galileo_cnc.program.extents import extents, union_box
from galileo_cnc.program.ops import NM_PER_MM, Program
from galileo_cnc.readers import read_file
from galileo_cnc.readers.gerber.transformed import with_source_apertures

Box = tuple[int, int, int, int]
#: formats whose paths are chained and ordered unless the user asks for file order
#: (G-code from elsewhere keeps its order unless --optimize: milling files carry state a
#: reorder breaks)
ORDERED_FORMATS = ("gerber", "dxf")
#: files with fewer ops plan in well under a second: front ends show no progress for them,
#: and plan_file tells them no stages
PLANNING_NOTICE_OPS = 5000
#: "auto" (the proposal), "none" (the file's own coordinates), "X,Y" in mm, or (x, y) nm.
OffsetChoice = Union[str, tuple[int, int]]


@dataclass(frozen=True)
class Artwork:
    """A read file and where it sits, in nm."""

    program: Program
    drawn_box_nm: Box | None     # drawn centre lines (arcs by their extremes) and flashes
    visited_box_nm: Box | None   # everything the machine goes to: drawn, flashed, moved to
    margin_nm: int
    #: the scale and rotation `program` was read with (a --fit resolved to its scale)
    transform: Transform = NO_TRANSFORM

    @property
    def proposal_nm(self) -> tuple[int, int]:
        """The offset the seed proposed, over the whole job: the lower-left corner of
        everything visited minus the margin (so a closing `G0 X0 Y0` fits too)."""
        return offset_for_box(self.visited_box_nm, self.margin_nm)

    def misfit(self, config: MachineConfig) -> str | None:
        """Why no offset can make the job fit the travel (None: one can)."""
        if self.visited_box_nm is None:
            return None
        x0, y0, x1, y1 = self.visited_box_nm
        for axis, size, travel, key in (("wide", x1 - x0, config.x_travel_mm, "x_travel_mm"),
                                        ("tall", y1 - y0, config.y_travel_mm, "y_travel_mm")):
            if size > round(travel * NM_PER_MM):
                # where a bigger machine says so: the profile ([machine], docs/streaming.md)
                done = f", {self.transform.describe()}" if self.transform.describe() else ""
                return (f"{self.program.source}: the job is {size / NM_PER_MM:.1f} mm {axis} "
                        f"(with its travel moves{done}); the machine's travel is {travel:g} "
                        f"mm ({key} in the profile)")
        return None

    def way_out(self) -> str:
        """What makes a misfit fit (transform.py), for the front ends to add."""
        turn = "" if self.transform.rotate_deg else ", --rotate 90"
        return f"--fit scales it to the travel (or --scale F{turn})"


MODES = ("auto", "ink", "centre")


@dataclass(frozen=True)
class PlanOptions:
    """How artwork becomes pen paths.

    `mode`: "ink" fills Gerber copper with the pens (docs/ink.md), "centre" draws
    each object's centre line with one pen per aperture (the seed's way), "auto" is
    ink for Gerber and centre for everything else. `pens_nm` overrides the
    profile's pens. `file_order` keeps the file's order: no grouping by pen, no
    path order. `optimize` orders G-code's paths too (Gerber and DXF are ordered
    anyway), if it only draws with a pen. `layers` and `units` choose what of a DXF
    drawing is read (read_dxf). `transform`: the scale, rotation or fit the drawing
    is read with (transform.py).

    A board's side (all unset: a layer alone, as before; holes without a side: a
    layer of one side, its own offset, drill marks): `side` "top" or "bottom"
    (the bottom mirrored about `mirror_axis`, ("x", nm) or ("y", nm) in board
    coordinates, default the vertical centre line of `outline_program`'s box, else
    of the holes'); with "auto" both sides take one offset, over `board_box_nm` (give
    the box of every layer of the board, extents.union_box) or else the outline's and
    the holes' box, and its mirror image. `holes`: the board's Hole and Slot objects in
    board coordinates (program/drills.py), left bare as `drill_marks` ("none", "small":
    dots `drill_mark_nm` wide, "actual": the holes) in the ink; `registration`: crosses
    on holes far apart (else outside the outline) after the copper, on both sides.
    `outline`: `outline_program` drawn as centre lines after the copper, and
    `silk_program` (the side's silkscreen, board coordinates) after it, each with a
    pen of its own as wide as the finest pen, cut away near copper (board_lines.py)."""

    mode: str = "auto"
    pens_nm: tuple[int, ...] = ()
    file_order: bool = False
    layers: tuple[str, ...] = ()
    units: str | None = None
    optimize: bool = False
    transform: Transform = NO_TRANSFORM
    holes: Sequence[Hole | Slot] = ()
    drill_marks: str = "small"
    drill_mark_nm: int = DEFAULT_DRILL_MARK_NM
    side: str | None = None
    mirror_axis: tuple[str, int] | None = None
    registration: bool = False
    outline_program: Program | None = None
    board_box_nm: Box | None = None
    outline: bool = False
    silk_program: Program | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise PlanError(f"--mode: expected ink or centre, got {self.mode!r}")
        if self.optimize and self.file_order:
            raise PlanError("--optimize and --file-order ask for opposite orders: give one")
        if self.drill_marks not in DRILL_MARK_MODES:
            raise PlanError(f"--drill-marks: expected none, small or actual, got "
                            f"{self.drill_marks!r}")
        if self.drill_mark_nm <= 0:
            raise PlanError("--drill-mark-size: expected a width above 0 mm")
        if self.side is not None and self.side not in sides.SIDES:
            raise PlanError(f"--side: expected top or bottom, got {self.side!r}")
        if self.outline and self.outline_program is None:
            raise PlanError("--outline: the board has no outline file (info BOARD lists "
                            "the files; --layer FILE=outline places one)")
        if self.on_board and not self.transform.is_identity:
            raise PlanError("--scale, --rotate and --fit change a drawing, not a board's side: "
                            "its holes and its other side would no longer match")

    @property
    def on_board(self) -> bool:
        """A board's side, or a layer with holes: more than a layer alone."""
        return self.side is not None or bool(self.holes) or self.registration \
            or self.mirror_axis is not None

    def mode_for(self, program: Program) -> str:
        if self.mode == "auto":
            return "ink" if program.format == "gerber" else "centre"
        if self.mode == "ink" and program.format != "gerber":
            raise PlanError(f"{program.source}: ink mode fills Gerber copper; this is "
                            f"{program.format} (use --mode centre)")
        return self.mode


@dataclass(frozen=True)
class PlannedFile:
    """A file planned for one machine: the artwork, the offset used, the Job, and the
    Program the job was planned from (`plotted`: the ink in ink mode, else the file's)."""

    artwork: Artwork
    offset_nm: tuple[int, int]
    job: Job
    plotted: Program
    mode: str = "centre"
    ink: InkPlan | None = None
    #: feeds above the profile's warning feed, one line each (feeds.py)
    feed_warnings: tuple[str, ...] = ()
    #: a board's side: which it is, the axis and where it lies on the machine, one line
    side_line: str = ""
    #: drill marks shrunk or left out, and pads too small for a ring (drill_marks.py)
    drill_mark_warnings: tuple[str, ...] = ()
    #: the holes as plotted on this side (mirrored on the bottom), program nm
    holes: tuple = ()
    #: the drill marks left bare: their polygon set, program nm (empty: none)
    marks: list = dataclasses.field(default_factory=list)
    #: a board's side: the line it turns over about (sides.MirrorAxis; None: a file)
    axis: object = None
    #: the outline and silk left out near copper, one line each (board_lines.py)
    line_warnings: tuple[str, ...] = ()
    #: the tools of the outline and the silk: tool -> "outline" | "silk" (previews
    #: colour them)
    pen_roles: dict = dataclasses.field(default_factory=dict)

    @property
    def program(self) -> Program:
        return self.artwork.program

    @property
    def pen_box_nm(self) -> tuple[int, int, int, int] | None:
        """The box of every point the pen visits, file nm: the artwork's, and in ink
        mode the fills' too, which reach out to the copper's edges (the box the "auto"
        offset is proposed from)."""
        box = self.artwork.visited_box_nm
        if self.ink is not None:
            box = union_box(box, extents(self.plotted, visited=True))
        return box

    @property
    def copper(self):
        """The copper the ink was planned for (program nm; None outside ink mode): the
        preview colours what the ink left bare and drew outside it."""
        return self.ink.copper if self.ink is not None else None


def load_artwork(source: str | Path | Program, margin_nm: int = DEFAULT_MARGIN_NM, *,
                 layers: tuple[str, ...] = (), units: str | None = None,
                 transform: Transform = NO_TRANSFORM,
                 config: MachineConfig | None = None) -> Artwork:
    """Read `source` (a path, or a Program already read) and find where it sits;
    `layers` and `units` are a DXF drawing's (readers.read_file); `transform` scales
    and turns it first, a fit to the travel of `config` (the seed's machine if None)."""
    program = source if isinstance(source, Program) \
        else read_file(source, layers=layers, units=units)
    if not transform.is_identity:
        config = config or MachineConfig()
        travel = (round(config.x_travel_mm * NM_PER_MM), round(config.y_travel_mm * NM_PER_MM))
        program, transform = apply_transform(program, transform, travel, margin_nm)
    return Artwork(program, extents(program), extents(program, visited=True), margin_nm,
                   transform)


def resolve_offset(artwork: Artwork, choice: OffsetChoice) -> tuple[int, int]:
    """The offset in nm for "auto", "none", "X,Y" (mm) or an (x, y) pair in nm."""
    if not isinstance(choice, str):
        return (int(choice[0]), int(choice[1]))
    if choice == "auto":
        return artwork.proposal_nm
    if choice == "none":
        return (0, 0)
    try:
        return offset_from_text(choice)
    except ValueError as problem:
        why = f": {problem}" if isinstance(problem, OffsetRangeError) else ""
        raise OffsetError(f"--offset: expected auto, none or X,Y in mm (e.g. 5,4), "
                          f"got {choice!r}{why}") from None


@dataclass(frozen=True)
class _Side:
    """A board side as plan_file needs it: the axis, the holes and crosses as plotted
    (mirrored on the bottom), and the box both sides' offset comes from."""

    name: str
    axis: sides.MirrorAxis
    #: a side of a two-sided job (`side` given): one offset for both, its first line said
    turned_over: bool
    holes: tuple
    crosses: tuple
    board_box_nm: Box | None


def _board_side(artwork: Artwork, options: PlanOptions) -> tuple[Artwork, _Side | None]:
    """The artwork as plotted on its side (the bottom mirrored), and the side."""
    if not options.on_board:
        return artwork, None
    name = options.side or "top"
    holes = tuple(options.holes)
    outline_box = extents(options.outline_program) if options.outline_program is not None \
        else None
    holes_box = drills_box(holes)
    program = artwork.program
    turned = program.metadata.get("side") == "bottom"     # mirrored already (a replan)
    layer_box = reach_box(program)
    try:
        if options.mirror_axis is not None:
            axis = sides.MirrorAxis.at(*options.mirror_axis)
        else:
            axis = sides.default_axis(outline_box, holes_box,
                                      options.board_box_nm or (None if turned else layer_box))
    except TransformError as problem:
        raise PlanError(str(problem)) from None
    crosses = sides.registration_points(holes, outline_box) if options.registration else []
    arm = sides.CROSS_ARM_NM
    crosses_box = union_box(*[(x - arm, y - arm, x + arm, y + arm) for x, y in crosses])
    board_box = options.board_box_nm or union_box(outline_box, holes_box) or \
        (axis.box(layer_box) if turned else layer_box)
    board_box = union_box(board_box, crosses_box)
    if name == "bottom":
        holes = tuple(sides.mirror_drills(holes, axis))
        crosses = [axis.point(x, y) for x, y in crosses]
        if not turned:
            program = sides.side_program(program, name, axis)
            program = dataclasses.replace(program, metadata={**program.metadata,
                                                             "side": "bottom"})
            artwork = Artwork(program, extents(program), extents(program, visited=True),
                              artwork.margin_nm, artwork.transform)
    return artwork, _Side(name, axis, options.side is not None, holes, tuple(crosses),
                          board_box)


def _smallest_pen(options: PlanOptions, config: MachineConfig) -> int:
    return min(options.pens_nm or config.pen_widths_nm)


def plan_file(source: str | Path | Program | Artwork, config: MachineConfig | None = None,
              offset: OffsetChoice = "auto", *, options: PlanOptions = PlanOptions(),
              margin_nm: int = DEFAULT_MARGIN_NM, group: bool = True,
              optimize: bool | None = None,
              on_progress: Callable[[int, int], None] | None = None,
              on_stage: Callable[[str], None] | None = None) -> PlannedFile:
    """Read (unless given an Artwork), offset, ink (in ink mode) and plan; PlanError says
    why a job cannot run: too big for the travel (before any planning), or the op that
    leaves it. `group=False` is the older spelling of options.file_order; `optimize`
    (None: unless file order) is for replanning a journaled job exactly as it was.
    `on_stage(text)` hears the stages (the ink's, inking.ink_program, then path order)
    of files of PLANNING_NOTICE_OPS ops or more: the largest take seconds a stage
    before the first `on_progress`."""
    with collector_paused():        # millions of objects, none in a cycle (collector.py)
        config = config or MachineConfig()
        artwork = source if isinstance(source, Artwork) else \
            load_artwork(source, margin_nm, layers=options.layers, units=options.units,
                         transform=options.transform, config=config)
        artwork, side = _board_side(artwork, options)
        if (problem := artwork.misfit(config)) is not None:
            raise PlanError(f"{problem}: {artwork.way_out()}")
        feed_warnings = check_feeds(artwork.program, config)   # PlanError above the limit
        offset_nm = resolve_offset(artwork, offset)
        if side is not None and side.turned_over and offset == "auto":
            offset_nm = sides.shared_offset(side.board_box_nm, side.axis, artwork.margin_nm)
        mode = options.mode_for(artwork.program)
        stage = on_stage if on_stage is not None and len(artwork.program) >= PLANNING_NOTICE_OPS \
            else (lambda _text: None)
        ink = None
        # centre lines and dots are the same under %LM/%LR/%LS: one pen per D code of the file
        plotted = with_source_apertures(artwork.program)
        file_order = options.file_order or not group
        plotted_format = "gerber" if mode == "ink" else plotted.format
        if optimize is None:
            optimize = not file_order and (plotted_format in ORDERED_FORMATS or options.optimize)
        ordered = None
        marks = marks_for(side.holes, options.drill_marks, options.drill_mark_nm,
                          INK_TOLERANCE_NM) if side is not None else []
        pen = _smallest_pen(options, config)
        mark_warnings: list[str] = []
        cutter = None
        inked_over: list = []      # centre lines inked past the copper's edge, and crosses
        if mode == "ink":
            # a mark leaves a ring the smallest pen fills: its width and the edge margins
            # (the ink's own limit for what it fills, inking.py)
            cutter = MarkCutter(marks, pen + 2 * DEFAULT_EDGE_MARGIN_NM + 4 * INK_TOLERANCE_NM,
                                pen, INK_TOLERANCE_NM) if marks else None
            paths = ink_paths(artwork.program, options.pens_nm or config.pen_widths_nm,
                              on_stage=stage, bare=cutter)
            if cutter is not None:
                mark_warnings = cutter.fitted.warnings
            if offset == "auto" and not (side and side.turned_over):
                # fills reach out to the copper's edges, past the centre lines and flash
                # points the proposal was made from: the margin is kept from the ink
                offset_nm = offset_for_box(union_box(artwork.visited_box_nm, paths.box_nm()),
                                           artwork.margin_nm)
            if side is not None and side.crosses:
                # walks of the smallest pen, clear of the marks, of the centre lines' ink
                # (the necks' too: their ink also passes the copper's edge) and of every
                # island but the hole's own pad
                lines = [piece for feature in paths.narrow + paths.necks
                         for piece in feature.pieces]
                crosses = clear_strokes(sides.cross_strokes(side.crosses),
                                        paths.copper.native, paths.bare, pen,
                                        CLEARANCE_NM, INK_TOLERANCE_NM, lines)
                paths.add_strokes(crosses)
                inked_over += crosses
            # path order from the walks' ends meanwhile (walk_order.py), as
            # plan_program would order the rows, while their arcs are fitted
            order = paths.start_order(offset_nm, config.nm_per_step) \
                if optimize and not file_order else None
            try:
                ink = paths.finish()
                plotted = ink.program
                if order is not None:
                    stage("ordering the paths to cut pen-up travel")
                    ordered = order.rows(plotted)
            finally:
                if order is not None:
                    order.cancel()
        else:
            if marks:
                plotted, mark_warnings = ring_flashes(plotted, marks, pen)
                plotted = clear_centre_lines(plotted, marks, pen, INK_TOLERANCE_NM)
            if optimize:
                stage("ordering the paths to cut pen-up travel")
            if side is not None and side.crosses:
                # centre lines: the crosses with a pen of their own, last
                plotted = sides.with_strokes(plotted, sides.cross_strokes(side.crosses),
                                             max(plotted.apertures, default=0) + 1, pen)
        drawn_lines = _board_lines(side, options) if side is not None else []
        roles: dict[int, str] = {}
        if drawn_lines:
            forbidden = _lines_keep_out(ink, inked_over, artwork.program, plotted, marks, pen,
                                        max(options.pens_nm or config.pen_widths_nm))
            drawn_lines = [clear_of(layer.role, layer.strokes, forbidden)
                           for layer in drawn_lines]
            plotted, roles, line_rows = with_lines(plotted, drawn_lines, pen,
                                                   config.nm_per_step, INK_TOLERANCE_NM)
            if ordered is not None and line_rows:
                ordered = _ordered_with(ordered, line_rows)
        job = plan_program(plotted, config, offset_nm, group=not file_order,
                           on_progress=on_progress, optimize=optimize, ordered=ordered)
        for tool, role in roles.items():
            job.pen_labels[tool] = f"{PEN_NAMES[role]} ({mm_text(pen)} mm)"
        # freed before the collector runs again: its first collection walks what was
        # made while it was paused and is still held (hellboard: 0.15 s with these rows)
        ordered = None
        job.mode = mode
        job.pens_nm = ink.pens_nm if ink is not None else ()
        job.layers, job.units = tuple(options.layers), options.units
        job.scale, job.rotate_deg = artwork.transform.scale, artwork.transform.rotate_deg
        if side is None:
            return PlannedFile(artwork, offset_nm, job, plotted, mode, ink,
                               tuple(feed_warnings))
        bare = cutter.fitted.bare(INK_TOLERANCE_NM, 0) if cutter is not None else []
        line = side.axis.describe(side.name, offset_nm) if side.turned_over else ""
        line_warnings = tuple(w for layer in drawn_lines
                              if (w := layer.warning(pen, CLEARANCE_NM)) is not None)
        return PlannedFile(artwork, offset_nm, job, plotted, mode, ink, tuple(feed_warnings),
                           line, tuple(mark_warnings), side.holes, bare,
                           side.axis if side.turned_over else None, line_warnings, roles)


def _board_lines(side: _Side, options: PlanOptions) -> list[BoardLines]:
    """The outline (if asked for) and the side's silk as centre lines, as plotted on
    the side (the bottom's mirrored about its axis), before they are kept off copper."""
    wanted = [(OUTLINE, options.outline_program if options.outline else None),
              (SILK, options.silk_program)]
    layers = []
    for role, program in wanted:
        if program is None:
            continue
        program = sides.side_program(program, side.name, side.axis)
        layers.append(BoardLines(role, tuple(centre_lines(program, INK_TOLERANCE_NM))))
    return layers


def _lines_keep_out(ink: InkPlan | None, inked_over: list, copper: Program, plotted: Program,
                    marks: list, pen_nm: int, widest_pen_nm: int) -> list:
    """Where the outline and silk must not go (board_lines.keep_out): in ink mode the
    ink's copper, its centre lines, necks and crosses (the smallest pen's) and the bare
    marks;
    in centre mode the copper and every centre line as the widest pen would draw it
    (which pen an aperture gets is the user's), and the marks."""
    if ink is not None:
        lines = inked_over + [piece for feature in ink.narrow + ink.necks
                              for piece in feature.pieces]
        return keep_out(ink.copper.native, lines, pen_nm // 2, ink.bare, pen_nm, CLEARANCE_NM)
    bare = [ring for mark in marks for ring in mark.polygons(INK_TOLERANCE_NM)]
    return keep_out(dark_geometry(copper, INK_TOLERANCE_NM).native,
                    centre_lines(plotted, INK_TOLERANCE_NM), widest_pen_nm // 2, bare, pen_nm,
                    CLEARANCE_NM)


def _ordered_with(ordered, rows: list[tuple[int, list[int]]]):
    """The ink's rows in plotting order, then `rows` (the outline's and silk's)."""
    if isinstance(ordered, OrderedRows):
        return OrderedRows(np.concatenate([ordered.indices,
                                           np.array([i for i, _ in rows], dtype=np.int64)]),
                           np.concatenate([ordered.table,
                                           np.array([r for _, r in rows], dtype=np.int64)]))
    return list(ordered) + rows
