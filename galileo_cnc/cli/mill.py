"""`convert FILE|BOARD --mill isolate -o out.nc`: a mill's G-code (plan/mill/, docs/mill.md).

The tool and its cut come from the profile's `[mill]` table, with `--mill-set KEY=VALUE`
over it (the table's keys and units: `--mill-set passes=2 --mill-set tool=endmill`).
A board (a folder, .zip or .gbrjob) gives its `--side` copper; the bottom is mirrored
about the board's axis as the plotter's bottom is (plan/sides.py), so the milled bottom
lands on the top after the turn-over. Coordinates are the board's own (work zero at the
board's origin), so isolation, drilling and cut-out files of one board agree.
"""

from __future__ import annotations

import argparse
import os

from galileo_cnc.config.machine import ConfigError
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError

MILL_JOBS = ("isolate",)


def add_mill_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mill", choices=MILL_JOBS,
                        help="write a mill's G-code instead of a plot: isolate (passes "
                        "round every copper island at the tool's cut; docs/mill.md)")
    parser.add_argument("--mill-set", action="append", default=[], metavar="KEY=VALUE",
                        help="a [mill] key over the profile's (e.g. passes=2, "
                        "tool=endmill, diameter_mm=0.3); may be repeated")
    parser.add_argument("--accept-shorts", action="store_true",
                        help="--mill isolate: write the passes although some islands are "
                        "closer than the tool can part (they are listed)")


def mill_table(pairs: list[str]) -> dict:
    """`--mill-set` KEY=VALUE pairs as a [mill] table: numbers as numbers, the rest text."""
    table: dict = {}
    for pair in pairs:
        key, equals, text = pair.partition("=")
        if not equals or not key.strip():
            raise ConfigError(f"--mill-set {pair!r}: expected KEY=VALUE, e.g. passes=2")
        text = text.strip()
        for kind in (int, float):
            try:
                table[key.strip()] = kind(text)
                break
            except ValueError:
                continue
        else:
            table[key.strip()] = text
    return table


def copper_to_mill(args: argparse.Namespace):
    """The copper layer to isolate: the file, or the board's `--side` copper (the bottom
    mirrored about the board's axis)."""
    from galileo_cnc.plan import sides
    from galileo_cnc.plan.board_plan import BoardChoice, board_holes, side_options
    from galileo_cnc.program.drills import drills_box
    from galileo_cnc.program.extents import extents
    from galileo_cnc.readers import read_file
    from galileo_cnc.readers.board import is_board, open_board

    if not is_board(args.file):
        return read_file(args.file)
    from galileo_cnc.cli.main import _board_choice
    choice = _board_choice(args) or BoardChoice()
    board = open_board(args.file, choice.layers)
    try:
        copper, options = side_options(board, choice)
        if choice.side == "top":
            return copper
        outline = options.outline_program
        axis = (sides.MirrorAxis.at(*choice.mirror_axis) if choice.mirror_axis else
                sides.default_axis(extents(outline) if outline is not None else None,
                                   drills_box(board_holes(board)), options.board_box_nm))
        return sides.side_program(copper, "bottom", axis)
    finally:
        board.close()


def run_mill_convert(args: argparse.Namespace, profile) -> int:
    from galileo_cnc.cli.main import check_output
    from galileo_cnc.plan.mill.gcode import mill_gcode

    check_output(args.output, "--output")
    mill = MillConfig.from_table(mill_table(args.mill_set), "--mill-set", base=profile.mill)
    program = copper_to_mill(args)
    text = mill_gcode(program, mill, accept_shorts=args.accept_shorts)
    try:
        with open(args.output, "w", encoding="ascii", newline="\n") as out:
            out.write(text)
    except OSError as problem:
        raise GalileoError(f"--output {args.output}: cannot write: {problem.strerror}") from None
    cuts = sum(1 for line in text.splitlines() if line.startswith("G1 Z"))
    print(f"{os.fsdecode(args.output)}: {text.count(chr(10))} lines, {cuts} ring"
          f"{'' if cuts == 1 else 's'} cut with {mill.describe()}")
    return 0
