"""The `galileo-cnc` command line: one sub-command per user task."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import sys


from galileo_cnc import __version__
from galileo_cnc.cli.mill import add_mill_options, run_mill_convert
from galileo_cnc.cli.serve import add_serve_command
from galileo_cnc.config.hardware import DEFAULT_BAUD
from galileo_cnc.errors import GalileoError
from galileo_cnc.preview.formats import preview_kind
from galileo_cnc.program.ops import NM_PER_MM


#: The largest --margin: a margin is a few mm; a metre is already a typing error.
MAX_MARGIN_MM = 1000.0


def margin_mm(text: str) -> float:
    """--margin: a finite length in mm, 0 to MAX_MARGIN_MM (argparse names the option)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 <= value <= MAX_MARGIN_MM:        # also false for NaN
        raise argparse.ArgumentTypeError(f"expected a length in mm from 0 to "
                                         f"{MAX_MARGIN_MM:g}, got {text!r}")
    return value


def check_output(path: str | None, option: str) -> None:
    """Refuse, before any work, an output file that could not be written afterwards."""
    if path is None:
        return
    target = os.path.abspath(path)
    folder = os.path.dirname(target)
    if os.path.isdir(target):
        raise GalileoError(f"{option} {path}: is a folder, expected a file name")
    if not os.path.isdir(folder):
        raise GalileoError(f"{option} {path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK) or (os.path.exists(target) and not os.access(target, os.W_OK)):
        raise GalileoError(f"{option} {path}: cannot write there (permission denied)")


def _run_info(args: argparse.Namespace) -> int:
    from galileo_cnc.cli.info import drill_report, format_summary, summarize
    from galileo_cnc.plan.pipeline import load_artwork
    from galileo_cnc.readers.board import is_board

    if is_board(args.file):
        return _run_board_info(args)
    report = drill_report(args.file, args.json, args.verbose)   # an Excellon drill file
    if report is not None:
        print(report)
        return 0
    config = _profile(args).config
    options = _plan_options(args)
    artwork = load_artwork(args.file, margin_nm=round(args.margin * NM_PER_MM),
                           layers=_layers(args), units=args.units,
                           transform=options.transform, config=config)
    summary = summarize(artwork)
    summary["misfit"] = artwork.misfit(config)          # None: the job fits
    summary["transform"] = artwork.transform.describe()
    summary["feeds"] = _feed_notes(artwork.program, config)
    summary["inked_by_default"] = options.mode_for(artwork.program) == "ink"
    if options.optimize and artwork.program.format == "gcode":
        _check_reorder(artwork.program)
    if args.plan or args.pens:          # pens are a question about the plan
        from galileo_cnc.cli.info import plan_summary
        from galileo_cnc.cli.plot import stages_on_terminal
        with stages_on_terminal(sys.stderr) as on_stage:   # stdout: the summary (maybe JSON)
            key, figures = plan_summary(artwork, config, options, on_stage, args.verbose)
        summary[key] = figures
        if key == "ink":                # the offset getg proposes: from where the fills go
            summary["proposed_offset_mm"] = figures["proposed_offset_mm"]
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary, args.verbose))
        if summary["misfit"]:
            print(f"            {artwork.way_out()}")
        if summary["transform"]:
            print(f"transform   {summary['transform']}")
        for note in summary["feeds"]:
            print(note)
    return 0


def _run_board_info(args: argparse.Namespace) -> int:
    """info BOARD: every file with its role and why, the board's size, holes per diameter."""
    from galileo_cnc.readers import read_drill
    from galileo_cnc.readers.board import describe_board
    text, summary = describe_board(args.file, tuple(args.layer or ()), read_drill=read_drill)
    print(json.dumps(summary, indent=2) if args.json else text)
    return 0


def _feed_notes(program, config) -> list[str]:
    """info: the feed warnings plot would give, and its refusal as a line (plan/feeds.py)."""
    from galileo_cnc.plan.feeds import FeedError, check_feeds
    try:
        return check_feeds(program, config)
    except FeedError as refused:
        return [f"refused: {refused}"]


