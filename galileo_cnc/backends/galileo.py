"""Our firmware as a Machine: a board, `sim://` or `simavr://`, over MachineLink.

The link is thread-safe (its own reader thread); jobs stream through
stream.streamer.JobStreamer and are journalled (journal.json), so `resume` continues
them: where the machine stands after a lost port or a stop, or homed again after a
reset of a job whose frame was the homed one (stream/resume.py).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from galileo_cnc.backends.base import (JobResult, Machine, MachineJob, MachineView, Resumption,
                                       position_mm_text)
from galileo_cnc.config.machine import MIN_FEED_STEPS_PER_S, MachineConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import Home, Jog, SetFeed, SetOrigin
from galileo_cnc.plan.pipeline import plan_file
from galileo_cnc.protocol import Status, Unlock
from galileo_cnc.machine.trace import Trace
from galileo_cnc.stream.homing import home, home_after_reset, z_has_end_stop
from galileo_cnc.stream.journal import Journal
from galileo_cnc.stream.resume import plan_resume
from galileo_cnc.stream.streamer import JobStreamer, Progress, StreamResult
from galileo_cnc.transport.link import LinkError, MachineLink

#: States in which the head may be moving: a command interrupted there must stop it.
MOVING_STATES = ("run", "hold", "homing")


class GalileoMachine(Machine):
    kind = "galileo"

    def __init__(self, link: MachineLink, journal: Journal | None = None):
        self.link = link
        self._journal = journal
        self._streamer: JobStreamer | None = None
        self.gcode_lines = None     # the command line's G-code modes (command_line.GcodeLines)

    @classmethod
    def open(cls, port: str | None, baud: int, config: MachineConfig, config_path=None,
             profile: MachineConfig | None = None, on_message=None,
             handle=None) -> "GalileoMachine":
        """`handle`: the port already open and probed (discovery.open_board)."""
        link = (MachineLink.attach(handle, port, baud, config, config_path, profile=profile,
                                   booted=True) if handle is not None else
                MachineLink.open(port, baud, config, config_path, profile=profile))
        link.on_message = on_message
        return cls(link)

    @property
    def journal(self) -> Journal:
        """journal.json in the user's data folder (found when asked: tests move it)."""
        return self._journal if self._journal is not None else Journal.default()

    @property
    def port_name(self) -> str:
        return self.link.port_name

    @property
    def simulated(self) -> bool:
        return self.link.simulated

    @property
    def config(self) -> MachineConfig:
        return self.link.config

    def describe(self) -> str:
        return self.link.describe()

    def step_recorder(self) -> "ReportedSteps":
        return ReportedSteps(self.link)

    def home_for_job(self) -> Status:
        return home(self.link)

    def check_profile(self) -> None:
        self.link.check_config()        # a board built for another machine: say so first

    def use_config(self, config: MachineConfig) -> None:
        self.link.config = config               # the journal keeps the link's copy

    def close(self) -> None:
        self.link.close()

    # ---- state -------------------------------------------------------------------
    def view(self, timeout_s: float = 1.0) -> MachineView | None:
        try:
            status = self.link.status(timeout_s=timeout_s)
        except LinkError:
            return None
        spm = self.link.config.steps_per_mm
        return MachineView(status.state, position_mm_text(status, self.link.config),
                           alarm=status.state == "alarm",
                           moving=status.state in MOVING_STATES, raw=status,
                           position_mm=(status.x_steps / spm, status.y_steps / spm,
                                        status.z_steps / spm))

    def after_command(self, view: MachineView | None) -> list[str]:
        if view is not None and view.alarm:
            return ["the machine is locked (alarm): check it, then type unlock"]
        return []

    def status_line(self, config: MachineConfig) -> str:
        state = self.link.status()
        return (f"state {state.state}, {position_mm_text(state, config)} "
                f"(steps X {state.x_steps} Y {state.y_steps} Z {state.z_steps}), "
                f"queue {state.queue_blocks}, feed {config.feed_mm_s:g} mm/s")

    def stop_if_moving(self, view: MachineView | None, say) -> None:
        if view is not None and view.moving:
            say("stopping the machine (ramping down)")
            self.link.abort()

    # ---- commands -----------------------------------------------------------------
    def home(self, say) -> None:
        say("homing...")
        self.link.send(Home())
        state = self.link.wait_idle()
        say(f"homed: {position_mm_text(state, self.link.config)}")

    def unlock(self, say) -> None:
        alarm = self.link.take_alarm()
        self.link.send_protocol(Unlock())
        state = self.link.status()
        cause = f" (it was alarm:{alarm.code} {alarm.text})" if alarm else ""
        say(f"unlocked{cause}: state {state.state}, "
            f"{position_mm_text(state, self.link.config)}")

    def jog(self, axis: int, distance_nm: int, feed_mm_s: float = 0.0) -> None:
        """One `Jog` at the machine's feed; LinkError when refused (leaving the travel)."""
        steps = [0, 0, 0]
        steps[axis] = self.link.config.nm_to_steps(distance_nm)
        self.link.send(Jog(*steps))

    def cancel_jog(self) -> None:
        """Ramps the machine down (the host's abort); the planner drops what was queued."""
        self.link.abort()

    def wait_still(self) -> Status:
        return self.link.wait_idle()

    def set_origin(self) -> str:
        self.wait_still()
        self.link.send(SetOrigin())
        return "origin set here: X, Y and Z are 0 now (Z 0 draws)"

    def feed_refusal(self, config: MachineConfig, mm_s: float) -> str | None:
        steps_per_s = config.feed_steps_per_s_of(mm_s)
        if MIN_FEED_STEPS_PER_S <= steps_per_s <= config.max_feed_steps_per_s:
            return None
        lowest = MIN_FEED_STEPS_PER_S / config.steps_per_mm
        highest = config.max_feed_steps_per_s / config.steps_per_mm
        return f"refused: the machine runs {lowest:g} .. {highest:g} mm/s"

    def set_feed(self, config: MachineConfig, mm_s: float) -> str:
        self.link.send(SetFeed(config.feed_steps_per_s_of(mm_s)))
        return ""

    # ---- jobs ---------------------------------------------------------------------
    def _job(self, planned, streamer: JobStreamer, start: int = 0) -> MachineJob:
        job = planned.job
        return MachineJob(planned, len(job), start,
                          streamer.timing.seconds_between(start, len(job)), "commands",
                          "machine commands", "of machine time", streamer,
                          self.link.config)

    def prepare(self, planned, config: MachineConfig, timing=None,
                homed: bool = False) -> MachineJob:
        """`timing`: the job's (stepped elsewhere, or kept by the console), or what gives
        it, when it was worked out for this machine's config; `homed`: the job's frame is the homed one
        (a reset can be resumed)."""
        streamer = JobStreamer(self.link, planned.job, planned.plotted, journal=self.journal,
                               homed=homed, timing=timing() if callable(timing) else timing)
        return self._job(planned, streamer)

    def run_job(self, job: MachineJob, operator) -> JobResult:
        """Raises PortGone (a lost port), MachineReset (the board was reset), LinkError
        (a refusal); the journal says how it ended."""
        streamer: JobStreamer = job.engine

        def progress(p: Progress) -> None:
            # the streamer counts from where this run started; a front end shows the
            # whole job's commands, as GRBL's job shows its lines (a resume goes on
            # from "334/539", not from "1/206")
            operator.progress(replace(p, confirmed=p.confirmed + streamer.start,
                                      total=p.total + streamer.start))

        self._refuse_if_locked()
        self._streamer = streamer
        try:
            result: StreamResult = streamer.run(on_progress=progress,
                                                on_pen_change=operator.pen_change)
        finally:
            self._streamer = None
        return JobResult(result.completed, result.confirmed, result.total, result.elapsed_s,
                         result.reason, "commands", held=result.held)

    def _refuse_if_locked(self) -> None:
        """A machine locked before the job (a failed `home`) takes none of it: said so,
        rather than found in the middle of streaming as an alarm nobody raised."""
        if self.link.status().state != "alarm":
            return
        alarm = self.link.take_alarm()
        cause = f" (alarm:{alarm.code} {alarm.text})" if alarm else ""
        raise GalileoError(f"the machine is locked{cause}: nothing of the job was sent; type "
                           f"unlock, then home again or jog to where the job should start")

    def stop(self) -> None:
        streamer = self._streamer
        if streamer is not None:
            streamer.abort()

    def pending(self, file: str | None = None):
        """GalileoError when there is none (of `file`)."""
        entry = self.journal.pending()
        if entry is None or (file is not None and Path(entry.source) != Path(file).resolve()):
            raise GalileoError(f"no interrupted job{f' of {file}' if file else ''} to resume")
        return entry

    def plan_resume(self, entry, *, on_stage=None, plan=None, timing=None) -> Resumption:
        """`timing`: job_timing, or one that keeps it (the console's PlanCache)."""
        point = plan_resume(self.link, entry, on_stage=on_stage,   # ResumeError says why not
                            plan=plan or plan_file)
        job, start = point.job, point.start
        reason = f" ({entry.reason})" if entry.reason else ""
        why = (f"{start} of {len(job)} commands were done{reason}; resuming at command "
               f"{start + 1} of {len(job)}")
        streamer = JobStreamer(self.link, job, point.program, journal=self.journal,
                               start=start, lead_in=point.lead_in, job_start=point.job_start,
                               homed=point.homed,
                               timing=timing(job, self.link.config) if timing else None)
        planned = _Resumed(job, point.program, point.artwork)
        return Resumption(self._job(planned, streamer, start), why, home_first=point.home,
                          unsure=point.unsure,
                          z_needs_hand=point.home and not z_has_end_stop(self.link.config),
                          lost=point.lost)

    def find_position(self, resumption: Resumption, operator) -> bool:
        """Where a lost port or a stop left the machine, it stands already; after a
        reset (or, for a homed job, wherever else it stands) it is homed (Z without an
        end stop: the user sets the pen first)."""
        if resumption.home_first:
            unsure = (f"; the last {resumption.unsure} commands it confirmed may not have "
                      f"run, so they are drawn again" if resumption.unsure > 0 else "")
            operator.say(f"{resumption.lost}: homing finds the job's frame again{unsure}")
            if resumption.z_needs_hand and not operator.confirm(
                    "Z has no end stop, so the reset lost the pen's height: turn the pen "
                    "back to its Z origin (where Z 0 was set; with the default pen "
                    "heights, touching the paper)"):
                return False
            home_after_reset(self.link)
            operator.say("homed")
        operator.say(resumption.job.estimate_line())
        return True

    # ---- a command line -----------------------------------------------------------
    def send_line(self, text: str, say) -> bool:
        """G-code as a job of one line, not journalled; `$$`, `$H`, `$X` as ours."""
        from galileo_cnc.backends.command_line import send_to_galileo

        return send_to_galileo(self, text, say)

    def origin_after_home(self) -> str:
        """Homing makes each homed axis's origin 0 at its switch (stream/homing.py)."""
        axes, z_note = "X, Y and Z", ""
        if not z_has_end_stop(self.link.config):
            axes, z_note = "X and Y", "; Z has no end stop and keeps its origin"
        return (f"the origin is now the home position ({axes} 0 at the end stops{z_note}): "
                f"an origin set in setup before is replaced; set it again where the paper "
                f"is (setup, then o)")


class _Resumed:
    """A resumed job in the shape of a PlannedFile, for what front ends read of it."""

    def __init__(self, job, program, artwork):
        self.job = job
        self.plotted = program
        self.program = program
        self.artwork = artwork
        self.offset_nm = job.offset_nm
        self.copper = None
        self.ink = None


class ReportedSteps:
    """The steps the machine behind a link reports: sim:// its reference machine's own
    stepper (from the step count at the job's start: a named machine may have moved
    before), simavr:// the step and direction pin edges the harness recorded since the
    board's power-on (complete once the port is closed). None from a real board."""

    def __init__(self, link: MachineLink):
        self.link = link
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

    def job_done(self) -> None:
        """While the port is still open: the sim's steps, or where the board stands."""
        if self._machine is not None:
            whole = self._machine.trace()
            self._trace = Trace(whole.tick[self._first:], whole.axis[self._first:],
                                whole.dir[self._first:], whole.final_position,
                                whole.total_ticks)
        elif self._board is not None:
            status = self.link.status()
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
