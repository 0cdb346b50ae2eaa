"""The `galileo-cnc` command line: one sub-command per user task."""

from __future__ import annotations

import argparse
import json
import os
import sys

from . import __version__
from .errors import GalileoError
from .program import NM_PER_MM


def _run_info(args: argparse.Namespace) -> int:
    from .info import format_summary, summarize
    from .readers import read_file

    program = read_file(args.file)
    summary = summarize(program, margin_nm=round(args.margin * NM_PER_MM))
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="galileo-cnc",
        description="Plot Gerber RS-274X artwork and G-code drawings on a home-built CNC plotter.")
    parser.add_argument("--version", action="version", version=f"galileo-cnc {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    info = commands.add_parser("info", help="describe a Gerber or G-code file")
    info.add_argument("file", help="Gerber (RS-274X) or G-code file")
    info.add_argument("--json", action="store_true", help="print machine-readable JSON")
    info.add_argument("--margin", type=float, default=1.0, metavar="MM",
                      help="margin kept from the origin by the proposed offset (default 1 mm)")
    info.set_defaults(run=_run_info)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return args.run(args)
    except GalileoError as error:
        print(f"galileo-cnc: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("galileo-cnc: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stdout = open(os.devnull, "w")
        return 0