def _say_feed_warnings(planned) -> None:
    """preview and convert: their result goes to stdout, the feed warnings (and a
    board's outline and silk left out near copper) to stderr."""
    for warning in (*planned.feed_warnings, *planned.line_warnings):
        print(warning, file=sys.stderr)


def _check_reorder(program) -> None:
    """info --optimize: the refusal plot and convert would give, without planning."""
    from galileo_cnc.plan.order.gcode_order import refusal
    from galileo_cnc.plan.planner import PlanError

    problem = refusal(program)
    if problem is not None:
        raise PlanError(f"--optimize: cannot reorder this G-code: {problem[1]}", problem[0])


def _profile(args: argparse.Namespace):
    from galileo_cnc.config.profile import load_profile
    from galileo_cnc.config.machine import pen_widths_from_text
    profile = load_profile(args.profile, port=args.port, baud=args.baud)
    if getattr(args, "pens", None):
        # in the config, so the journal keeps them and a resumed job inks the same
        profile = dataclasses.replace(profile, config=profile.config.replace(
            pen_widths_mm=pen_widths_from_text(args.pens)))
    return profile


def _plan_options(args: argparse.Namespace):
    from galileo_cnc.plan.pipeline import PlanOptions
    return PlanOptions(mode=args.mode, file_order=getattr(args, "file_order", False),
                       layers=_layers(args), units=args.units, optimize=args.optimize,
                       transform=_transform(args))


def _add_layer_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--layer", action="append", metavar="FILE=ROLE",
                        help="a board: give FILE this role (top-copper, bottom-copper, "
                        "outline, drill-plated, ...; see info BOARD); repeatable")


def _transform(args: argparse.Namespace):
    from galileo_cnc.plan.transform import Transform
    return Transform.asked(args.scale, args.rotate, args.fit)


def _layers(args: argparse.Namespace) -> tuple[str, ...]:
    return tuple(name.strip() for name in (args.layers or "").split(",") if name.strip())


def _run_plot(args: argparse.Namespace) -> int:
    from galileo_cnc.cli.mill import run_mill_plot
    from galileo_cnc.grbl.mill_plan import MillRequest
    from galileo_cnc.cli.plot import PlotOptions, run_plot
    from galileo_cnc.stream.homing import check_homeable
    from galileo_cnc.transport.discovery import GRBL, open_board
    from galileo_cnc.transport.port import SIM_URL

    _plan_options(args)                     # contradictory options refused before connecting
    if args.offset != "auto":               # only "auto" needs the artwork: a typo is
        from galileo_cnc.plan.pipeline import resolve_offset    # refused before connecting
        resolve_offset(None, args.offset)
    check_output(args.preview, "--preview")
    if args.preview is not None:
        preview_kind(args.preview, "--preview")
    check_output(args.trace, "--trace")
    profile = _profile(args)
    if args.resume and args.check:
        raise GalileoError("plot --resume --check: check the job without --resume")
    if args.home:                           # refused before anything is opened or moves
        if args.resume:
            raise GalileoError("plot --home --resume: a job resumed after a reset is homed "
                               "anyway, any other continues where the machine stands")
        check_homeable(profile.config)
    # the one probe; the probed port stays open for the machine (an Uno resets each
    # time it is opened)
    device, kind, handle = open_board(profile.port, profile.baud)
    if profile.port is None and device == SIM_URL:
        # the simulated machine runs in real time: a job there takes as long as on paper
        raise GalileoError("plot: no board found (no serial port answered as galileo-cnc "
                           "firmware or GRBL): connect it, or name its port with --port "
                           "(galileo-cnc ports --probe lists them); --port sim:// plots on "
                           "the built-in simulated machine (sim://?speed=0 at once)")
    try:
        if kind == GRBL and args.home:
            raise GalileoError("plot --home: on a GRBL board, home with `home` ($H) in the "
                               "console; GRBL keeps the work offset (G54) from its switches")
        if profile.port is None and device != SIM_URL:
            profile = dataclasses.replace(profile, port=device)
        options = PlotOptions(args.file, profile, offset=args.offset,
                              margin_nm=round(args.margin * NM_PER_MM), yes=args.yes,
                              preview=args.preview, trace=args.trace, resume=args.resume,
                              group=not args.file_order, mode=args.mode,
                              layers=_layers(args), units=args.units, optimize=args.optimize,
                              transform=_transform(args), home=args.home, check=args.check,
                              handle=handle, kind=kind, allow_open=args.allow_open,
                              board=_board_choice(args), mill=MillRequest.from_args(args))
        return run_plot(options) if options.mill is None else run_mill_plot(options)
    finally:
        if handle is not None:
            handle.close()                  # the machine closed it already, unless refused


