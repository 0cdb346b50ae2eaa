"""`convert FILE|BOARD --mill isolate|drill|cutout -o out.nc`: a mill's G-code (plan/mill/,
docs/mill.md): the isolation passes round a copper layer, the board's holes and slots
drilled bit by bit, or the cut-out along its outline with tabs.

The tool and its cut come from the profile's `[mill]` table, with `--mill-set KEY=VALUE`
over it (the table's keys and units: `--mill-set passes=2 --mill-set tool=endmill`).
A board (a folder, .zip or .gbrjob) gives its `--side` copper, every drill file's holes
and its outline; on `--side bottom` all three are mirrored about the board's axis as the
plotter's bottom is (plan/sides.py), so the bottom's work lands on the top's after the
turn-over. Coordinates are the board's own (work zero at the board's origin), so the
isolation, drilling and cut-out files of one board agree.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

from dataclasses import dataclass

from galileo_cnc.config.machine import ConfigError
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError

MILL_JOBS = ("isolate", "drill", "cutout", "all")


def add_mill_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mill", choices=MILL_JOBS,
                        help="write a mill's G-code instead of a plot: isolate (passes "
                        "round every copper island at the tool's cut), drill (a board's "
                        "holes and slots, bit by bit), cutout (along the board's outline, "
                        "with tabs), all (the three in that order, a tool change between); "
                        "docs/mill.md")
    parser.add_argument("--mill-set", action="append", default=[], metavar="KEY=VALUE",
                        help="a [mill] key over the profile's (e.g. passes=2, "
                        "tool=endmill, diameter_mm=0.3); may be repeated")
    parser.add_argument("--accept-shorts", action="store_true",
                        help="--mill isolate: write the passes although some islands are "
                        "closer than the tool can part (they are listed)")
    parser.add_argument("--drill-order", choices=("plated-first", "unplated-first"),
                        default="plated-first", help="--mill drill: which holes first")


def mill_table(pairs: list[str]) -> dict:
    """`--mill-set` KEY=VALUE pairs as a [mill] table: numbers as numbers, true/false as
    booleans, a list of numbers (drills=0.8,1.0) as a list, the rest text."""
    table: dict = {}
    for pair in pairs:
        key, equals, text = pair.partition("=")
        if not equals or not key.strip():
            raise ConfigError(f"--mill-set {pair!r}: expected KEY=VALUE, e.g. passes=2")
        value = _value(text.strip())
        table[key.strip()] = [value] if key.strip() == "drills" and \
            not isinstance(value, list) else value
    return table


def _value(text: str):
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    if "," in text:
        return [_value(part.strip()) for part in text.split(",")]
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            continue
    return text


class _MillSource:
    """What the mill works from: one file, or a board's side (the bottom mirrored)."""

    def __init__(self, args: argparse.Namespace, choice):
        from galileo_cnc.readers.board import is_board
        self.path = args.file
        self.board = None
        if is_board(args.file):
            from galileo_cnc.plan.board_plan import BoardChoice
            from galileo_cnc.readers.board import open_board
            self.choice = choice or BoardChoice()
            self.board = open_board(args.file, self.choice.layers)

    def close(self) -> None:
        if self.board is not None:
            self.board.close()

    def needs_board(self, job: str) -> None:
        if self.board is None:
            raise GalileoError(f"{os.fsdecode(self.path)}: --mill {job} needs a board (a "
                               f"folder, .zip or .gbrjob with its drill files and outline)")

    def _side(self):
        """The side's copper, its plan options and the mirror axis (None on the top)."""
        from galileo_cnc.plan import sides
        from galileo_cnc.plan.board_plan import board_holes, side_options
        from galileo_cnc.program.drills import drills_box
        from galileo_cnc.program.extents import extents
        copper, options = side_options(self.board, self.choice)
        if self.choice.side == "top":
            return copper, options, None
        outline = options.outline_program
        axis = (sides.MirrorAxis.at(*self.choice.mirror_axis) if self.choice.mirror_axis
                else sides.default_axis(extents(outline) if outline is not None else None,
                                        drills_box(board_holes(self.board)),
                                        options.board_box_nm))
        return copper, options, axis

    def copper(self):
        from galileo_cnc.plan import sides
        from galileo_cnc.readers import read_file
        if self.board is None:
            return read_file(self.path)
        copper, _, axis = self._side()
        return copper if axis is None else sides.side_program(copper, "bottom", axis)

    def holes(self) -> list:
        from galileo_cnc.plan import sides
        from galileo_cnc.plan.board_plan import board_holes
        self.needs_board("drill")
        _, _, axis = self._side()
        holes = board_holes(self.board)
        if not holes:
            raise GalileoError(f"{self.board.source}: no holes or slots: the board has no "
                               f"drill file (info BOARD lists the files; --layer "
                               f"FILE=drill places one)")
        return holes if axis is None else sides.mirror_drills(holes, axis)

    def outline(self):
        from galileo_cnc.plan import sides
        self.needs_board("cutout")
        _, options, axis = self._side()
        if options.outline_program is None:
            raise GalileoError(f"{self.board.source}: no file is the outline (info BOARD "
                               f"lists the files; --layer FILE=outline places one)")
        outline = options.outline_program
        return outline if axis is None else sides.side_program(outline, "bottom", axis)


