"""`preview [getg's options] FILE|BOARD [-o OUT]`: a picture of what getg would plot,
without the machine: each side of a board (with the offset getg proposes, one for
both sides), or the file. Written where the user asks (-o) or beside the current
folder's other work, named after the file and the side."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from prompt_toolkit.completion import PathCompleter

from galileo_cnc.console.getg import parse_options
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.board_plan import BoardChoice, copper_sides, plan_board
from galileo_cnc.plan.drill_marks import warnings_to_show
from galileo_cnc.preview.formats import preview_kind
from galileo_cnc.preview.write import write_preview
from galileo_cnc.readers.board import is_board

DEFAULT_SUFFIX = ".png"


def run(console, arguments: list[str]) -> None:
    arguments, output = _output_option(arguments)
    options, config, board, arguments = parse_options(console, arguments, "preview")
    path = " ".join(arguments) if arguments else console.ask(
        "file to preview: ", completer=PathCompleter(expanduser=True))
    if not path:
        return
    path = os.path.expanduser(path)
    if output is not None:
        preview_kind(output, "-o")          # before any planning
    if is_board(path):
        choice = BoardChoice(**board)
        sides = (choice.side,) if "side" in board else copper_sides(path, choice.layers)
        if not sides:
            console.say(f"{path}: no file is top-copper or bottom-copper")
            return
        offset = "auto"
        for side in sides:
            planned = plan_board(path, config, offset, choice=dataclasses.replace(
                choice, side=side), options=options, on_stage=console.say_stage)
            offset = planned.offset_nm      # the other side: the same offset
            console.say(planned.side_line)
            for warning in (*warnings_to_show(planned.drill_mark_warnings),
                            *planned.line_warnings):
                console.say(warning)
            _write(console, planned, config, _name(path, output, side if len(sides) > 1 or
                                                   output is None else None))
        return
    if board:
        raise GalileoError("preview: --side, --drill-marks, --mirror-axis, --registration, "
                           f"--outline, --silk and --layer are for a board; {path} is one file")
    planned = console.plans.plan_file(path, config, "auto", options=options,
                                      on_stage=console.say_stage)
    _write(console, planned, config, _name(path, output, None))


def _output_option(arguments: list[str]) -> tuple[list[str], str | None]:
    """`-o OUT` (anywhere among the arguments) taken out."""
    rest, output = list(arguments), None
    for flag in ("-o", "--output"):
        while flag in rest:
            at = rest.index(flag)
            if at + 1 >= len(rest):
                raise GalileoError(f"preview: {flag} needs a file name (.png, .svg ...)")
            output = os.path.expanduser(rest[at + 1])
            del rest[at:at + 2]
    return rest, output


def _name(source: str, output: str | None, side: str | None) -> str:
    """OUT as given, with `-SIDE` before its extension for each side of a board; else
    the source's name (a folder's, an archive's stem) with the side, as a .png here."""
    if output is not None:
        if side is None:
            return output
        stem, suffix = os.path.splitext(output)
        return f"{stem}-{side}{suffix}"
    stem = Path(source.rstrip("/")).stem
    return f"{stem}-{side}{DEFAULT_SUFFIX}" if side else f"{stem}{DEFAULT_SUFFIX}"


def _write(console, planned, config, output: str) -> None:
    info = write_preview(planned, config, output)
    console.say(f"{output}: {info.summary()}")
