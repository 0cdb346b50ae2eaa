"""`galileo-cnc plot`: the console's getg without questions, for shells and scripts,
on any machine (backends/: our firmware, sim://, simavr://, a GRBL board).

Reads the file, applies the offset (`auto`: the proposed one, `none`, or X,Y in
mm), plans, runs the job on the Machine with a one-line progress display (a
`PlotOperator`), announces pen changes (waits for Enter unless --yes), and can write
the step trace and a preview. `--trace` writes the steps the machine reports where it
can (sim://: its reference's own stepper; simavr://: the step pins the harness
recorded, GRBL's too) and says so; from a real board, which cannot report its steps,
it writes the reference's trace of the job and says that. `--home` (our firmware)
homes the machine before the job, so that a reset mid-job can be resumed. `--resume`
continues the machine's journalled job: after a reset it homes again and redraws
from the first command that may not have finished (stream/resume.py); on GRBL it
homes or has the user re-zero (grbl/job.py). `--check` (GRBL) runs the job through
GRBL's check mode ($C) and lists every line GRBL rejects.
Exit codes: 0 done, 1 bad input or refused job, 3 port lost or a homed job's machine
reset (resume with --resume), 130 stopped with Ctrl-C (the machine ramped down).
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterator, TextIO

from galileo_cnc.backends import JobResult, open_machine
from galileo_cnc.command_text import fixed_text
from galileo_cnc.config.profile import Profile
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.machine.timing import duration_text, job_timing
from galileo_cnc.plan.feeds import machine_refusal
from galileo_cnc.plan.ink.background import Deferred
from galileo_cnc.plan.offsets import DEFAULT_MARGIN_NM
from galileo_cnc.plan.open_traces import ink_warnings, open_traces
from galileo_cnc.plan.widths import mm_text
from galileo_cnc.plan.board_plan import plan_source
from galileo_cnc.plan.drill_marks import warnings_to_show
from galileo_cnc.plan.pipeline import PLANNING_NOTICE_OPS, PlanOptions
from galileo_cnc.preview.formats import is_svg
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.stream.homing import check_homeable
from galileo_cnc.stream.streamer import (MachineReset, PenChange, Progress,
                                         head_position_text)
from galileo_cnc.transport.link import PortGone
from galileo_cnc.transport.port import SIM_URL, with_step_trace

EXIT_OK, EXIT_FAILED, EXIT_PORT_LOST, EXIT_INTERRUPTED = 0, 1, 3, 130


class TextProgress:
    """One self-rewriting line on a terminal; a line per 10 % elsewhere."""

    def __init__(self, out: TextIO):
        self.out = out
        self.tty = out.isatty()
        self._shown = -1
        self._open_line = False        # a stage() line waits to be cleared

    def __call__(self, p: Progress) -> None:
        percent = 100 * p.confirmed // max(p.total, 1)
        eta = duration_text(p.eta_s) if p.eta_s is not None else "?"
        # ink fill has no line of its own (it comes from the union of many objects)
        where = f"line {p.source_line} of the file" if p.source_line else "filling copper"
        text = f"{percent:3d}% {p.confirmed}/{p.total} lines  {where}  ETA {eta}"
        if self.tty:
            text += head_position_text(p.position_nm)    # the head, where the machine says
            bar = "#" * (percent // 4)
            self.out.write(f"\r[{bar:<25}] {text}\x1b[K")
            self.out.flush()
        elif percent // 10 != self._shown:
            self._shown = percent // 10
            self.out.write(text + "\n")

    def stage(self, text: str) -> None:
        """What the planning of a large file is at (plan_file's on_stage): seconds a
        stage on the largest layers. One rewritten line on a terminal, a line each
        elsewhere."""
        if self.tty:
            self.out.write(f"\r{text} ...\x1b[K")
            self._open_line = True
        else:
            self.out.write(f"{text} ...\n")
        self.out.flush()

    def end_line(self) -> None:
        """Clear a terminal line that stage() left open (before other output)."""
        if self._open_line:
            self.out.write("\r\x1b[K")
            self.out.flush()
            self._open_line = False

    @contextmanager
    def staging(self) -> Iterator[Callable[[str], None]]:
        """`stage` for a planning, and the line cleared when the planning ends or
        fails (so an error starts on a line of its own)."""
        try:
            yield self.stage
        finally:
            self.end_line()

    def planning(self, done: int, total: int) -> None:
        """Planning a large file takes seconds: say so, and how far it got on a terminal."""
        if done == 0 and total >= PLANNING_NOTICE_OPS:
            self.end_line()
            self.out.write(f"planning {total} operations ...")
            self.out.write("\n" if not self.tty else "")
        elif self.tty and total >= PLANNING_NOTICE_OPS:
            end = "\n" if done == total else ""
            self.out.write(f"\rplanning {total} operations ... {100 * done // total}%{end}")
        self.out.flush()

    def message(self, text: str) -> None:
        self.out.write(("\r\x1b[K" if self.tty else "") + text + "\n")
        self.out.flush()


@contextmanager
def stages_on_terminal(stream: TextIO) -> Iterator[Callable[[str], None] | None]:
    """plan_file's on_stage for commands whose stdout is their result (info, preview,
    convert): the stages on `stream` (stderr) if it is a terminal, else none; the
    line is cleared when planning ends, or fails."""
    progress = TextProgress(stream)
    if not progress.tty:
        yield None
        return
    with progress.staging() as on_stage:
        yield on_stage


@dataclass
class PlotOptions:
    file: str
    profile: Profile
    offset: str = "auto"
    margin_nm: int = DEFAULT_MARGIN_NM
    yes: bool = False
    preview: str | None = None
    trace: str | None = None
    resume: bool = False
    group: bool = True
    mode: str = "auto"
    layers: tuple[str, ...] = ()
    units: str | None = None
    optimize: bool = False          # reorder pen-drawing G-code too (plan/order/gcode_order.py)
    transform: Any = None           # --scale, --rotate, --fit (plan/transform.py)
    home: bool = False              # home before the job: a reset mid-job is resumable
    check: bool = False             # GRBL's check mode ($C) instead of plotting
    allow_open: bool = False        # plot although the ink leaves trace pieces out
    #: the board's port, already open and probed (discovery.open_board), and what
    #: answered there: the machine greets over it instead of opening the port again
    handle: Any = None
    kind: str | None = None
    #: a board's side and choices (plan/board_plan.py); None: the defaults on a board
    board: Any = None
    #: plot --mill: a cli.mill.MillRequest; cli.mill.run_mill_plot runs it, never run_plot
    mill: Any = None

    @property
    def plan(self) -> PlanOptions:
        return PlanOptions(mode=self.mode, file_order=not self.group, layers=self.layers,
                           units=self.units, optimize=self.optimize,
                           **({"transform": self.transform} if self.transform else {}))


class PlotOperator:
    """The shell as a job's Operator: the progress line, pen changes announced (and
    Enter waited for unless --yes), what the job says printed on a line of its own."""

    def __init__(self, progress: TextProgress, yes: bool):
        self.line = progress
        self.yes = yes

    def say(self, text: str) -> None:
        self.line.message(text)

    def progress(self, p: Progress) -> None:
        self.line(p)

    def pen_change(self, change: PenChange) -> None:
        self.line.message(f"\a{change.prompt}" + ("" if self.yes else ", then press Enter"))
        if not self.yes:
            sys.stdin.readline()

    def confirm(self, question: str) -> bool:
        """The user makes it so and presses Enter (--yes: taken as done)."""
        self.line.message(f"\a{question}" + (" (--yes takes the machine as standing there)"
                                              if self.yes else ", then press Enter"))
        if not self.yes:
            sys.stdin.readline()
        return True


#: jobs of this many commands have their timing worked out in a second process
BACKGROUND_COMMANDS = 20_000


def run_plot(options: PlotOptions, out: TextIO | None = None, err: TextIO | None = None) -> int:
    # the streams of the call, not of the import (a test may have replaced them since)
    out = out if out is not None else sys.stdout
    profile = options.profile
    progress = TextProgress(out)
    operator = PlotOperator(progress, options.yes)
    if options.check and options.trace:
        raise GalileoError("plot --check --trace: check mode moves nothing, so there are no "
                           "steps to trace")
    if options.home:
        check_homeable(profile.config)      # before anything is planned, opened or moved
    planned = None
    if not options.resume:              # a resumed job is planned from its journal
        with progress.staging() as on_stage:
            planned = plan_source(options.file, profile.config, options.offset,
                                  board=options.board, margin_nm=options.margin_nm,
                                  on_progress=progress.planning, on_stage=on_stage,
                                  options=options.plan)
        if planned.ink is not None and not options.allow_open:
            refuse_open_traces(planned.ink)  # before the machine is opened
    # our firmware's timing (the estimate and the progress line's time left: 3.5 s for
    # hellboard's 121k commands) in a second process while the machine opens
    timing = Deferred(job_timing, planned.job.commands, profile.config,
                      fork=len(planned.job) >= BACKGROUND_COMMANDS) \
        if planned is not None else None
    # simavr:// records the step pins for --trace
    # no port: cli/main's open_board probed every port already and found no board
    port = with_step_trace(profile.port) if options.trace and profile.port else \
        profile.port or SIM_URL
    machine = open_machine(port, profile, on_message=progress.message,
                           handle=options.handle, kind=options.kind,
                           shown_as=profile.port or SIM_URL)
    recorder = machine.step_recorder()
    done = None
    try:
        found = " (no board found)" if profile.port is None and machine.simulated else ""
        out.write(machine.describe() + found + "\n")
        machine.check_profile()             # before any plan is shown: no job for it
        if planned is not None and (refused := machine_refusal(
                planned.program, profile.config, machine.feed_refusal)) is not None:
            raise GalileoError(refused)     # GRBL's $110/$111: plan_file knows only ours
        if options.check and not machine.checks_jobs:
            raise GalileoError(f"plot --check runs GRBL's check mode ($C): it needs a GRBL "
                               f"board, and {machine.port_name} runs galileo-cnc firmware "
                               f"(info and preview check a file without a machine)")
        if planned is not None:
            if planned.ink is not None:
                _say_ink(planned.ink, out)
            _say_place(planned, out)
            if options.home:
                _home_first(machine, progress, profile)
            job = machine.prepare(planned, profile.config,
                                  timing=timing.result if timing is not None
                                  and machine.config == profile.config else None,
                                  homed=options.home)
            if options.check:
                report = machine.check_job(job)
                out.write(f"GRBL check mode ($C): {report}\n")
                return EXIT_OK if report.ok else EXIT_FAILED
            out.write(job.estimate_line() + "\n")
            result = _run(machine, options, operator, lambda: machine.run_job(job, operator))
        else:
            with progress.staging() as on_stage:
                resumption = machine.plan_resume(machine.pending(options.file),
                                                 on_stage=on_stage)
            progress.message(resumption.why)
            if resumption.job is None:
                progress.message(resumption.nothing_left)
                return EXIT_OK
            job = resumption.job
            _say_place(job.planned, out)
            result = _run(machine, options, operator,
                          lambda: machine.resume(resumption, operator))
        if not isinstance(result, JobResult):
            return result                   # an exit code: the job did not finish
        where = f"; {result.where}" if result.where else ""
        progress.message(f"\aprocess has finished in {duration_text(result.elapsed_s)}{where}")
        recorder.job_done()
        done = job
    finally:
        machine.close()                     # simavr: the board stops, its pin record is whole
        if timing is not None:
            timing.cancel()
    _write_outputs(options, machine, recorder, done, out=out)
    return EXIT_OK


def _run(machine, options: PlotOptions, operator: PlotOperator, run) -> JobResult | int:
    """The job's result, or the exit code of how it did not finish (said why)."""
    say = operator.say
    again = f"the job can continue: galileo-cnc plot {options.file} --resume"
    try:
        result = run()
    except PortGone as gone:
        say(f"galileo-cnc: {gone}")
        runs_on = getattr(gone, "runs_on", "")
        say(f"{runs_on}; once the machine stands still {again}" if runs_on else again)
        return EXIT_PORT_LOST
    except MachineReset as reset:
        say(f"galileo-cnc: {reset}")
        if not reset.resumable:             # not homed: its position is lost
            return EXIT_FAILED
        say(again)
        return EXIT_PORT_LOST
    except GrblStreamError as stopped:
        say(f"galileo-cnc: {stopped}")
        if stopped.alarm:
            say("GRBL is locked in alarm: its position may be lost; home or re-zero, then "
                "unlock it with $X")
        return EXIT_FAILED
    if result is None:                      # the user could not set the position
        return EXIT_FAILED
    if not result.completed:
        how = result.held or "the machine ramped down"
        say(f"stopped: {result.reason}; {how} ({result.confirmed} of {result.total} "
            f"{result.unit} confirmed)")
        say(again)                          # Ctrl-C: how to go on (issue 31, item 13)
        return EXIT_INTERRUPTED
    return result