def mill_text(args: argparse.Namespace, mill: MillConfig,
              choice=None) -> tuple[str, list[str], str]:
    """The G-code of the `--mill` job, the notes the user should read and what it does
    in a few words; `choice`: the board options given (a BoardChoice, None: none)."""
    from galileo_cnc.plan.mill.cutout import cuts_gcode, plan_cutout
    from galileo_cnc.plan.mill.drill import plan_drilling, plan_gcode
    from galileo_cnc.plan.mill.gcode import mill_gcode
    from galileo_cnc.plan.widths import mm_text
    source = _MillSource(args, choice)
    try:
        if args.mill == "all":
            return _whole_board(args, mill, source)
        if args.mill == "isolate":
            text = mill_gcode(source.copper(), mill, accept_shorts=args.accept_shorts)
            rings = sum(1 for line in text.splitlines() if line.startswith("G1 Z"))
            return text, [], f"{_count(rings, 'ring')} round the copper, {mill.describe()}"
        if args.mill == "drill":
            plan = plan_drilling(source.holes(), mill, args.drill_order)
            items = sum(len(group.items) for group in plan.groups)
            return plan_gcode(plan, mill, os.fsdecode(args.file)), plan.notes, (
                f"{_count(items, 'hole')} and slots with "
                f"{', '.join(mm_text(bit) for bit in sorted(mill.drills_nm))} mm bits, "
                f"{_count(plan.tool_changes, 'bit change')}")
        outline = source.outline()
        plan = plan_cutout(outline, mill)
        edges = sum(1 for cut in plan.cuts if cut.edge)
        tabs = sum(len(cut.tabs) for cut in plan.cuts)
        return cuts_gcode(plan.cuts, mill, outline.source, plan.notes), plan.notes, (
            f"{_count(edges, 'edge')} and {_count(len(plan.cuts) - edges, 'hole')} cut "
            f"with a {mm_text(mill.diameter_nm)} mm end mill through "
            f"{mm_text(mill.board_thickness_nm)} mm, {_count(tabs, 'tab')}")
    finally:
        source.close()


def _whole_board(args: argparse.Namespace, mill: MillConfig,
                 source: "_MillSource") -> tuple[str, list[str], str]:
    """--mill all: isolation, drilling and cut-out as one job, a tool change (M0 naming
    the tool, Z re-zeroed) before the drilling's first bit and before the end mill."""
    from galileo_cnc.plan.mill.cutout import cuts_gcode, plan_cutout
    from galileo_cnc.plan.mill.drill import mm_text, plan_drilling, plan_gcode
    from galileo_cnc.plan.mill.gcode import mill_gcode
    source.needs_board("all")
    isolation = mill_gcode(source.copper(), mill, accept_shorts=args.accept_shorts)
    drilling = plan_drilling(source.holes(), mill, args.drill_order)
    outline = source.outline()
    cutout = plan_cutout(outline, mill)
    first_bit = f"{mm_text(drilling.groups[0].bit_nm)} mm bit"
    end_mill = f"{mm_text(mill.diameter_nm)} mm end mill"
    text = joined_jobs([(isolation, None),
                        (plan_gcode(drilling, mill, os.fsdecode(args.file)), first_bit),
                        (cuts_gcode(cutout.cuts, mill, outline.source, cutout.notes),
                         end_mill)], mill)
    notes = drilling.notes + cutout.notes
    return text, notes, (f"isolation ({mill.describe()}), drilling "
                         f"({drilling.tool_changes + 1} bit(s)), cut-out with the "
                         f"{end_mill}: {_count(drilling.tool_changes + 2, 'tool change')}")


