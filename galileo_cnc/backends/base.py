"""One machine interface for every front end (the console, `plot`, later a web page).

A `Machine` is a connected board of one kind: our firmware (`sim://`, `simavr://`, a
real board; backends/galileo.py) or stock GRBL 1.1 (backends/grbl.py). Front ends
call it for everything that differs between the kinds, never `if grbl:` themselves.
A job runs in two steps: `prepare` (or `plan_resume` for an interrupted one) turns
a planned file into a `MachineJob` (the estimate, the travel check), which the front
end announces; `run_job` (or `resume`) streams it, journalled, and returns a
`JobResult`. What a job needs from the person at the machine comes through the
`Operator` the front end lends it.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any, Callable, ContextManager, Protocol

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.stream.streamer import PenChange, Progress


def mm3(nm: int) -> str:
    return f"{nm / NM_PER_MM:.3f}"


def position_text(nm: tuple[int, ...]) -> str:
    """A head position (nm) as the front ends print it: X, Y, Z in mm."""
    return f"X {mm3(nm[0])}  Y {mm3(nm[1])}  Z {mm3(nm[2])} mm"


def position_mm_text(status, config: MachineConfig) -> str:
    """Our firmware's status position (steps) as position_text prints it."""
    return (f"X {status.x_steps / config.steps_per_mm:.3f}  "
            f"Y {status.y_steps / config.steps_per_mm:.3f}  "
            f"Z {status.z_steps / config.steps_per_mm:.3f} mm")


@dataclass(frozen=True, slots=True)
class MachineView:
    """A status report as a front end shows it (toolbar, alarm check)."""

    state: str                  # as the toolbar shows it: "idle", "GRBL Idle"
    where: str                  # "X 0.000  Y 0.000  Z 0.000 mm"
    alarm: bool = False         # locked: the console names it after a command
    moving: bool = False        # a command interrupted there must stop the head
    raw: Any = None             # the machine's own status
    #: where the head is, work mm (X, Y, Z): what a page draws over the preview
    position_mm: tuple[float, float, float] | None = None


@dataclass
class JobResult:
    """How a job run ended (a lost port, a reset or a refusal raise instead)."""

    completed: bool
    confirmed: int              # units confirmed from where this run started
    total: int                  # units this run had to send
    elapsed_s: float
    reason: str = ""            # why it stopped
    unit: str = "commands"      # what was counted: "commands", "G-code lines"
    where: str = ""             # the position at the end, where the machine says it
    held: str = ""              # stopped: what the stop left the machine in, if not said


class Operator(Protocol):
    """What a front end lends a job."""

    def say(self, text: str) -> None:
        """A line for the user."""

    def progress(self, p: Progress) -> None:
        """How far the job is, in units of the whole job (a resumed run starts at the
        units done before it)."""

    def pen_change(self, c: PenChange) -> None:
        """Returns when the pen is in; raise stream.streamer.StreamAborted to stop."""

    def confirm(self, question: str) -> bool:
        """Whether the user made `question` true (the pen stands at the work zero)."""


@dataclass
class MachineJob:
    """A planned job made ready for one machine: what `run_job` streams."""

    planned: Any                # plan.pipeline.PlannedFile
    total: int                  # units of the whole job
    start: int                  # the first unit this run sends
    estimate_s: float           # the machine time of the run, from `start`
    unit: str                   # "commands" or "G-code lines"
    #: how a front end names the units and the estimate, on the machine's terms
    unit_long: str
    estimate_by: str            # "of machine time", "on GRBL (its planner's estimate)"
    engine: Any = None          # the kind's own job object (JobStreamer, grbl.job.GrblJob)
    config: MachineConfig | None = None     # what it was planned for

    @property
    def remaining(self) -> int:
        return self.total - self.start

    @property
    def source(self) -> str:
        return self.planned.program.source

    def estimate_line(self) -> str:
        """`120 commands, about 0:42 of machine time`."""
        return (f"{self.remaining} {self.unit}, about {duration_text(self.estimate_s)} "
                f"{self.estimate_by}")


@dataclass
class Resumption:
    """An interrupted job planned again, and where it goes on (`plan_resume`)."""

    job: MachineJob | None      # None: nothing is left to do (`why` says so)
    why: str                    # where it goes on, and why there
    home_first: bool = False    # a reset lost the position: homed before the lead-in
    unsure: int = 0             # confirmed units that may not have run (drawn again)
    z_needs_hand: bool = False  # home_first without a Z end stop: the user sets the pen
    nothing_left: str = ""      # job None: the machine's words for it
    lost: str = ""              # home_first: why the position was lost, for the user


