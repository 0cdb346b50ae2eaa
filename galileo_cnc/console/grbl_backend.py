"""The console on a stock GRBL 1.1 board (docs/grbl.md, docs/console.md "GRBL").

GrblLink is single-threaded (every read in the caller's loop), so one lock
serialises it: a command holds it while it runs (`session`), the toolbar's poller
only asks `?` when it can take it at once. The port is wrapped so a job stopped
from the progress bar's key thread can break the streaming thread's read
(`InterruptiblePort`). The pieces come from galileo_cnc.grbl (jog, home, unlock,
G-code, estimate, travel, streaming) and grbl/session.py (connection line,
steps/mm check, pieces between pen changes, feed hold then reset); jobs and their
journal, getg's and resume's, are grbl_job.py's.
"""

from __future__ import annotations

import threading
import time
from contextlib import contextmanager

import serial

from galileo_cnc.config.machine import MIN_FEED_STEPS_PER_S, MachineConfig
from galileo_cnc.console.backend import Backend, MachineView
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.jog import cancel_jog, home, unlock
from galileo_cnc.grbl.link import FEED_HOLD, GrblLink
from galileo_cnc.grbl.numbers import read_float
from galileo_cnc.grbl.reports import GrblError, Status, alarm_text, banner_version
from galileo_cnc.grbl.session import describe, hold_and_reset, refuse_other_scale
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.transport.link import LinkError, PortGone
from galileo_cnc.transport.port import open_port, port_error_text

#: GRBL states in which the head may move: an interrupted command stops it.
MOVING_STATES = ("Run", "Jog", "Hold", "Home")
#: Alarms after which GRBL answers nothing, not even `?`, until a soft reset.
CRITICAL_ALARMS = (1, 2)


class JobInterrupted(Exception):
    """The user stopped the job: raised by the port's next read in the streaming thread."""


class InterruptiblePort:
    """A pyserial port whose `readline` raises JobInterrupted (once) after `interrupt`:
    GrblLink and grbl.stream read in short slices, so the streaming thread notices
    within one slice (0.2 s) that the key thread asked for a stop."""

    def __init__(self, port):
        self._port = port
        self._stop = threading.Event()
        self.armed = False

    @property
    def timeout(self):
        return self._port.timeout

    @timeout.setter
    def timeout(self, value) -> None:
        self._port.timeout = value

    def interrupt(self) -> None:
        self._stop.set()

    def arm(self) -> None:
        self._stop.clear()
        self.armed = True

    def disarm(self) -> None:
        self.armed = False
        self._stop.clear()

    def readline(self, *args) -> bytes:
        if self.armed and self._stop.is_set():
            self.disarm()
            raise JobInterrupted
        return self._port.readline(*args)

    def write(self, data: bytes) -> int:
        return self._port.write(data)

    def close(self) -> None:
        self._port.close()

    def __getattr__(self, name):
        return getattr(self._port, name)


def mm3(nm: int) -> str:
    return f"{nm / NM_PER_MM:.3f}"


def position_text(nm: tuple[int, ...]) -> str:
    return f"X {mm3(nm[0])}  Y {mm3(nm[1])}  Z {mm3(nm[2])} mm"


class GrblBackend(Backend):
    kind = "grbl"
    simulated = False

    def __init__(self, link: GrblLink, port: InterruptiblePort, name: str,
                 config: MachineConfig, config_path=None):
        self.link = link
        self.port = port
        self.port_name = name
        self.config_path = config_path
        self.lock = threading.RLock()
        self.alarms_said = len(link.alarms)     # ALARM:N already printed
        self._last: MachineView | None = None
        #: why no job can run (steps/mm differ from the profile's), None when fine
        self.scale_problem: str | None = None
        try:
            refuse_other_scale(link, config.steps_per_mm, config_path, name)
        except GalileoError as problem:
            self.scale_problem = str(problem)

    @classmethod
    def open(cls, name: str, baud: int, config: MachineConfig, config_path=None,
             profile: MachineConfig | None = None, handle=None) -> "GrblBackend":
        """`handle`: the port already open and probed (discovery.open_board)."""
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
        return cls(link, port, name, profile or config, config_path)

    def describe(self) -> str:
        line = f"connected to {describe(self.link, self.port_name)}"
        if self.scale_problem:
            line += f"\nwarning: {self.scale_problem}; jobs are refused until they agree"
        return line

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
                                 moving=status.state in MOVING_STATES, raw=status)
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
        """The toolbar's `?`, unless a command is using the link (then the last view)."""
        if not self.lock.acquire(blocking=False):
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

    def stop_if_moving(self, console, view: MachineView | None) -> None:
        if view is None or not view.moving:
            return
        if view.raw.state == "Jog":
            console.say("cancelling the jog (GRBL decelerates)")
            cancel_jog(self.link)
            return
        console.say("stopping GRBL: feed hold (it decelerates), then a reset")
        hold_and_reset(self.link)

    # ---- commands -----------------------------------------------------------------
    def home(self, console) -> None:
        console.say("homing ($H)...")
        try:
            status = home(self.link)
        except GrblError as problem:
            if problem.alarm:
                self.settle()           # what GRBL still says after the alarm
                return                  # after_command prints the ALARM line and the hint
            raise
        console.say(f"homed: {position_text(status.wpos_nm)} work, machine "
                    f"{position_text(status.mpos_nm)}")

    def unlock(self, console) -> None:
        before = self.link.alarms[-1] if self.link.alarms else None
        if self.view() is None:        # waiting for a reset after a limit alarm
            self.link.soft_reset()
        status = unlock(self.link)
        self.news()                     # what the unlock was for needs no second line
        cause = f" (it was {alarm_text(before)})" if before is not None else ""
        console.say(f"unlocked ($X){cause}: state {status.state}, "
                    f"{position_text(status.wpos_nm)}; the position may be off: home "
                    f"or set the origin before plotting")

    def jog_with_keypad(self, console, units: int) -> None:
        from galileo_cnc.console.grbl_keypad import jog_with_keypad
        jog_with_keypad(console, self, units)

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

    def set_feed(self, console, mm_s: float) -> str:
        # GRBL takes the feed with each line (F in mm/min): nothing to send now
        return f", sent to GRBL as F{mm_s * 60:g} with each jog and job line"

    def check_before_planning(self, console) -> None:
        if self.scale_problem:
            raise GalileoError(self.scale_problem)

    def plot(self, console, planned, config: MachineConfig) -> None:
        from galileo_cnc.console.grbl_job import plot_on_grbl
        plot_on_grbl(console, self, planned, config)

    def resume(self, console) -> None:
        """The job in the GRBL journal (from getg or `galileo-cnc plot`), as plot
        --resume continues it: home or re-zero, lead-in, then the rest."""
        from galileo_cnc.console.grbl_job import resume_on_grbl
        resume_on_grbl(console, self)

    def stop_job(self) -> None:
        """From the progress bar's key thread: feed hold now (GRBL decelerates on its
        path), and the streaming thread's next read raises JobInterrupted."""
        self.port.write(FEED_HOLD)
        self.port.interrupt()
