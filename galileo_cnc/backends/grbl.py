"""A stock GRBL 1.1 board as a Machine (docs/grbl.md): GrblLink + grbl/job.py.

GrblLink is single-threaded (every read in the caller's loop), so one lock
serialises it: a front end's command holds it while it runs (`session`), a toolbar's
poller only asks `?` when it can take it at once. The port is wrapped so a job
stopped from another thread can break the streaming thread's read
(grbl.job.InterruptiblePort). The pieces come from galileo_cnc.grbl (jog, home,
unlock, estimate, travel) and grbl/session.py (connection line, steps/mm check,
feed hold then reset); jobs and their journal are grbl/job.py's.
"""

from __future__ import annotations

import threading
import time
from contextlib import contextmanager

import serial

from galileo_cnc.backends.base import (JobResult, Machine, MachineJob, MachineView, Resumption,
                                       position_text)
from galileo_cnc.config.machine import MIN_FEED_STEPS_PER_S, MachineConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.check import check_job
from galileo_cnc.grbl.jog import cancel_jog, home, jog, unlock, wait_jog
from galileo_cnc.grbl.job import (GrblJob, InterruptiblePort, cut_short, grbl_journal,
                                  journal_config, link_scale, pending_job, resume_from)
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.mill_job import GrblMillJob, mill_journal, pending_mill_job
from galileo_cnc.grbl.numbers import read_float
from galileo_cnc.grbl.reports import GrblError, Status, alarm_text, banner_version
from galileo_cnc.grbl.resume import GrblResumeError
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.session import (describe, find_position, hold_and_reset,
                                      position_text as stands_at, refuse_other_scale)
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.pipeline import plan_file
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.simavr.grbl_firmware import grbl_step_trace
from galileo_cnc.stream.journal import FINISHED
from galileo_cnc.stream.resume import replan
from galileo_cnc.transport.link import LinkError, MachineAlarm, PortGone
from galileo_cnc.transport.port import open_port, port_error_text

#: GRBL states in which the head may move: an interrupted command stops it.
MOVING_STATES = ("Run", "Jog", "Hold", "Home")
#: Alarms after which GRBL answers nothing, not even `?`, until a soft reset.
CRITICAL_ALARMS = (1, 2)
#: What a stopped job leaves GRBL in.
HELD = "GRBL held the feed and was reset (its queue dropped, the position kept)"
#: the hold was never seen to settle: the reset may have come while GRBL still moved
NOT_HELD = ("GRBL was reset without being seen to stand still (its queue dropped; it "
            "may still have moved, so resume homes or has you re-zero)")