def _run_preview(args: argparse.Namespace) -> int:
    from galileo_cnc.preview.write import write_preview

    check_output(args.output, "--output")
    preview_kind(args.output, "--output")
    config = _profile(args).config
    planned = _plan(args, config)
    _say_feed_warnings(planned)
    info = write_preview(planned, config, args.output)
    print(f"{args.output}: {info.summary()}")
    _say_open_traces(planned)
    return 0


def _say_open_traces(planned) -> None:
    """preview and convert: the trace pieces the ink leaves out, as one summary."""
    from galileo_cnc.plan.open_traces import open_traces
    summary = open_traces(planned.ink)
    if summary is not None:
        print(summary.text())


def _plan(args: argparse.Namespace, config):
    """plan_file for preview and convert: their result goes to stdout, so the stages
    of planning go to stderr, and only on a terminal."""
    from galileo_cnc.cli.plot import stages_on_terminal
    from galileo_cnc.plan.board_plan import plan_source

    with stages_on_terminal(sys.stderr) as on_stage:
        return plan_source(args.file, config, args.offset, board=_board_choice(args),
                           margin_nm=round(args.margin * NM_PER_MM),
                           options=_plan_options(args), on_stage=on_stage)


def _run_convert(args: argparse.Namespace) -> int:
    from galileo_cnc.plan.gcode_writer import converted_gcode, pen_moves
    from galileo_cnc.plan.measure import job_lengths

    check_output(args.output, "--output")
    if args.mill:
        return run_mill_convert(args, _profile(args), _board_choice(args))
    config = _profile(args).config
    pen = pen_moves(config, args.pen, args.target)      # refused before any planning
    planned = _plan(args, config)
    _say_feed_warnings(planned)
    lines = 0
    try:
        with open(args.output, "w", encoding="ascii", newline="\n") as out:
            for line in converted_gcode(planned, config, pen):
                out.write(line + "\n")
                lines += 1
    except OSError as problem:
        raise GalileoError(f"--output {args.output}: cannot write: {problem.strerror}") from None
    lengths = job_lengths(planned.job)
    metres = config.steps_per_mm * 1000
    print(f"{args.output}: {lines} lines, {lengths.drawn_steps / metres:.2f} m drawn, "
          f"{lengths.travel_steps / metres:.2f} m pen-up travel, {lengths.lifts} pen lift{'' if lengths.lifts == 1 else 's'} "
          f"({planned.mode} mode{', paths ordered' if planned.job.ordered else ''})")
    _say_open_traces(planned)
    return 0


def _run_ports(args: argparse.Namespace) -> int:
    from galileo_cnc.transport.discovery import list_ports

    found = list_ports()
    for port in found:
        mark = "known board" if port.known_board else ""
        line = f"{port.device:<20} {port.description} {mark}".rstrip()
        if args.probe:
            line += f"  [{_probe(port.device, args.baud)}]"
        print(line)
    print(f"{'sim://':<20} built-in simulated machine (always there)")
    print(f"{'simavr://':<20} the firmware running in simavr (build both with make -C "
          f"firmware and make -C firmware/harness in a checkout; installed elsewhere, set "
          f"GALILEO_FIRMWARE and GALILEO_SIMAVR)")
    return 0