def _home_first(machine, progress: TextProgress, profile: Profile) -> None:
    progress.message("homing: the job's frame is the homed one (a reset can be resumed)")
    status = machine.home_for_job()
    progress.message(f"homed: X {status.x_steps / profile.config.steps_per_mm:.3f} "
                     f"Y {status.y_steps / profile.config.steps_per_mm:.3f} mm")


def _say_place(planned, out: TextIO) -> None:
    """A board's side and its axis, where the drawing sits in the file, and the offset
    that moves it."""
    program, box = planned.artwork.program, planned.artwork.drawn_box_nm
    if planned.ink is not None:         # the fills reach past the centre lines
        box = planned.pen_box_nm
    offset = planned.offset_nm
    if getattr(planned, "side_line", ""):
        out.write(f"{planned.side_line}\n")
    for warning in (*warnings_to_show(getattr(planned, "drill_mark_warnings", ())),
                    *getattr(planned, "line_warnings", ())):
        out.write(f"{warning}\n")
    if box is not None:
        done = planned.artwork.transform.describe()
        out.write(f"{program.source}: {done + '; ' if done else ''}"
                  f"minimum X {_mm(box[0])} mm, Y {_mm(box[1])} mm; "
                  f"offset {_mm(offset[0])}, {_mm(offset[1])} mm\n")
    for warning in getattr(planned, "feed_warnings", ()):     # a resumed job said them
        out.write(f"{warning}\n")