def joined_jobs(parts: list[tuple[str, str | None]], mill: MillConfig) -> str:
    """Mill jobs' G-code as one: before each next part a tool change to its tool
    (drill.tool_change_lines), its own start (modes, safe height, spindle on) left
    out, as every part's end (M2) but the last's."""
    from galileo_cnc.plan.mill.drill import tool_change_lines
    out: list[str] = []
    for k, (text, tool) in enumerate(parts):
        lines = text.splitlines()
        if k < len(parts) - 1 and lines and lines[-1] == "M2":
            lines = lines[:-1]
        if tool is not None:
            start = lines.index("G21 G90 G17 G94")
            spindle = next(i for i, line in enumerate(lines) if line.startswith("M3"))
            lines = lines[:start] + tool_change_lines(tool, mill) + lines[spindle + 1:]
        out += lines
    return "\n".join(out) + "\n"


def _count(n: int, what: str) -> str:
    return f"{n} {what}{'' if n == 1 else 's'}"


def mill_program(file, job: str, mill: MillConfig, choice=None, *, accept_shorts: bool = False,
                 drill_order: str = "plated-first"):
    """(MillProgram, notes, summary): the `--mill` job of a file or board (job one of
    MILL_JOBS) as a machine runs it (Machine.prepare_mill; grbl/mill_job.py)."""
    from galileo_cnc.grbl.mill_job import MillProgram
    from galileo_cnc.readers.gcode.writer import mm
    if job not in MILL_JOBS:
        raise GalileoError(f"--mill {job!r}: must be one of {', '.join(MILL_JOBS)}")
    args = argparse.Namespace(file=file, mill=job, accept_shorts=accept_shorts,
                              drill_order=drill_order)
    text, notes, summary = mill_text(args, mill, choice)
    name = f"{os.path.basename(os.fsdecode(file).rstrip('/'))} (--mill {job})"
    program = MillProgram(text, os.fsdecode(file), name, mm(mill.safe_height_nm),
                          mm(mill.plunge_feed_um_min * 1000))
    return program, notes, summary


@dataclass(frozen=True)
class MillRequest:
    """`plot --mill JOB` (and its options): what PlotOptions.mill carries."""

    job: str                            # one of MILL_JOBS
    mill_set: tuple[str, ...] = ()      # --mill-set KEY=VALUE over the profile's [mill]
    accept_shorts: bool = False
    drill_order: str = "plated-first"

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> "MillRequest | None":
        """The request add_mill_options' options make, None without --mill."""
        if not getattr(args, "mill", None):
            return None
        return cls(args.mill, tuple(args.mill_set), args.accept_shorts, args.drill_order)


#: What sim:// (or a galileo-cnc plotter: it runs no G-code) does with a mill job.
DRY_RUN_NOTE = ("a dry run: the mill job's XY paths are plotted from its G-code (Z at or "
                "below 0 cuts, drawn with the pen down; M3/M5 lower and lift the pen, no "
                "spindle turns); every G38.2 touches at once at the touch plate's top (work "
                "Z = the plate's thickness: the Z zero stays) and the M0 pauses are listed, "
                "not waited for")
#: The dry run's G-code, kept for plot --resume on sim://.
DRY_RUN_NAME = "mill-dry-run.nc"


def run_mill_plot(options, out=None) -> int:
    """`plot FILE|BOARD --mill JOB`: the mill job on the machine at --port through the
    machine interface: GRBL runs its G-code (grbl/mill_job.py: M0 pauses asked like
    pen changes, G38.2, the journal, --resume); elsewhere (sim://, our firmware) a dry
    run, plotted as DRY_RUN_NOTE says."""
    from galileo_cnc.backends import open_machine
    from galileo_cnc.cli.plot import PlotOperator, TextProgress, _run, run_plot
    from galileo_cnc.transport.discovery import GRBL, open_board
    from galileo_cnc.transport.port import SIM_URL
    out = out if out is not None else sys.stdout
    request: MillRequest = options.mill
    profile = options.profile
    mill = MillConfig.from_table(mill_table(list(request.mill_set)), "--mill-set",
                                 base=profile.mill)
    program = notes = summary = None
    if not options.resume:
        program, notes, summary = mill_program(options.file, request.job, mill, options.board,
                                               accept_shorts=request.accept_shorts,
                                               drill_order=request.drill_order)
    port, kind, handle = profile.port or SIM_URL, options.kind, options.handle
    if kind is None:                    # cli/main probes before; a caller may not have
        port, kind, handle = open_board(profile.port, profile.baud)
    if kind != GRBL:
        out.write(f"note: {port} runs galileo-cnc firmware, not G-code: {DRY_RUN_NOTE}\n")
        return _dry_run(dataclasses.replace(options, handle=handle, kind=kind), program, out,
                        run_plot)
    if options.trace or options.preview:
        if handle is not None:
            handle.close()
        raise GalileoError("plot --mill on GRBL writes no --trace or --preview (the "
                           "convert --mill G-code shows the paths)")
    progress = TextProgress(out)
    operator = PlotOperator(progress, options.yes)
    machine = open_machine(port, profile, on_message=progress.message, handle=handle,
                           kind=kind, shown_as=profile.port or port)
    named = dataclasses.replace(options, file=f"{os.fsdecode(options.file)} --mill "
                                              f"{request.job}")
    try:
        out.write(machine.describe() + "\n")
        if options.resume:
            resumption = machine.plan_mill_resume(machine.pending_mill())
            progress.message(resumption.why)
            if resumption.job is None:
                progress.message(resumption.nothing_left)
                return 0
            result = _run(machine, named, operator, lambda: machine.resume(resumption, operator))
        else:
            for note in notes:
                progress.message(f"note: {note}")
            out.write(f"{program.name}: {summary}\n")
            if mill.height_map:
                program = _with_height_map(machine, program, mill, operator, progress)
            job = machine.prepare_mill(program)
            out.write(f"{job.estimate_line()}\n")
            result = _run(machine, named, operator, lambda: machine.run_job(job, operator))
        if isinstance(result, int):
            return result
        where = f"; {result.where}" if result.where else ""
        progress.message(f"\amill job finished{where}")
        return 0
    finally:
        machine.close()


