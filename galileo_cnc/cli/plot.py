"""`galileo-cnc plot`: the console's getg without questions, for shells and scripts.

Reads the file, applies the offset (`auto`: the proposed one, `none`, or X,Y in
mm), plans, streams with a one-line progress display, announces pen changes
(waits for Enter unless --yes), and can write the step trace and a preview.
`--trace` writes the steps the machine reports where it can (sim://: its reference's own
stepper; simavr://: the step pins the harness recorded) and says so; from a real board,
which cannot report its steps, it writes the reference's trace of the job and says that.
`--home` homes the machine before the job, so that a reset mid-job can be resumed:
`--resume` then homes again (stream/homing.py) and redraws from the first command
that may not have finished (stream/resume.py).
Exit codes: 0 done, 1 bad input or refused job, 3 port lost or a homed job's machine
reset (resume with --resume), 130 stopped with Ctrl-C (the machine ramped down).
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, TextIO

from galileo_cnc.config.profile import Profile
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import Job
from galileo_cnc.machine.trace import Trace
from galileo_cnc.machine.timing import duration_text, job_timing
from galileo_cnc.plan.ink.background import Deferred
from galileo_cnc.plan.offsets import DEFAULT_MARGIN_NM
from galileo_cnc.plan.widths import mm_text
from galileo_cnc.plan.pipeline import PLANNING_NOTICE_OPS, PlanOptions, plan_file
from galileo_cnc.program.ops import NM_PER_MM, Program
from galileo_cnc.stream.homing import check_homeable, home, home_after_reset, z_has_end_stop
from galileo_cnc.stream.journal import Journal
from galileo_cnc.stream.resume import plan_resume
from galileo_cnc.stream.streamer import (JobStreamer, MachineReset, PenChange, Progress,
                                         StreamResult)
from galileo_cnc.transport.link import MachineLink, PortGone
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
    home: bool = False              # home before the job: a reset mid-job is resumable
    #: the board's port, already open and probed (discovery.open_identified): the
    #: link greets over it instead of opening `profile.port` again
    handle: Any = None


#: jobs of this many commands have their timing worked out in a second process
BACKGROUND_COMMANDS = 20_000


def run_plot(options: PlotOptions, out: TextIO | None = None, err: TextIO | None = None) -> int:
    # the streams of the call, not of the import (a test may have replaced them since)
    out = out if out is not None else sys.stdout
    profile = options.profile
    journal = Journal.default()
    progress = TextProgress(out)
    planned = None
    if options.home:
        check_homeable(profile.config)      # before anything is planned, opened or moved
    if not options.resume:              # a resumed job is planned from its journal
        with progress.staging() as on_stage:
            planned = plan_file(options.file, profile.config, options.offset,
                                margin_nm=options.margin_nm, on_progress=progress.planning,
                                on_stage=on_stage,
                                options=PlanOptions(mode=options.mode,
                                                    file_order=not options.group,
                                                    layers=options.layers, units=options.units,
                                                    optimize=options.optimize))

    # the job's timing (the estimate and the progress line's time left: 3.5 s for
    # hellboard's 121k commands) in a second process while the port opens and a board
    # boots (an Arduino resets when its port opens)
    timing = Deferred(job_timing, planned.job.commands, profile.config,
                      fork=len(planned.job) >= BACKGROUND_COMMANDS) \
        if planned is not None else None
    # no port: cli/main's open_board probed every port already and found no board
    port = with_step_trace(profile.port) if options.trace and profile.port else \
        profile.port or SIM_URL
    if options.handle is not None:
        link = MachineLink.attach(options.handle, port, profile.baud, profile.config,
                                  profile.path, booted=True)
    else:
        link = MachineLink.open(port, profile.baud, profile.config, profile.path)
    link.on_message = progress.message
    steps = ReportedSteps(link)
    outputs = None
    try:
        found = " (no board found)" if profile.port is None and link.simulated else ""
        out.write(link.describe() + found + "\n")
        link.check_config()                 # before any plan is shown: no job for it
        start, lead_in, job_start, homed = 0, (), None, options.home
        if planned is not None:
            job, artwork, offset = planned.job, planned.artwork, planned.offset_nm
            plotted = planned.plotted
            if planned.ink is not None:
                _say_ink(planned.ink, out)
        else:
            entry = journal.pending()
            if entry is None or Path(entry.source) != Path(options.file).resolve():
                raise GalileoError(f"no interrupted job of {options.file} to resume")
            with progress.staging() as on_stage:
                point = plan_resume(link, entry, on_stage=on_stage)
            job, artwork, start, lead_in = point.job, point.artwork, point.start, point.lead_in
            job_start, plotted, homed = point.job_start, point.program, point.homed
            offset = job.offset_nm                  # the interrupted job's, not --offset
            if point.home:
                _home_after_reset(link, entry.confirmed + 1 - start, options.yes, progress)
            out.write(f"resuming at command {start + 1} of {len(job)}\n")
        program, box = artwork.program, artwork.drawn_box_nm     # found while reading
        if box is not None:
            out.write(f"{program.source}: minimum X {box[0] / NM_PER_MM:.3f} mm, "
                      f"Y {box[1] / NM_PER_MM:.3f} mm; offset {offset[0] / NM_PER_MM:.3f}, "
                      f"{offset[1] / NM_PER_MM:.3f} mm\n")
        if options.home and planned is not None:
            progress.message("homing: the job's frame is the homed one (a reset can be "
                             "resumed)")
            status = home(link)
            progress.message(f"homed: X {status.x_steps / profile.config.steps_per_mm:.3f} "
                             f"Y {status.y_steps / profile.config.steps_per_mm:.3f} mm")
        streamer = JobStreamer(link, job, plotted, journal=journal, start=start,
                               lead_in=lead_in, job_start=job_start, homed=homed,
                               timing=timing.result() if timing is not None
                               and link.config == profile.config else None)
        out.write(f"{len(job) - start} commands, about "
                  f"{duration_text(streamer.timing.seconds_between(start, len(job)))} "
                  f"of machine time\n")

        def pen_change(change: PenChange) -> None:
            progress.message(f"\a{change.prompt}"
                             + ("" if options.yes else ", then press Enter"))
            if not options.yes:
                sys.stdin.readline()

        began = time.monotonic()
        try:
            result: StreamResult = streamer.run(on_progress=progress, on_pen_change=pen_change)
        except PortGone as gone:
            progress.message(f"galileo-cnc: {gone}")
            progress.message(f"the job can continue: galileo-cnc plot {options.file} --resume")
            return EXIT_PORT_LOST
        except MachineReset as reset:
            progress.message(f"galileo-cnc: {reset}")
            if not homed:
                return EXIT_FAILED
            progress.message(f"the job can continue: galileo-cnc plot {options.file} --resume")
            return EXIT_PORT_LOST
        if not result.completed:
            progress.message(f"stopped: {result.reason}; the machine ramped down "
                             f"({result.confirmed} of {result.total} commands confirmed)")
            return EXIT_INTERRUPTED
        progress.message(f"\aprocess has finished in {duration_text(time.monotonic() - began)}")
        steps.job_done(link)
        outputs = (job, program, offset, planned.copper if planned is not None else None)
    finally:
        link.close()
        if timing is not None:
            timing.cancel()
    if outputs is not None:             # after closing: simavr's pin record is complete then
        _write_outputs(options, link, steps, *outputs, out=out)
    return EXIT_OK


def _home_after_reset(link: MachineLink, unsure: int, yes: bool,
                      progress: TextProgress) -> None:
    """A reset lost the position: home (Z without an end stop: the user puts the pen at
    its Z origin first), saying how many confirmed commands are drawn again."""
    progress.message(f"the machine was reset during the job: homing finds the job's frame "
                     f"again; the last {unsure} commands it confirmed may not have run, "
                     f"so they are drawn again")
    if not z_has_end_stop(link.config):
        progress.message("\aZ has no end stop, so the reset lost the pen's height: turn the "
                         "pen back to its Z origin (where Z 0 was set; with the default pen "
                         "heights, touching the paper)"
                         + (": --yes takes the pen as standing there" if yes
                            else ", then press Enter"))
        if not yes:
            sys.stdin.readline()
    home_after_reset(link)
    progress.message("homed")


def _say_ink(ink, out: TextIO) -> None:
    """The ink in one line, then what the user should know (narrow features, bridges)."""
    pens = ", ".join(mm_text(w) for w in ink.pens_nm)
    share = 100 * ink.inked_nm2 / ink.copper_nm2 if ink.copper_nm2 else 100.0
    out.write(f"ink: pens {pens} mm, {share:.1f} % of the copper inked, "
              f"{len(ink.narrow)} narrow features as centre lines\n")
    for warning in ink.warnings_to_show():
        out.write(f"{warning}\n")


def _write_outputs(options: PlotOptions, link: MachineLink, steps: ReportedSteps, job: Job,
                   program: Program, offset: tuple[int, int], copper=None, *,
                   out: TextIO) -> None:
    """The step trace and the preview; `copper` (ink mode) colours what the ink
    left bare and drew outside. The preview draws the reference's trace (the plan)."""
    if not (options.trace or options.preview):
        return
    trace = job_trace(link, job)
    if options.trace:
        reported = steps.trace()
        if reported is not None:
            reported.save(options.trace)
            out.write(f"step trace: {options.trace} ({len(reported)} steps, as "
                      f"{steps.source} reported them)\n")
        else:
            trace.save(options.trace)
            out.write(f"step trace: {options.trace} ({len(trace)} steps): the reference "
                      f"machine's, since {link.port_name} cannot report its steps\n")
    if options.preview:
        from galileo_cnc.preview.render import render_preview
        info = render_preview(program, trace, link.config, offset, options.preview,
                              job=job, copper=copper)
        out.write(f"preview: {options.preview}: {info.summary()}\n")


