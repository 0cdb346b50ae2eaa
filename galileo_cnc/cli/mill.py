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
from galileo_cnc.grbl.mill_plan import (DRY_RUN_NOTE, MILL_JOBS, MillRequest, dry_run_path,
                                        mill_text, with_height_map, write_dry_run)


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
    path = dry_run_path()
    if program is not None:
        for line in write_dry_run(program, path):
            out.write(line + "\n")
    return run_plot(dataclasses.replace(options, file=str(path), mill=None, board=None), out)


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