class Machine:
    """The interface; backends/galileo.py and backends/grbl.py say what each does."""

    kind = ""
    link: Any = None
    port_name = ""
    simulated = False
    checks_jobs = False         # check_job: the job run through a check mode
    queues_jogs = False         # jogs queue up in the machine (cancel_jog drops them)
    preview_note = ""           # added to a preview's line (what the preview shows)
    runs_mill = False           # prepare_mill: runs a mill job's G-code (GRBL)

    # ---- connection ----------------------------------------------------------------
    def describe(self) -> str:
        """The connection line."""
        raise NotImplementedError

    @property
    def config(self) -> MachineConfig:
        """The machine configuration jobs are planned with."""
        raise NotImplementedError

    def check_profile(self) -> None:
        """GalileoError when no job may run here (a board built for another machine)."""

    def use_config(self, config: MachineConfig) -> None:
        """Jobs are planned with `config` from now on (a new feed rate)."""

    def session(self) -> ContextManager:
        """Held while a front end's command runs: a status poller waits meanwhile."""
        return nullcontext()

    def close(self) -> None:
        raise NotImplementedError

    # ---- state -------------------------------------------------------------------
    def view(self, timeout_s: float = 1.0) -> MachineView | None:
        """A fresh status, None when the machine did not answer."""
        raise NotImplementedError

    def poll(self) -> MachineView | None:
        """For a toolbar's thread while nothing else runs."""
        return self.view()

    def status_line(self, config: MachineConfig) -> str:
        raise NotImplementedError

    def after_command(self, view: MachineView | None) -> list[str]:
        """Lines to print after a command (an alarm, named once; the unlock hint)."""
        return []

    def stop_if_moving(self, view: MachineView | None, say: Callable[[str], None]) -> None:
        """After an interrupted command: never leave the head moving."""

    # ---- commands -----------------------------------------------------------------
    def home(self, say: Callable[[str], None]) -> None:
        raise NotImplementedError

    def unlock(self, say: Callable[[str], None]) -> None:
        raise NotImplementedError

    def jog(self, axis: int, distance_nm: int, feed_mm_s: float) -> None:
        """One jog along axis 0, 1, 2; GalileoError when the machine refuses it."""
        raise NotImplementedError

    def cancel_jog(self):
        """Stop jogging (the head decelerates); the status after it."""
        raise NotImplementedError

    def wait_still(self):
        """Wait until the head stands still (jogs run out); the status then."""
        raise NotImplementedError

    def set_origin(self) -> str:
        """Once the head stands still, make where it stands the work origin (X, Y and
        Z 0; Z 0 draws); a note for the user. GalileoError when the machine refuses it."""
        raise NotImplementedError

    def feed_refusal(self, config: MachineConfig, mm_s: float) -> str | None:
        """Why the machine cannot run at `mm_s`, or None."""
        raise NotImplementedError

    def set_feed(self, config: MachineConfig, mm_s: float) -> str:
        """Make `mm_s` the machine's feed; a note for the confirmation line."""
        raise NotImplementedError

    # ---- jobs ---------------------------------------------------------------------
    def prepare(self, planned, config: MachineConfig, timing=None,
                homed: bool = False) -> MachineJob:
        """The planned file made ready for this machine (estimated), from its first
        unit. `timing`: our firmware's JobTiming of it, or a callable giving it (work a
        machine of another kind does not need); `homed`: homed for it (home_for_job)."""
        raise NotImplementedError

    def home_for_job(self):
        """Home before a job, so that a reset mid-job can be resumed; the status."""
        raise NotImplementedError

    def check_job(self, job: MachineJob):
        """Run `job` through the machine's check mode (checks_jobs); a report with `ok`."""
        raise NotImplementedError

    def step_recorder(self):
        """What records the steps the machine reports for a job (`job_done` while the
        port is open, then `trace()` after close: a Trace, or None from a board that
        cannot report them; `source` names who reported them)."""
        raise NotImplementedError

    def run_job(self, job: MachineJob, operator: Operator) -> JobResult:
        """Stream `job`, journalled. A lost port raises transport.link.PortGone (the
        journal says `interrupted`: `resume` continues it)."""
        raise NotImplementedError

    def stop(self) -> None:
        """From another thread: stop the running job (the machine ramps down)."""
        raise NotImplementedError

    def pending(self, file: str | None = None):
        """The journal's entry of the interrupted job (of `file`), None when none."""
        raise NotImplementedError

    def plan_resume(self, entry, *, on_stage=None, plan=None, timing=None) -> Resumption:
        """The job of `entry` planned again and where it goes on; GalileoError when it
        cannot be resumed (the file changed, the machine moved)."""
        raise NotImplementedError

    def find_position(self, resumption: Resumption, operator: Operator) -> bool:
        """Find the resumed job's position again (home after a reset; GRBL: home or
        have the user re-zero); False when the user could not set it."""
        raise NotImplementedError

    def resume(self, resumption: Resumption, operator: Operator) -> JobResult | None:
        """The resumed job's position found again, then the rest run; None when the
        user could not set the position."""
        if not self.find_position(resumption, operator):
            return None
        return self.run_job(resumption.job, operator)

    # ---- mill jobs (plan/mill/'s G-code; docs/mill.md) --------------------------------
    def prepare_mill(self, program) -> MachineJob:
        """A mill job (grbl.mill_job.MillProgram) made ready for this machine; `run_job`
        streams it, and its M0 pauses come to the operator's `pen_change` as a
        grbl.mill_job.MillPause ("paused for a bit change: put in the 1.000 mm bit")."""
        raise NotImplementedError

    def pending_mill(self):
        """The interrupted mill job: (journal entry, MillProgram); GalileoError when none."""
        raise NotImplementedError

    def interrupted_mill(self):
        """pending_mill's pair, or None where there is no interrupted mill job (always on
        a machine that runs no G-code); GalileoError only when there is one that cannot
        be resumed (its G-code changed or is gone)."""
        return None

    def plan_mill_resume(self, pending) -> Resumption:
        """Where the interrupted mill job `pending` (pending_mill's) goes on; `resume`
        runs it."""
        raise NotImplementedError

    # ---- a command line -----------------------------------------------------------
    def send_line(self, text: str, say: Callable[[str], None]) -> bool:
        """One line typed for the machine (`$$`, `G0 X10`; backends/command_line.py),
        its reply said; True when the machine took it."""
        raise NotImplementedError

    def origin_after_home(self) -> str:
        """After a home: where the work origin is now (an origin the user set may be
        gone), for the user."""
        return ""
