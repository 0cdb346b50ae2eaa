"""`getg [FILE]`: read a file, agree on offsets, plan, and stream the job.

The seed's flow: show the minimum X/Y, propose the offset that brings the artwork
to the origin (plus a margin), ask y/n, then plot with a progress bar and pen
changes. Lengths are nm inside; mm only in what is printed and typed.
"""

from __future__ import annotations

import dataclasses
import os

from prompt_toolkit.completion import PathCompleter

from galileo_cnc.command_text import fixed_text
from galileo_cnc.config.machine import pen_widths_from_text
from galileo_cnc.console import jobs, mill
from galileo_cnc.plan.offsets import offset_from_text
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.board_plan import BoardChoice, copper_sides, plan_board
from galileo_cnc.plan.drill_marks import warnings_to_show
from galileo_cnc.plan.feeds import machine_refusal
from galileo_cnc.plan.open_traces import ink_warnings, open_traces
from galileo_cnc.plan.pipeline import PLANNING_NOTICE_OPS, Artwork, PlanOptions, load_artwork
from galileo_cnc.plan.sides import parse_axis
from galileo_cnc.plan.transform import Transform
from galileo_cnc.readers.board import is_board
from galileo_cnc.program.ops import NM_PER_MM


def run(console, arguments: list[str]) -> None:
    request, arguments = mill.split_mill_options(arguments, PLAN_SWITCHES + BOARD_SWITCHES)
    options, config, board, arguments = parse_options(console, arguments)
    path = " ".join(arguments) if arguments else console.ask(
        "file to plot: ", completer=PathCompleter(expanduser=True))
    if not path:
        return
    if request is not None:                 # getg --mill JOB: the mill job (console/mill.py)
        mill.run(console, request, os.path.expanduser(path), board,
                 plot_gcode=lambda gcode: run(console, [gcode]))
        return
    console.machine.check_profile()         # e.g. a board built for another machine
    if is_board(os.path.expanduser(path)):
        _board(console, os.path.expanduser(path), options, config, board)
        return
    if board:
        raise GalileoError(f"getg: --side, --drill-marks, --mirror-axis, --registration, "
                           f"--outline, --silk and --layer are for a board (a folder, .zip "
                           f"or .gbrjob); {path} is one file")
    artwork = load_artwork(os.path.expanduser(path), layers=options.layers,
                           units=options.units, transform=options.transform,
                           config=console.config)     # GalileoError: one message, no traceback
    if (problem := artwork.misfit(console.config)) is not None:
        # before any question or planning
        console.say(f"{problem}: getg {artwork.way_out()}")
        return
    if (refused := machine_refusal(artwork.program, config,
                                   console.machine.feed_refusal)) is not None:
        console.say(refused)                # GRBL's $110/$111: plan_file knows only ours
        return
    if artwork.transform.describe():
        console.say(f"drawing     {artwork.transform.describe()}")
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
    if not _ink_accepted(console, planned):
        return
    jobs.plot(console, planned, config)


def _ink_accepted(console, planned) -> bool:
    """The ink's and the feeds' warnings said; trace pieces left out asked about."""
    if planned.ink is not None:
        for warning in ink_warnings(planned.ink):
            console.say(warning)
        if open_traces(planned.ink) is not None and \
                not console.confirm("plot it with these trace pieces left out?", default=False):
            console.say("not plotted (getg --pens MM,MM plans it for other pens)")
            return False
    for warning in planned.feed_warnings:
        console.say(warning)
    return True


def _board(console, path: str, options: PlanOptions, config, board: dict) -> None:
    """getg BOARD: the top side, the turn-over, the bottom side, with one offset (the
    bottom mirrored to land on the top); `--side` plots that side alone, and a board
    with copper on one side only has that side plotted (no turn-over). Planned
    afresh each time (the console's PlanCache keeps files, not boards)."""
    choice = BoardChoice(**board)
    sides = (choice.side,) if "side" in board else copper_sides(path, choice.layers)
    one_side = len(sides) == 1
    if not sides:
        console.say(f"{path}: no file is top-copper or bottom-copper (galileo-cnc info BOARD "
                    f"lists the files; --layer FILE=top-copper places one)")
        return
    offset = "auto"
    for side in sides:
        side_choice = dataclasses.replace(choice, side=side)
        planned = plan_board(path, config, offset, choice=side_choice, options=options,
                             on_stage=console.say_stage)
        if offset == "auto":
            offset_nm = choose_offset(console, planned.artwork, planned)
            if offset_nm is None:
                return
            if offset_nm != planned.offset_nm:
                planned = plan_board(path, config, offset_nm, choice=side_choice,
                                     options=options, on_stage=console.say_stage)
            offset = planned.offset_nm      # the other side: the same offset
        console.say(planned.side_line)
        for warning in (*warnings_to_show(planned.drill_mark_warnings),
                        *planned.line_warnings):
            console.say(warning)
        if side == "bottom" and not one_side:
            if not console.confirm(f"turn the blank over about {turn_over_line(planned)} "
                                   f"against the fence; plot the bottom side?"):
                console.say(f"not plotted: getg --side bottom {path} plots it later")
                return
        if not _ink_accepted(console, planned) or not jobs.plot(console, planned, config):
            return                          # stopped: resume finishes this side