def _mm(nm: int) -> str:
    return fixed_text(nm / NM_PER_MM, 3)


def _say_ink(ink, out: TextIO) -> None:
    """The ink in one line, then what the user should know (narrow features, bridges)."""
    pens = ", ".join(mm_text(w) for w in ink.pens_nm)
    share = 100 * ink.inked_nm2 / ink.copper_nm2 if ink.copper_nm2 else 100.0
    out.write(f"ink: pens {pens} mm, {share:.1f} % of the copper inked, "
              f"{sum(not feature.neck for feature in ink.narrow)} narrow features as "
              f"centre lines" + (f", {len(ink.necks)} necks" if ink.necks else "") + "\n")
    for warning in ink_warnings(ink):
        out.write(f"{warning}\n")


def refuse_open_traces(ink) -> None:
    """plot does not draw a board with open nets unless told to (--allow-open)."""
    summary = open_traces(ink)
    if summary is not None:
        raise GalileoError(f"{summary.text()}. plot --allow-open plots it so")


def _write_outputs(options: PlotOptions, machine, recorder, job, *, out: TextIO) -> None:
    """The step trace and the preview; the preview draws the plan (the job's path
    from its commands, preview/job_path.py: nothing stepped), `copper` (ink mode)
    colouring what the ink left bare and drew outside."""
    if job is None or not (options.trace or options.preview):
        return
    planned, config = job.planned, job.config
    if options.trace:
        reported = recorder.trace()
        if reported is not None:
            reported.save(options.trace)
            out.write(f"step trace: {options.trace} ({len(reported)} steps, as "
                      f"{recorder.source} reported them)\n")
        else:
            from galileo_cnc.machine import simulate
            trace = simulate(planned.job.commands, config)
            trace.save(options.trace)
            out.write(f"step trace: {options.trace} ({len(trace)} steps): the reference "
                      f"machine's, since {machine.port_name} cannot report its steps\n")
    if options.preview:
        from galileo_cnc.preview.write import write_preview
        info = write_preview(planned, config, options.preview)
        # an SVG is drawn from the commands alone: the machine's note is about steps
        note = "" if is_svg(options.preview) else machine.preview_note
        out.write(f"preview: {options.preview}: {info.summary()}{note}\n")