class ReportedSteps:
    """The steps the machine behind a link reports: sim:// its reference machine's own
    stepper (from the step count at the job's start: a named machine may have moved
    before), simavr:// the step and direction pin edges the harness recorded since the
    board's power-on (complete once the port is closed). None from a real board."""

    def __init__(self, link: MachineLink):
        handle = link.handle
        self._machine = getattr(handle, "machine", None)
        board = getattr(handle, "board", None)
        self._board = board if board is not None and board.records_steps else None
        self._first = len(self._machine.trace()) if self._machine is not None else 0
        self._config = link.config
        self._trace: Trace | None = None
        self._final: tuple[int, int, int] | None = None
        self.source = ("the simulated machine" if self._machine is not None else
                       "the firmware's step pins in simavr" if self._board is not None else "")

    def job_done(self, link: MachineLink) -> None:
        """While the port is still open: the sim's steps, or where the board stands."""
        if self._machine is not None:
            whole = self._machine.trace()
            self._trace = Trace(whole.tick[self._first:], whole.axis[self._first:],
                                whole.dir[self._first:], whole.final_position,
                                whole.total_ticks)
        elif self._board is not None:
            status = link.status()
            self._final = (status.x_steps, status.y_steps, status.z_steps)

    def trace(self) -> Trace | None:
        """After the port is closed: the reported steps, None if nothing reports them."""
        if self._board is not None and self._final is not None and self._trace is None:
            c = self._config
            pins = ((c.x_step_pin, c.x_dir_pin), (c.y_step_pin, c.y_dir_pin),
                    (c.z_step_pin, c.z_dir_pin))
            tick, axis, direction = self._board.step_trace(pins)
            self._trace = Trace(tick, axis, direction, self._final,
                                int(tick[-1]) if len(tick) else 0)
        return self._trace


def job_trace(link: MachineLink, job: Job):
    """The reference machine's trace of the job: what the machine steps, from any
    port (a real board cannot report its steps; sim:// steps the same)."""
    from galileo_cnc.machine import simulate
    return simulate(job.commands, link.config)
