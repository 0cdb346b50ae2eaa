"""`getg [FILE]`: read a file, agree on offsets, plan, and stream the job.

The seed's flow: show the minimum X/Y, propose the offset that brings the artwork
to the origin (plus a margin), ask y/n, then plot with a progress bar and pen
changes. Lengths are nm inside; mm only in what is printed and typed.
"""

from __future__ import annotations

import os

from prompt_toolkit.completion import PathCompleter

from galileo_cnc.config.machine import pen_widths_from_text
from galileo_cnc.console import jobs
from galileo_cnc.plan.offsets import offset_from_text
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.open_traces import ink_warnings, open_traces
from galileo_cnc.plan.pipeline import PLANNING_NOTICE_OPS, Artwork, PlanOptions, load_artwork
from galileo_cnc.program.ops import NM_PER_MM


def run(console, arguments: list[str]) -> None:
    options, config, arguments = _options(console, arguments)
    path = " ".join(arguments) if arguments else console.ask(
        "file to plot: ", completer=PathCompleter(expanduser=True))
    if not path:
        return
    console.machine.check_profile()         # e.g. a board built for another machine
    artwork = load_artwork(os.path.expanduser(path), layers=options.layers,
                           units=options.units)     # GalileoError: one message, no traceback
    if (problem := artwork.misfit(console.config)) is not None:
        console.say(problem)                          # before any question or planning
        return
    offset_nm = choose_offset(console, artwork)
    if offset_nm is None:
        return
    if len(artwork.program) >= PLANNING_NOTICE_OPS:
        console.say(f"planning {len(artwork.program)} operations ...")
    # the accepted proposal is "auto": in ink mode the fills may need more room
    choice = "auto" if offset_nm == artwork.proposal_nm else offset_nm
    planned = console.plans.plan_file(artwork, config, choice,  # PlanError: file:line
                                      options=options, on_stage=console.say_stage)
    if planned.offset_nm != offset_nm:
        console.say(f"offsets     X {_mm(planned.offset_nm[0])} mm, Y {_mm(planned.offset_nm[1])} "
                    "mm (the ink reaches past the centre lines)")
    if planned.ink is not None:
        for warning in ink_warnings(planned.ink):
            console.say(warning)
        if open_traces(planned.ink) is not None and \
                not console.confirm("plot it with these trace pieces left out?", default=False):
            console.say("not plotted (getg --pens MM,MM plans it for other pens)")
            return
    jobs.plot(console, planned, config)


def _options(console, arguments: list[str]) -> tuple[PlanOptions, object, list[str]]:
    """`--mode ink|centre`, `--pens 0.3,0.8` (the profile's pens otherwise), a DXF
    drawing's `--layers A,B` and `--units mm|in`, and `--optimize` (order G-code's
    paths too), before the file name; GalileoError for anything else that starts
    with --."""
    mode, config, rest = "auto", console.config, list(arguments)
    layers: tuple[str, ...] = ()
    units = None
    optimize = False
    while rest and rest[0].startswith("--"):
        flag = rest.pop(0)
        if flag == "--optimize":                  # the one option without a value
            optimize = True
            continue
        value = rest.pop(0) if rest else ""
        if flag == "--mode" and value in ("ink", "centre"):
            mode = value
        elif flag == "--pens":
            config = config.replace(pen_widths_mm=pen_widths_from_text(value))
        elif flag == "--layers" and value:
            layers = tuple(name.strip() for name in value.split(",") if name.strip())
        elif flag == "--units" and value in ("mm", "in"):
            units = value
        else:
            raise GalileoError(f"getg: unknown option {flag} {value}".rstrip()
                               + " (getg [--mode ink|centre] [--pens MM,MM] [--layers A,B] "
                               "[--units mm|in] [--optimize] [FILE])")
    return PlanOptions(mode=mode, layers=layers, units=units, optimize=optimize), config, rest


def choose_offset(console, artwork: Artwork) -> tuple[int, int] | None:
    """The offset to subtract, in nm: the proposal, the user's, or none (None: nothing drawn)."""
    box = artwork.drawn_box_nm
    if box is None:
        console.say(f"{artwork.program.source}: nothing is drawn")
        return None
    proposal = artwork.proposal_nm
    console.say(f"minimum     X {_mm(box[0])} mm, Y {_mm(box[1])} mm")
    console.say(f"offsets     X {_mm(proposal[0])} mm, Y {_mm(proposal[1])} mm "
                f"(brings the job to the origin plus a {artwork.margin_nm / NM_PER_MM:g} mm "
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