def _probe(device: str, baud: int) -> str:
    """What answers on `device`: our firmware, GRBL with its version, or nothing."""
    from galileo_cnc.transport.discovery import GALILEO, GRBL, identify_board

    kind = identify_board(device, baud)
    if kind == GALILEO:
        return "galileo-cnc firmware"
    if kind != GRBL:
        return "no banner"
    # identify_board tells GRBL from the rest; its banner on connect names the version
    from galileo_cnc.grbl.link import GrblLink
    from galileo_cnc.grbl.reports import GrblError
    from galileo_cnc.transport.port import open_port
    try:
        with open_port(device, baud, timeout=0.2) as port:
            link = GrblLink(port)
            return f"GRBL {link.wait_banner()}"
    except (GrblError, OSError):
        return "GRBL"


def _run_console(args: argparse.Namespace) -> int:
    """The console is another front end: the program's entry (galileo_cnc/__main__.py)
    hands its start in as `start_console`; cli/ never imports console/."""
    if args.start_console is None:
        raise GalileoError("the console starts from galileo-cnc itself (python -m galileo_cnc)")
    return args.start_console(_profile(args))


def _add_connection_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", help="COMx, /dev/tty..., a pty path or a pyserial URL "
                        "(sim:// is the built-in simulated machine); default: find a board, "
                        "else sim://")
    parser.add_argument("--baud", type=int,
                        help=f"baud rate (default {DEFAULT_BAUD}; 9600 accepted)")
    parser.add_argument("--profile", metavar="TOML", help="machine profile (default: "
                        "~/.config/galileo-cnc/profile.toml if present, else the seed's machine)")


def _add_job_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", help="Gerber (RS-274X), G-code or DXF file")
    parser.add_argument("--offset", default="auto", metavar="auto|none|X,Y",
                        help="subtracted from every coordinate: auto = the minimum minus the "
                        "margin (default), none, or X,Y in mm")
    parser.add_argument("--margin", type=margin_mm, default=1.0, metavar="MM",
                        help="margin kept from the origin by --offset auto (default 1 mm)")
    parser.add_argument("--file-order", action="store_true",
                        help="keep the file's order (default: Gerber and DXF paths chained "
                        "and ordered per pen to cut pen-up travel)")
    _add_optimize_option(parser)
    _add_ink_options(parser)
    _add_drawing_options(parser)
    _add_board_options(parser)


def _add_board_options(parser: argparse.ArgumentParser) -> None:
    """A board's side (plan/board_plan.py; docs/boards.md)."""
    parser.add_argument("--side", choices=("top", "bottom"),
                        help="a board: which side (default top); the bottom is mirrored so "
                        "turning the blank over puts it on the top")
    parser.add_argument("--drill-marks", choices=("none", "small", "actual"),
                        help="a board: leave each hole's centre bare in the ink, as a small "
                        "dot (the default) or the whole hole, so etching marks where to drill")
    parser.add_argument("--drill-mark-size", type=margin_mm, metavar="MM",
                        help="a board: the small drill marks' width (default 0.3 mm, never "
                        "wider than the hole)")
    parser.add_argument("--mirror-axis", metavar="x=MM|y=MM",
                        help="a board: the line the blank turns over about, in board mm "
                        "(default: the vertical centre line of the outline, else of the holes)")
    parser.add_argument("--registration", action="store_true",
                        help="a board: crosses drawn on both sides to check the turn-over")
    parser.add_argument("--outline", action="store_true",
                        help="a board: draw the outline as a centre line after the copper, "
                        "with a pen of its own (the finest pen), kept off the copper")
    parser.add_argument("--silk", action="store_true",
                        help="a board: draw the side's silkscreen as centre lines after the "
                        "copper and the outline, with a pen of its own (the finest pen), "
                        "kept off the copper")
    _add_layer_option(parser)