def turn_over_line(planned) -> str:
    """`the vertical line X 37.500 mm (work)`: where the blank turns, on the machine."""
    axis = planned.axis
    line = "vertical" if axis.axis == "x" else "horizontal"
    return f"the {line} line {axis.axis.upper()} {axis.on_machine_mm(planned.offset_nm):.3f} " \
           f"mm (work)"


def parse_options(console, arguments: list[str], command: str = "getg"):
    """`--mode ink|centre`, `--pens 0.3,0.8` (the profile's pens otherwise), a DXF
    drawing's `--layers A,B` and `--units mm|in`, and `--optimize` (order G-code's
    paths too), before the file name; a board's `--side`, `--drill-marks`,
    `--mirror-axis`, `--registration`, `--outline`, `--silk` and `--layer FILE=ROLE`;
    GalileoError for anything else that starts with --. (PlanOptions, config, the
    board's choices as BoardChoice's keywords, the rest)."""
    mode, config, rest = "auto", console.config, list(arguments)
    layers: tuple[str, ...] = ()
    units = None
    optimize = fit = False
    scale = rotate = None
    board: dict = {}
    while rest and rest[0].startswith("--"):
        flag = rest.pop(0)
        if flag in PLAN_SWITCHES:                 # the options without a value
            optimize, fit = optimize or flag == "--optimize", fit or flag == "--fit"
            continue
        if flag in BOARD_SWITCHES:
            board[flag[2:]] = True
            continue
        value = rest.pop(0) if rest else ""
        if flag in BOARD_FLAGS:
            _board_option(board, flag, value, command)
            continue
        if flag in ("--scale", "--rotate"):
            scale, rotate = (value, rotate) if flag == "--scale" else (scale, value)
            continue
        if flag == "--mode" and value in ("ink", "centre"):
            mode = value
        elif flag == "--pens":
            config = config.replace(pen_widths_mm=pen_widths_from_text(value))
        elif flag == "--layers" and value:
            layers = tuple(name.strip() for name in value.split(",") if name.strip())
        elif flag == "--units" and value in ("mm", "in"):
            units = value
        else:
            raise GalileoError(f"{command}: unknown option {flag} {value}".rstrip()
                               + f" ({command} [--mode ink|centre] [--pens MM,MM] [--layers A,B] "
                               "[--units mm|in] [--optimize] [--scale F] [--rotate 90|180|270] "
                               "[--fit] [--side top|bottom] [--drill-marks none|small|actual] "
                               "[--mirror-axis x=MM] [--registration] [--outline] [--silk] "
                               "[--layer FILE=ROLE] [FILE])")
    return PlanOptions(mode=mode, layers=layers, units=units, optimize=optimize,
                       transform=Transform.asked(scale, rotate, fit)), config, board, rest


BOARD_FLAGS = ("--side", "--drill-marks", "--mirror-axis", "--layer")
#: getg's options that take no value: the plan's and a board's
PLAN_SWITCHES = ("--optimize", "--fit")
BOARD_SWITCHES = ("--registration", "--outline", "--silk")


def _board_option(board: dict, flag: str, value: str, command: str) -> None:
    if flag == "--side" and value in ("top", "bottom"):
        board["side"] = value
    elif flag == "--drill-marks" and value in ("none", "small", "actual"):
        board["drill_marks"] = value
    elif flag == "--mirror-axis":
        try:
            board["mirror_axis"] = parse_axis(value)
        except ValueError as problem:
            raise GalileoError(f"{command}: {problem}") from None
    elif flag == "--layer" and "=" in value:
        board["layers"] = (*board.get("layers", ()), value)
    else:
        raise GalileoError(f"{command}: {flag} {value}: expected --side top|bottom, --drill-marks "
                           f"none|small|actual, --mirror-axis x=MM or y=MM, --layer FILE=ROLE")


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
    return fixed_text(nm / NM_PER_MM, 4)
