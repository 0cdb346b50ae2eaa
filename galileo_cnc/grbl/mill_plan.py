"""A mill job set up from a file or a board, for every front end (`plot --mill` and
`convert --mill` in cli/mill.py, the console's `getg --mill`, the web page's plan
request): the profile's [mill] table with `--mill-set KEY=VALUE` over it, the board's
side (its copper, holes and outline; the bottom mirrored as plan/sides.py does), and
the job's G-code as a MillProgram (grbl/mill_job.py) with the notes and a summary.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass

from galileo_cnc.config.machine import ConfigError
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.errors import GalileoError

MILL_JOBS = ("isolate", "drill", "cutout", "all")


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

    def __init__(self, file, choice):
        from galileo_cnc.readers.board import is_board
        self.path = file
        self.board = None
        if is_board(file):
            from galileo_cnc.plan.board_plan import BoardChoice
            from galileo_cnc.readers.board import open_board
            self.choice = choice or BoardChoice()
            self.board = open_board(file, self.choice.layers)

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


def mill_text(file, request: "MillRequest", mill: MillConfig,
              choice=None) -> tuple[str, list[str], str]:
    """The G-code of the `--mill` job `request` asks of `file` (a file or a board), the
    notes the user should read and what it does in a few words; `choice`: the board
    options given (a BoardChoice, None: none)."""
    from galileo_cnc.plan.mill.cutout import cuts_gcode, plan_cutout
    from galileo_cnc.plan.mill.drill import plan_drilling, plan_gcode
    from galileo_cnc.plan.mill.gcode import mill_gcode
    from galileo_cnc.plan.widths import mm_text
    source = _MillSource(file, choice)
    try:
        if request.job == "all":
            return _whole_board(request, mill, source)
        if request.job == "isolate":
            text = mill_gcode(source.copper(), mill, accept_shorts=request.accept_shorts)
            rings = sum(1 for line in text.splitlines() if line.startswith("G1 Z"))
            return text, [], f"{_count(rings, 'ring')} round the copper, {mill.describe()}"
        if request.job == "drill":
            plan = plan_drilling(source.holes(), mill, request.drill_order)
            items = sum(len(group.items) for group in plan.groups)
            return plan_gcode(plan, mill, os.fsdecode(file)), plan.notes, (
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


def _whole_board(request: "MillRequest", mill: MillConfig,
                 source: "_MillSource") -> tuple[str, list[str], str]:
    """--mill all: isolation, drilling and cut-out as one job, a tool change (M0 naming
    the tool, Z re-zeroed) before the drilling's first bit and before the end mill."""
    from galileo_cnc.plan.mill.cutout import cuts_gcode, plan_cutout
    from galileo_cnc.plan.mill.drill import mm_text, plan_drilling, plan_gcode
    from galileo_cnc.plan.mill.gcode import mill_gcode
    source.needs_board("all")
    isolation = mill_gcode(source.copper(), mill, accept_shorts=request.accept_shorts)
    drilling = plan_drilling(source.holes(), mill, request.drill_order)
    outline = source.outline()
    cutout = plan_cutout(outline, mill)
    first_bit = f"{mm_text(drilling.groups[0].bit_nm)} mm bit"
    end_mill = f"{mm_text(mill.diameter_nm)} mm end mill"
    text = joined_jobs([(isolation, None),
                        (plan_gcode(drilling, mill, os.fsdecode(source.path)), first_bit),
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
    text, notes, summary = mill_text(file, MillRequest(job, (), accept_shorts, drill_order),
                                     mill, choice)
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
    def from_args(cls, args) -> "MillRequest | None":
        """The request add_mill_options' options make, None without --mill."""
        if not getattr(args, "mill", None):
            return None
        return cls(args.mill, tuple(args.mill_set), args.accept_shorts, args.drill_order)

    def mill(self, base: MillConfig) -> MillConfig:
        """The profile's [mill] (`base`) with this request's --mill-set over it."""
        return MillConfig.from_table(mill_table(list(self.mill_set)), "--mill-set", base=base)

    def program(self, file, mill: MillConfig, choice=None):
        """(MillProgram, notes, summary) of this job on `file` (mill_program) with the
        tool `mill` (self.mill's)."""
        return mill_program(file, self.job, mill, choice,
                            accept_shorts=self.accept_shorts, drill_order=self.drill_order)


def profile_mill(path=None) -> MillConfig:
    """The [mill] table of the profile at `path` (None: the user's), as `plot` reads it:
    what a front end that keeps only the machine's config (the console, the web page)
    plans a mill job with."""
    from galileo_cnc.config.profile import load_profile
    return load_profile(path).mill


def with_height_map(machine, program, mill: MillConfig, confirm, say):
    """[mill] height_map = true: the surface under the cuts probed on `machine` (the
    user clips the probe on first, and takes it off after: `confirm(question)`), the
    program to follow it; the map goes into the job's journal with it
    (grbl/mill_job.py). `say`: the map's summary."""
    from galileo_cnc.plan.mill.heightmap import job_grid
    grid = job_grid(program.text.splitlines(), mill, program.name)
    if not confirm(f"height map: clip the probe to the tool; it probes {grid.describe()}"):
        raise GalileoError("the height map was not probed: nothing was cut")
    height_map = machine.probe_height_map(grid)
    say(height_map.describe())
    if not confirm("height map probed: take the probe clip off the tool"):
        raise GalileoError("the probe clip stays on: nothing was cut")
    return dataclasses.replace(program, height_map=height_map)


# ---- the dry run (a machine that runs no G-code) ---------------------------------

#: What sim:// (or a galileo-cnc plotter: it runs no G-code) does with a mill job.
DRY_RUN_NOTE = ("a dry run: the mill job's XY paths are plotted from its G-code (Z at or "
                "below 0 cuts, drawn with the pen down; M3/M5 lower and lift the pen, no "
                "spindle turns); every G38.2 touches at once at the touch plate's top (work "
                "Z = the plate's thickness: the Z zero stays) and the M0 pauses are listed, "
                "not waited for")
#: The dry run's G-code, kept for plot --resume on sim://.
DRY_RUN_NAME = "mill-dry-run.nc"


def dry_run_path():
    """Where the dry run's G-code is kept (plot --resume on sim:// reads it again)."""
    return data_dir() / DRY_RUN_NAME


def write_dry_run(program, path) -> list[str]:
    """The program's G-code written to `path` as dry_run_gcode makes it; the lines that
    name each M0 it will not wait for (`M0 at NAME:LINE: message`)."""
    from galileo_cnc.grbl.mill_job import mill_lines
    lines, pauses = mill_lines(program.text)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dry_run_gcode(program.text), encoding="ascii")
    return [f"M0 at {program.name}:{lines[index].command + 1}: {message}"
            for index, message in pauses.items()]


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