def _board_choice(args: argparse.Namespace):
    """The board options given (None: none given, so a file alone is fine)."""
    from galileo_cnc.plan.board_plan import BoardChoice
    from galileo_cnc.plan.sides import parse_axis
    try:
        axis = parse_axis(args.mirror_axis) if args.mirror_axis else None
    except ValueError as problem:
        raise GalileoError(str(problem)) from None
    given = {"side": args.side, "drill_marks": args.drill_marks,
             "drill_mark_nm": None if args.drill_mark_size is None
             else round(args.drill_mark_size * NM_PER_MM),
             "mirror_axis": axis,
             "registration": args.registration or None,
             "outline": args.outline or None, "silk": args.silk or None,
             "layers": tuple(args.layer) if args.layer else None}
    given = {key: value for key, value in given.items() if value is not None}
    return BoardChoice(**given) if given else None


def _add_optimize_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--optimize", action="store_true",
                        help="G-code: chain and order its paths too (refused, naming the "
                        "line, if the file does more than draw with a pen: spindle speeds, "
                        "depths, dwells, tool changes...); Gerber and DXF are ordered anyway")


def _add_drawing_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--layers", metavar="A,B", help="DXF: draw only these layers "
                        "(info lists them)")
    parser.add_argument("--units", choices=("mm", "in"), help="DXF: the drawing's units, "
                        "instead of its $INSUNITS (a drawing without them is read as mm)")
    _add_transform_options(parser)


def _add_transform_options(parser: argparse.ArgumentParser) -> None:
    """--scale, --rotate, --fit (plan/transform.py): before the offset, exact in nm."""
    parser.add_argument("--scale", metavar="F", help="scale the drawing by F (0.5, 2, "
                        "80%%), exactly, about the file's origin")
    parser.add_argument("--rotate", metavar="DEG", help="turn the drawing 90, 180 or 270 "
                        "degrees clockwise (as vpype's rotate)")
    parser.add_argument("--fit", action="store_true", help="scale the drawing to the "
                        "largest size that fits the travel with the margin (keeps the aspect)")


