"""The `galileo-cnc` command line: one sub-command per user task."""

from __future__ import annotations

import argparse
import sys

from . import __version__
from .errors import GalileoError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="galileo-cnc", description=__doc__)
    parser.add_argument("--version", action="version", version=f"galileo-cnc {__version__}")
    parser.add_subparsers(dest="command", metavar="COMMAND")
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