class GrblMachine(Machine):
    kind = "grbl"
    simulated = False
    checks_jobs = True              # GRBL's check mode ($C)
    queues_jogs = True              # jogs queue up: a held key is followed, then cancelled
    runs_mill = True                # a mill job's G-code (grbl/mill_job.py)
    preview_note = " (the plan: GRBL cannot report its steps)"

    def __init__(self, link: GrblLink, port: InterruptiblePort, name: str,
                 config: MachineConfig, config_path=None):
        self.link = link
        self.port = port
        self.port_name = name
        self.config_path = config_path
        self.profile_config = config
        self.lock = threading.RLock()
        self.alarms_said = len(link.alarms)     # ALARM:N already printed
        self._last: MachineView | None = None
        self._job: GrblJob | None = None
        #: a job this connection stopped: what shows GRBL kept its position since
        self._kept: tuple | None = None
        #: why no job can run (steps/mm differ from the profile's), None when fine
        self.scale_problem: str | None = None
        self._check_scale()

    def _check_scale(self) -> None:
        """scale_problem from GRBL's steps/mm (as last read) against the profile's."""
        try:
            refuse_other_scale(self.link, self.profile_config.steps_per_mm,
                               self.config_path, self.port_name)
            self.scale_problem = None
        except GalileoError as problem:
            self.scale_problem = str(problem)

    def _scale_warning(self) -> str:
        return f"warning: {self.scale_problem}; jobs are refused until they agree"

    @classmethod
    def open(cls, name: str, baud: int, config: MachineConfig, config_path=None,
             profile: MachineConfig | None = None, handle=None,
             shown_as: str | None = None) -> "GrblMachine":
        """`handle`: the port already open and probed (discovery.open_board);
        `shown_as`: the name messages give the port (`name` by default)."""
        if handle is None:
            try:
                handle = open_port(name, baud, timeout=0.2)
            except (serial.SerialException, OSError, ValueError) as problem:
                raise LinkError(f"cannot open {name}: {port_error_text(problem)}") from None
        port = InterruptiblePort(handle)
        try:
            link = GrblLink.connect(port)
        except GrblError as problem:
            port.close()
            raise LinkError(f"{name}: {problem}") from None
        except (serial.SerialException, OSError) as problem:
            port.close()
            raise LinkError(f"{name}: {port_error_text(problem)}") from None
        return cls(link, port, shown_as or name, profile or config, config_path)

    @property
    def config(self) -> MachineConfig:
        return self.profile_config

    def step_recorder(self) -> "GrblSteps":
        return GrblSteps(self)

    def describe(self) -> str:
        line = f"connected to {describe(self.link, self.port_name)}"
        if self.scale_problem:
            line += f"\n{self._scale_warning()}"
        return line

    def check_profile(self) -> None:
        if self.scale_problem:
            raise GalileoError(self.scale_problem)

    def close(self) -> None:
        with self.lock:
            try:
                self.port.close()
            except (serial.SerialException, OSError):
                pass

    @contextmanager
    def session(self):
        """The link is ours while a command runs; a lost port says so as on our firmware."""
        with self.lock:
            try:
                yield
            except (serial.SerialException, OSError) as lost:
                raise PortGone(f"{self.port_name}: {port_error_text(lost)}") from None

    # ---- state -------------------------------------------------------------------
    def make_view(self, status: Status) -> MachineView:
        state = status.state + (f":{status.substate}" if status.substate is not None else "")
        if status.pins:
            state += f", pins {status.pins}"        # a limit switch closed, say so
        self._last = MachineView(f"GRBL {state}", position_text(status.wpos_nm),
                                 alarm=status.state == "Alarm",
                                 moving=status.state in MOVING_STATES, raw=status,
                                 position_mm=tuple(nm / NM_PER_MM for nm in status.wpos_nm))
        return self._last

    def view(self, timeout_s: float = 1.0) -> MachineView | None:
        with self.lock:
            for _ in range(2):          # a `?` that came during a reset is lost: ask again
                try:
                    return self.make_view(self.link.status(timeout_s=timeout_s))
                except GrblError:
                    continue
                except (serial.SerialException, OSError):
                    return None
            return None

    def poll(self) -> MachineView | None:
        """The toolbar's `?`, unless a command is using the link: then the view of the
        last report that command read (a job or jog asks for them as it streams)."""
        if not self.lock.acquire(blocking=False):
            latest = self.link.tracker.last
            if latest is not None and (self._last is None or latest is not self._last.raw):
                return self.make_view(latest)
            return self._last
        try:
            return self.view()
        finally:
            self.lock.release()

    def settle(self, quiet_s: float = 0.3, reset_s: float = 3.0) -> None:
        """Reads what GRBL still sends after an alarm that reset it (the `ok` of the
        line that caused it, up to half a second later, then the banner and
        `[MSG:'$H'|'$X' to unlock]`) until it is quiet after the banner, so the next
        command's reply is not taken from them (and no `?` is lost in the reset)."""
        deadline = time.monotonic() + reset_s
        banner = False
        while True:
            wait = quiet_s if banner else max(0.05, deadline - time.monotonic())
            line = self.link.read_line(wait)
            if line is None:
                return
            banner = banner or banner_version(line) is not None
            try:
                self.link.classify(line)
            except GrblError:
                pass                    # another ALARM:N: kept in link.alarms

    def news(self) -> list[str]:
        """ALARM:N lines GRBL sent that were not printed yet, with GRBL's words."""
        new = self.link.alarms[self.alarms_said:]
        self.alarms_said = len(self.link.alarms)
        return [alarm_text(code) for code in new]

    def after_command(self, view: MachineView | None) -> list[str]:
        lines = self.news()
        if view is None and self.link.alarms and self.link.alarms[-1] in CRITICAL_ALARMS:
            # after a limit alarm GRBL waits for a reset and answers nothing meanwhile
            try:
                self.link.soft_reset()
                view = self.view()
                lines.append("GRBL was reset to answer again after the alarm (its "
                             "position may be lost)")
            except (GrblError, serial.SerialException, OSError):
                pass
        if view is not None and view.alarm:
            lines.append("GRBL is locked (Alarm): type home ($H) to home it, or unlock "
                         "($X) to unlock it where it stands")
        return lines

    def status_line(self, config: MachineConfig) -> str:
        status = self.link.status()
        self.make_view(status)
        state = status.state + (f":{status.substate}" if status.substate is not None else "")
        scale = [float(read_float(self.link.settings.steps_per_mm_text(a))) for a in range(3)]
        steps = [round(nm * s / NM_PER_MM) for nm, s in zip(status.wpos_nm, scale)]
        extra = ""
        if status.pins:
            extra += f", pins {status.pins}"
        if status.planner_free is not None:
            extra += f", planner {status.planner_free} blocks free"
        return (f"state {state}, {position_text(status.wpos_nm)} work "
                f"(steps X {steps[0]} Y {steps[1]} Z {steps[2]}), machine "
                f"{position_text(status.mpos_nm)}{extra}, feed {config.feed_mm_s:g} mm/s "
                f"(GRBL {self.link.version})")

    def stop_if_moving(self, view: MachineView | None, say) -> None:
        if view is None or not view.moving:
            return
        if view.raw.state == "Jog":
            say("cancelling the jog (GRBL decelerates)")
            cancel_jog(self.link)
            return
        say("stopping GRBL: feed hold (it decelerates), then a reset")
        hold_and_reset(self.link)

    # ---- commands -----------------------------------------------------------------
    def _alarm_settled(self, problem: GrblError) -> None:
        """An alarm GRBL raised: what it still says read, then MachineAlarm (the front
        end names the alarm: after_command)."""
        if problem.alarm:
            self.settle()
            raise MachineAlarm(str(problem)) from None
        raise problem

    def home(self, say) -> None:
        self._kept = None               # the frame a stopped job was in may move
        say("homing ($H)...")
        try:
            status = home(self.link)
        except GrblError as problem:
            self._alarm_settled(problem)
        say(f"homed: {position_text(status.wpos_nm)} work, machine "
            f"{position_text(status.mpos_nm)}")

    def unlock(self, say) -> None:
        self._kept = None
        before = self.link.alarms[-1] if self.link.alarms else None
        if self.view() is None:        # waiting for a reset after a limit alarm
            self.link.soft_reset()
        status = unlock(self.link)
        self.news()                     # what the unlock was for needs no second line
        cause = f" (it was {alarm_text(before)})" if before is not None else ""
        say(f"unlocked ($X){cause}: state {status.state}, "
            f"{position_text(status.wpos_nm)}; the position may be off: home "
            f"or set the origin before plotting")

    def jog(self, axis: int, distance_nm: int, feed_mm_s: float) -> None:
        """One `$J=` jog; GrblError (TravelError, JogError: GRBL's or our words) when
        refused."""
        jog(self.link, "XYZ"[axis], distance_nm / NM_PER_MM, feed_mm_s * 60)

    def cancel_jog(self) -> Status:
        """0x85: GRBL decelerates on its path and drops the queued jogs."""
        return cancel_jog(self.link)

    def wait_still(self) -> Status:
        return wait_jog(self.link)

    def set_origin(self) -> str:
        """G10 L20 P0: the current coordinate system's zero is here (GRBL keeps G54-G59
        in its EEPROM)."""
        self._kept = None
        self.wait_still()
        reply = self.link.command("G10 L20 P0 X0 Y0 Z0")
        if not reply.ok:
            raise GrblError(f"GRBL refused the origin: {reply.text}")
        return ("origin set here: X, Y and Z are 0 now (Z 0 draws; G10 L20 P0, kept in "
                "GRBL's EEPROM)")

    def max_feed_mm_s(self) -> float:
        """GRBL's $110/$111 (mm/min): the fastest X and Y may go."""
        return min(float(read_float(self.link.settings.max_rate_mm_min(a))) for a in (0, 1)) / 60

    def feed_refusal(self, config: MachineConfig, mm_s: float) -> str | None:
        lowest = MIN_FEED_STEPS_PER_S / config.steps_per_mm
        highest = self.max_feed_mm_s()
        if lowest <= mm_s <= highest:
            return None
        return (f"refused: GRBL runs {lowest:g} .. {highest:g} mm/s here (its $110/$111 "
                f"max rates {self.link.settings.max_rate_mm_min(0)}/"
                f"{self.link.settings.max_rate_mm_min(1)} mm/min)")

    def set_feed(self, config: MachineConfig, mm_s: float) -> str:
        # GRBL takes the feed with each line (F in mm/min): nothing to send now
        return f", sent to GRBL as F{mm_s * 60:g} with each jog and job line"

    # ---- jobs ---------------------------------------------------------------------
    def _machine_job(self, job: GrblJob) -> MachineJob:
        return MachineJob(job.planned, len(job.lines), job.start, job.estimate_s,
                          "G-code lines", "G-code lines", "on GRBL (its planner's estimate)",
                          job, job.config)

    def prepare(self, planned, config: MachineConfig, timing=None,
                homed: bool = False) -> MachineJob:
        self.check_profile()
        job = GrblJob(self.link, self.port, planned, config)
        job.port_name = self.port_name
        return self._machine_job(job)

    def check_job(self, job: MachineJob):
        """GRBL's check mode ($C) over the whole job: what GRBL rejects, moving nothing."""
        engine: GrblJob = job.engine
        return check_job(self.link, engine.lines, where=engine.where)

    def run_job(self, job: MachineJob, operator) -> JobResult:
        """The travel check, then the job journalled and streamed (a mill job: in the
        mill journal; its M0s come to operator.pen_change as a MillPause). Raises
        GrblPortLost (a PortGone) for a lost port, GrblStreamError for a refusal, an
        alarm or a probe that touched nothing."""
        engine = job.engine
        engine.check_travel()
        if isinstance(engine, GrblMillJob):
            engine.begin_journal(mill_journal(), engine.entry)
            return self._streamed(engine, operator, f"the spindle stopped, the tool lifted "
                                                    f"to {engine.program.safe_mm} mm")
        if engine.entry is None:                # a new job
            self._warn_g92(operator)
        engine.begin_journal(grbl_journal(), engine.entry)
        return self._streamed(engine, operator, "the pen lifted")

    def _streamed(self, engine, operator, lifted: str) -> JobResult:
        """A journalled GrblJob or GrblMillJob run; `lifted`: what a stop left."""
        self._kept = None
        self._job = engine
        try:
            result = engine.run(operator.progress, operator.pen_change)
        except GrblStreamError:
            self.news()                 # the alarm is in the error, with its file line
            raise
        finally:
            self._job = None
        if not result.completed:
            try:
                where = stands_at(self.link.status())
                # reset while it still moved (no report at rest): the position may be
                # lost even without ALARM:3, which GRBL 1.1h can lose (docs/grbl.md)
                self._kept = self._keeping() if engine.stopped_at_rest else None
            except GrblError:
                where = "GRBL's position was not reported"
            lifted = f"; {engine.lift_failed}" if engine.lift_failed else f"; {lifted}"
            return JobResult(False, result.confirmed, result.total, result.elapsed_s,
                             result.reason, "G-code lines", where,
                             (HELD if engine.stopped_at_rest else NOT_HELD) + lifted)
        return JobResult(True, result.total, result.total, result.elapsed_s,
                         unit="G-code lines", where=stands_at(self.link.tracker.last))

    def _warn_g92(self, operator) -> None:
        """A G92 offset is lost on any reset, so a resume could not restore it: say so."""
        reply = self.link.command("$#")
        g92 = next((line for line in reply.lines if line.startswith("[G92:")), "")
        if g92 and any(float(v) != 0 for v in g92[5:-1].split(",")):
            operator.say(f"note: GRBL has a G92 offset {g92}: GRBL forgets it on a reset, "
                         f"so a resume after a lost port could not restore it (set the "
                         f"work zero with G10 L20 instead)")

    def stop(self) -> None:
        job = self._job
        if job is not None:
            job.stop()

    def pending(self, file: str | None = None):
        return pending_job(grbl_journal(), file)

    def plan_resume(self, entry, *, on_stage=None, plan=None, timing=None) -> Resumption:
        config = journal_config(entry)
        refuse_other_scale(self.link, config.steps_per_mm, self.config_path, self.port_name)
        planned = replan(entry, config, on_stage=on_stage, plan=plan or plan_file)
        job = GrblJob(self.link, self.port, planned, config)
        job.port_name = self.port_name
        start, why = resume_from(self.link, entry, job.lines)
        if start >= len(job.lines):
            journal = grbl_journal()
            journal.begin(entry)
            journal.end(FINISHED, "every line was acknowledged before the job stopped")
            return Resumption(None, why, nothing_left="nothing left to resume: GRBL had "
                              "acknowledged every line of the job")
        job.entry = entry
        job.go_on_from(start)
        return Resumption(self._machine_job(job), why)

    def _keeping(self) -> tuple:
        """What shows GRBL kept its position since now: no banner (a reset) and no
        alarm after this, the same work offset (no new origin)."""
        link = self.link
        banners = sum(1 for line in link.messages if banner_version(line))
        return banners, len(link.alarms), tuple(link.tracker.wco_nm or ())

    def kept_position(self) -> bool:
        """GRBL stands where the job's stop left it, in the same work frame: this
        connection stopped the job, and GRBL was not reset, alarmed, homed, unlocked
        or given a new origin since (a jog is fine: the lead-in travels back)."""
        if self._kept is None:
            return False
        try:
            status = self.link.status()
        except GrblError:
            return False
        return status.state == "Idle" and self._keeping() == self._kept

    def find_position(self, resumption: Resumption, operator) -> bool:
        """Where this connection stopped the job and GRBL kept its position since, go
        on from there; else home ($H) or have the user re-zero: GRBL was reset since
        the job stopped."""
        engine: GrblJob = resumption.job.engine
        if isinstance(engine, GrblMillJob):
            return self._find_mill_position(engine, operator, resumption)
        if self.kept_position():
            operator.say(f"GRBL kept its position since the job stopped: "
                         f"{stands_at(self.link.status())}; the job goes on from there")
            operator.say(resumption.job.estimate_line())
            return True
        try:
            found = find_position(self.link, engine.scale, engine.pen, operator.say,
                                  lambda question: operator.confirm(f"{question}: move it "
                                                                    f"there"))
        except GrblError as problem:
            self._alarm_settled(problem)
        if found:
            operator.say(resumption.job.estimate_line())
        return found

    # ---- mill jobs -------------------------------------------------------------------
    def _mill_machine_job(self, job: GrblMillJob) -> MachineJob:
        return MachineJob(job.program, len(job.lines), job.start, job.estimate_s,
                          "G-code lines", "G-code lines", "on GRBL (its planner's estimate)",
                          job, None)

    def prepare_mill(self, program) -> MachineJob:
        """A mill job's G-code as GRBL runs it (grbl/mill_job.py): sent in mm, GRBL's own
        $100-$102 apply, so the profile's steps/mm are not checked against them."""
        job = GrblMillJob(self.link, self.port, program)
        job.port_name = self.port_name
        return self._mill_machine_job(job)

    def pending_mill(self):
        return pending_mill_job(mill_journal())

    def interrupted_mill(self):
        try:
            return self.pending_mill()
        except GrblResumeError:
            raise                       # there is one, but it cannot be resumed
        except GalileoError:
            return None

    def probe_height_map(self, grid, on_point=None):
        """The surface under the job probed with G38.2 at every node of `grid`
        (grbl/probe.py): a HeightMap in work Z; ProbeError naming the node in mm."""
        from galileo_cnc.grbl.probe import probe_height_map
        return probe_height_map(self.link, grid, on_point)

    def plan_mill_resume(self, pending) -> Resumption:
        entry, program = pending
        job = GrblMillJob(self.link, self.port, program)
        job.port_name = self.port_name
        if entry.total != len(job.lines):
            raise GalileoError(f"{entry.source}: the journal counts {entry.total} G-code "
                               f"lines, the kept G-code has {len(job.lines)}: it cannot be "
                               f"resumed")
        start, why = job.resume_point(entry, cut_short(self.link, entry))
        if start >= len(job.lines):
            journal = mill_journal()
            journal.begin(entry)
            journal.end(FINISHED, "every line was confirmed before the job stopped")
            return Resumption(None, why, nothing_left="nothing left to resume: GRBL had "
                              "confirmed every line of the mill job")
        job.entry = entry
        job.go_on_from(start)
        return Resumption(self._mill_machine_job(job), why)

    def _find_mill_position(self, engine: GrblMillJob, operator, resumption) -> bool:
        """As for a plot: the kept position, else $H, else the user puts the tool at the
        job's work zero (X0 Y0, its tip on the board's top), which becomes G54's zero,
        and the tool goes up to the safe height at once."""
        if self.kept_position():
            operator.say(f"GRBL kept its position since the job stopped: "
                         f"{stands_at(self.link.status())}; the job goes on from there")
        elif self.link.settings.homing:
            operator.say("homing ($H): the reset lost GRBL's position")
            try:
                home(self.link)
            except GrblError as problem:
                self._alarm_settled(problem)
        else:
            if not operator.confirm("GRBL has no homing ($22=0): the reset lost its "
                                    "position. The tool in the spindle must stand at the "
                                    "job's work zero: X0 Y0, its tip on the board's top"):
                return False
            if self.link.status().state == "Alarm":
                unlock(self.link)
            self.link.command_checked("G10 L20 P1 X0 Y0 Z0")
            self.link.command_checked(f"G0 Z{engine.program.safe_mm}")
        operator.say(resumption.job.estimate_line())
        return True

    # ---- a command line -----------------------------------------------------------
    def send_line(self, text: str, say) -> bool:
        """The line as it is, GRBL's reply shown; `$N=` settings read again after."""
        from galileo_cnc.backends.command_line import (changes_grbl_settings,
                                                       run_home_or_unlock, send_to_grbl)

        if run_home_or_unlock(self, text, say):
            return True
        try:
            taken = send_to_grbl(self.link, text, say)
        except GrblError as problem:
            self._alarm_settled(problem)
        if taken and changes_grbl_settings(text):
            self.link.read_info()           # steps/mm, max rates: what jobs are checked by
            self._check_scale()
            if self.scale_problem:
                say(self._scale_warning())
        return taken

    def origin_after_home(self) -> str:
        """$H sets GRBL's machine frame; the work origin stays G54's offset from it."""
        status = self.link.status()
        offset = tuple(m - w for m, w in zip(status.mpos_nm, status.wpos_nm))
        if not any(offset):
            return "the work origin is now the home position (GRBL's G54 offset is zero)"
        return (f"the work origin is GRBL's G54 offset, {position_text(offset)} from the "
                f"homed machine frame: where it was set only if GRBL was homed then too; "
                f"else set it again where the paper is (setup, then o)")


class GrblSteps:
    """The steps GRBL's pins made on simavr:// (recorded from the board's power-on),
    the final position GRBL's last work position; None from a real board."""

    source = "GRBL's step pins in simavr"

    def __init__(self, machine: GrblMachine):
        self.machine = machine
        board = getattr(machine.port, "board", None)
        self._board = board if board is not None and board.records_steps else None
        self._final = None

    def job_done(self) -> None:
        self._final = self.machine.link.tracker.last

    def trace(self) -> Trace | None:
        if self._board is None or self._final is None:
            return None
        link = self.machine.link
        scale = link_scale(link)
        tick, axis, direction = grbl_step_trace(self._board.trace(), link.settings.integer(3))
        here = tuple(round(nm * float(scale.steps_per_mm[a]) / NM_PER_MM)
                     for a, nm in enumerate(self._final.wpos_nm))
        return Trace(tick, axis, direction, here, int(tick[-1]) if len(tick) else 0)