def _add_ink_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mode", choices=("ink", "centre"), default="auto",
                        help="ink: fill Gerber copper with your pens (the default for Gerber); "
                        "centre: each object's centre line, one pen per aperture")
    parser.add_argument("--pens", metavar="MM[,MM]",
                        help="the pens you own, e.g. 0.3,0.8 (default: the profile's "
                        "[pens] widths_mm, else one 0.4 mm pen)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="galileo-cnc",
        description="Plot Gerber RS-274X artwork, G-code and DXF drawings on a home-built "
                    "CNC plotter.")
    parser.add_argument("--version", action="version", version=f"galileo-cnc {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    info = commands.add_parser("info", help="describe a Gerber, G-code, DXF or drill file, "
                               "or a board (a folder, .zip or .gbrjob: its files' roles)")
    info.add_argument("file", help="Gerber (RS-274X), G-code, DXF or Excellon file, or a board")
    _add_layer_option(info)
    info.add_argument("--json", action="store_true", help="print machine-readable JSON")
    info.add_argument("--margin", type=margin_mm, default=1.0, metavar="MM",
                      help="margin kept from the origin by the proposed offset (default 1 mm)")
    info.add_argument("--profile", metavar="TOML", help="machine profile (its pens)")
    info.add_argument("--plan", action="store_true",
                      help="plan the job too (seconds on a large board): pen-down and "
                      "travel lengths; in ink mode the ink and the trace pieces left out "
                      "(--pens implies it)")
    info.add_argument("--verbose", action="store_true",
                      help="every warning (else the first few, and left-out trace pieces "
                      "as one summary)")
    _add_optimize_option(info)
    _add_ink_options(info)
    _add_drawing_options(info)
    info.set_defaults(run=_run_info, port=None, baud=None)

    plot = commands.add_parser("plot", help="plot a file without questions (batch getg)")
    _add_job_options(plot)
    _add_connection_options(plot)
    plot.add_argument("--yes", action="store_true",
                      help="announce pen changes instead of waiting for Enter")
    plot.add_argument("--preview", metavar="PNG|SVG",
                      help="write a preview of what was plotted (.svg: vector)")
    plot.add_argument("--trace", metavar="NPZ", help="write the step trace (tick, axis, dir)")
    plot.add_argument("--home", action="store_true",
                      help="home the machine (X and Y end stops, Z too if it has one) before "
                      "the job: its frame is then the homed one, so the job can be resumed "
                      "even after the board is reset")
    plot.add_argument("--resume", action="store_true",
                      help="continue the interrupted job of FILE: after a lost port where the "
                      "machine stands, after the last line it accepted; after a stop from "
                      "the command it stopped in; after a reset of a job planned with "
                      "--home, it homes the machine (without a Z end stop, put the pen at "
                      "its Z origin first) and redraws from the first command that may "
                      "not have finished: lines the machine confirmed may still have been "
                      "queued (up to 9 commands), so a few are drawn twice. A reset job "
                      "without --home cannot be resumed")
    plot.add_argument("--allow-open", action="store_true",
                      help="plot a board although the ink leaves trace pieces out (open "
                      "traces: a centre line would join another copper island); refused "
                      "otherwise, with a summary and the widest pen that draws them all")
    add_mill_options(plot)
    plot.add_argument("--check", action="store_true",
                      help="GRBL only: run the job through GRBL's check mode ($C), moving "
                      "nothing, and list every line GRBL rejects (exit 1 if any)")
    plot.set_defaults(run=_run_plot)

    preview = commands.add_parser("preview", help="draw what the machine will plot: a PNG "
                                  "picture, or an SVG a browser zooms (with a legend, a "
                                  "scale and the origin)")
    _add_job_options(preview)
    preview.add_argument("-o", "--output", required=True, metavar="PNG|SVG")
    preview.add_argument("--profile", metavar="TOML", help="machine profile")
    preview.set_defaults(run=_run_preview, port=None, baud=None)

    convert = commands.add_parser("convert", help="write the plot as G-code in mm (for this "
                                  "machine or a GRBL board)")
    _add_job_options(convert)
    convert.add_argument("-o", "--output", required=True, metavar="NC")
    convert.add_argument("--profile", metavar="TOML", help="machine profile (feed, pens)")
    convert.add_argument("--pen", choices=("z", "servo", "spindle"),
                         help="how the pen moves: z (the profile's pen heights), servo "
                         "(M3 S.. / M5 and a dwell), spindle (M3 / M5); default: the "
                         "profile's [grbl] pen")
    convert.add_argument("--target", choices=("grbl", "galileo"), default="grbl",
                         help="who reads the file: grbl (its senders; G4 P in seconds, "
                         "the default) or galileo (galileo-cnc itself; G4 P in ms)")
    add_mill_options(convert)
    convert.set_defaults(run=_run_convert, port=None, baud=None)

    ports = commands.add_parser("ports", help="list serial ports (and sim://)")
    ports.add_argument("--probe", action="store_true",
                       help="open each port and say what answers: galileo-cnc firmware "
                       "or GRBL (with its version)")
    ports.add_argument("--baud", type=int, default=DEFAULT_BAUD)
    ports.set_defaults(run=_run_ports)

    add_serve_command(commands, _add_connection_options)

    console = commands.add_parser("console", help="the interactive console (the default)")
    _add_connection_options(console)
    console.set_defaults(run=_run_console)
    return parser


#: options whose value may start with a minus ("--offset -1,-1"): argparse takes
#: "-1,-1" for an option, as it looks like no number; joined as "--offset=-1,-1"
_NEGATIVE_VALUE_OPTIONS = ("--offset",)
_NEGATIVE_VALUE = re.compile(r"-[0-9.]")


def _negative_values_joined(argv: list[str]) -> list[str]:
    out: list[str] = []
    for arg in argv:
        if out and out[-1] in _NEGATIVE_VALUE_OPTIONS and _NEGATIVE_VALUE.match(arg):
            out[-1] = f"{out[-1]}={arg}"
        else:
            out.append(arg)
    return out


def main(argv: list[str] | None = None, start_console=None) -> int:
    """`start_console(profile) -> exit code`: how `galileo-cnc console` (and no command)
    starts the interactive front end."""
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0].startswith("--") and argv[0] not in ("--help", "--version"):
        argv = ["console", *argv]          # no command: the console, as the seed started
    args = parser.parse_args(_negative_values_joined(argv))
    args.start_console = start_console
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
