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

from galileo_cnc.errors import GalileoError
# the job's setup is shared with the console and the web page (grbl/mill_plan.py)
from galileo_cnc.grbl.mill_plan import MILL_JOBS, MillRequest, mill_text, with_height_map


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
    from galileo_cnc.cli.plot import PlotOperator, TextProgress, _run
    from galileo_cnc.transport.discovery import GRBL, open_board
    from galileo_cnc.transport.port import SIM_URL
    out = out if out is not None else sys.stdout
    request: MillRequest = options.mill
    profile = options.profile
    mill = request.mill(profile.mill)
    program = notes = summary = None
    if not options.resume:
        program, notes, summary = request.program(options.file, mill, options.board)
    port, kind, handle = profile.port or SIM_URL, options.kind, options.handle
    if kind is None:                    # cli/main probes before; a caller may not have
        port, kind, handle = open_board(profile.port, profile.baud)
    if kind != GRBL:
        out.write(f"note: {port} runs galileo-cnc firmware, not G-code: {DRY_RUN_NOTE}\n")
        return _dry_run(dataclasses.replace(options, handle=handle, kind=kind), program, out)
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
                program = with_height_map(machine, program, mill, operator.confirm,
                                          progress.message)
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


def _dry_run(options, program, out) -> int:
    """sim:// (or our firmware): the job's G-code plotted as DRY_RUN_NOTE says."""
    from galileo_cnc.cli.plot import run_plot
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
    request = MillRequest.from_args(args)
    text, notes, summary = mill_text(args.file, request, request.mill(profile.mill), choice)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    try:
        with open(args.output, "w", encoding="ascii", newline="\n") as out:
            out.write(text)
    except OSError as problem:
        raise GalileoError(f"--output {args.output}: cannot write: {problem.strerror}") from None
    print(f"{os.fsdecode(args.output)}: {text.count(chr(10))} lines: {summary}")
    return 0
