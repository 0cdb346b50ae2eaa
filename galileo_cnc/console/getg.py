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
    if artwork.drawn_box_nm is None:
        console.say(f"{artwork.program.source}: nothing is drawn")
        return

    def plan(offset):
        if len(artwork.program) >= PLANNING_NOTICE_OPS:
            console.say(f"planning {len(artwork.program)} operations ...")
        return console.plans.plan_file(artwork, config, offset,  # PlanError: file:line
                                       options=options, on_stage=console.say_stage)

    # ink fills reach past the centre lines the proposal is made from: the offset
    # asked about is the one the ink plan uses, so the ink is planned first
    planned = plan("auto") if options.mode_for(artwork.program) == "ink" else None
    offset_nm = choose_offset(console, artwork, planned)
    if offset_nm is None:
        return
    if planned is None or planned.offset_nm != offset_nm:
        planned = plan("auto" if offset_nm == artwork.proposal_nm else offset_nm)
    if planned.ink is not None:
        for warning in planned.ink.warnings_to_show():
            console.say(warning)
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


def choose_offset(console, artwork: Artwork, inked=None) -> tuple[int, int] | None:
    """The offset to subtract, in nm: the proposal (the ink plan's, when `inked` is
    given), the user's, or none (None: nothing drawn)."""
    box = artwork.drawn_box_nm
    if box is None:
        console.say(f"{artwork.program.source}: nothing is drawn")
        return None
    margin = artwork.margin_nm
    if inked is None:
        proposal, what = artwork.proposal_nm, "job"
        console.say(f"minimum     X {_mm(box[0])} mm, Y {_mm(box[1])} mm")
    else:
        proposal, what = inked.offset_nm, "ink"
        console.say(f"minimum     X {_mm(proposal[0] + margin)} mm, Y "
                    f"{_mm(proposal[1] + margin)} mm (where the pen goes, fills included)")
    console.say(f"offsets     X {_mm(proposal[0])} mm, Y {_mm(proposal[1])} mm "
                f"(brings the {what} to the origin plus a {margin / NM_PER_MM:g} mm margin)")
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
    return f"{round(nm / NM_PER_MM, 4) + 0.0:.4f}"     # + 0.0: never "-0.0000"
