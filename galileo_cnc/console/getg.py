"""`getg [FILE]`: read a file, agree on offsets, plan, and stream the job.

The seed's flow: show the minimum X/Y, propose the offset that brings the artwork
to the origin (plus a margin), ask y/n, then plot with a progress bar and pen
changes. Lengths are nm inside; mm only in what is printed and typed.
"""

from __future__ import annotations

from prompt_toolkit.completion import PathCompleter

from galileo_cnc.machine.timing import duration_text, job_timing
from galileo_cnc.plan.offsets import DEFAULT_MARGIN_NM, offset_from_text, proposed_offset
from galileo_cnc.program.extents import extents
from galileo_cnc.stream.journal import Journal
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.program.ops import NM_PER_MM, Program
from galileo_cnc.readers import read_file
from galileo_cnc.stream.streamer import JobStreamer
from galileo_cnc.console.job_screen import JobScreen, report


def run(console, arguments: list[str]) -> None:
    path = " ".join(arguments) if arguments else console.ask(
        "file to plot: ", completer=PathCompleter(expanduser=True))
    if not path:
        return
    program = read_file(path)                     # GalileoError: one message, no traceback
    offset_nm = choose_offset(console, program)
    if offset_nm is None:
        return
    job = plan_program(program, console.config, offset_nm)   # PlanError names file:line, axis
    timing = job_timing(job.commands, console.config)
    pens = len(job.pen_changes)
    console.say(f"{len(job)} machine commands, {pens} pen change{'s' * (pens != 1)}, "
                f"estimated time {duration_text(timing.total_s)}")
    streamer = JobStreamer(console.link, job, program, journal=Journal.default(), timing=timing)
    result = JobScreen(console, program.source, len(job)).run(streamer.run, streamer.abort)
    report(console, result)


def choose_offset(console, program: Program) -> tuple[int, int] | None:
    """The offset to subtract, in nm: the proposal, the user's, or none (None: nothing drawn)."""
    box = extents(program)
    if box is None:
        console.say(f"{program.source}: nothing is drawn")
        return None
    proposal = proposed_offset(program)
    console.say(f"minimum     X {_mm(box[0])} mm, Y {_mm(box[1])} mm")
    console.say(f"offsets     X {_mm(proposal[0])} mm, Y {_mm(proposal[1])} mm "
                f"(brings the artwork to the origin plus a {DEFAULT_MARGIN_NM / NM_PER_MM:g} mm "
                "margin)")
    if console.confirm("use these offsets?"):
        return proposal
    while True:
        answer = console.ask("offsets X,Y in mm (Enter keeps the file's coordinates): ")
        if not answer:
            return (0, 0)
        try:
            return offset_from_text(answer)
        except ValueError as problem:
            console.say(str(problem))


def _mm(nm: int) -> str:
    return f"{nm / NM_PER_MM:.4f}"