def _with_height_map(machine, program, mill: MillConfig, operator, progress):
    """[mill] height_map = true: the surface under the cuts probed (the user clips the
    probe on first, and takes it off after), the program to follow it; the map goes
    into the job's journal with it (grbl/mill_job.py)."""
    from galileo_cnc.plan.mill.heightmap import job_grid
    grid = job_grid(program.text.splitlines(), mill, program.name)
    if not operator.confirm(f"height map: clip the probe to the tool; it probes "
                            f"{grid.describe()}"):
        raise GalileoError("the height map was not probed: nothing was cut")
    height_map = machine.probe_height_map(grid)
    progress.message(height_map.describe())
    if not operator.confirm("height map probed: take the probe clip off the tool"):
        raise GalileoError("the probe clip stays on: nothing was cut")
    return dataclasses.replace(program, height_map=height_map)


def _dry_run(options, program, out, run_plot) -> int:
    """sim:// (or our firmware): the job's G-code plotted as DRY_RUN_NOTE says."""
    from galileo_cnc.config.userdirs import data_dir
    from galileo_cnc.grbl.mill_job import mill_lines
    path = data_dir() / DRY_RUN_NAME
    if program is not None:
        lines, pauses = mill_lines(program.text)
        for index, message in pauses.items():
            out.write(f"M0 at {program.name}:{lines[index].command + 1}: {message}\n")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(dry_run_gcode(program.text), encoding="ascii")
    return run_plot(dataclasses.replace(options, file=str(path), mill=None, board=None), out)


def dry_run_gcode(text: str) -> str:
    """The mill job's G-code as the G-code reader plots it: each G38.2 a move down to
    the plate's top (the G92 after it names it) and that G92 left out, M0 kept as a
    comment."""
    lines = text.splitlines()
    out = []
    for k, line in enumerate(lines):
        code = line.split("(")[0].strip()
        if code.startswith("G38.2"):
            after = lines[k + 1].split() if k + 1 < len(lines) else []
            plate = next((w[1:] for w in after if w.startswith("Z")), "0") \
                if after[:1] == ["G92"] else "0"
            feed = next((f" {w}" for w in code.split() if w.startswith("F")), "")
            out.append(f"G1 Z{plate}{feed} (G38.2: the probe touches the plate's top)")
        elif code.startswith("G92") and k and lines[k - 1].startswith("G38.2"):
            out.append(f"({code}: the zero stays)")
        elif code.split()[:1] in (["M0"], ["M00"]):
            said = "; ".join(part.split(")")[0] for part in line.split("(")[1:])
            out.append(f"(M0: {said})")
        else:
            out.append(line)
    return "\n".join(out) + "\n"


def run_mill_convert(args: argparse.Namespace, profile, choice=None) -> int:
    """convert --mill: the G-code written to --output (checked writable by the caller)."""
    mill = MillConfig.from_table(mill_table(args.mill_set), "--mill-set", base=profile.mill)
    text, notes, summary = mill_text(args, mill, choice)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    try:
        with open(args.output, "w", encoding="ascii", newline="\n") as out:
            out.write(text)
    except OSError as problem:
        raise GalileoError(f"--output {args.output}: cannot write: {problem.strerror}") from None
    print(f"{os.fsdecode(args.output)}: {text.count(chr(10))} lines: {summary}")
    return 0
