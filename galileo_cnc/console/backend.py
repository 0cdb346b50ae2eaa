"""What the console's commands need from a machine, whichever firmware it runs.

Two implementations: `galileo_backend.GalileoBackend` (our firmware, `sim://` and
`simavr://`, over transport.link.MachineLink) and `grbl_backend.GrblBackend` (a
stock GRBL 1.1 board, over grbl.link.GrblLink). `open_backend` asks the port who
answers (discovery.open_board, as `plot` does) and opens the right one. Commands call the backend for
everything that differs between the two, never `if grbl:` themselves; a command
that makes no sense on a backend is refused once, by `unsupported`.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any, ContextManager


from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.transport.discovery import GALILEO, GRBL, open_board


@dataclass(frozen=True, slots=True)
class MachineView:
    """A status report as the console shows it (toolbar, alarm check)."""

    state: str                  # as the toolbar shows it: "idle", "GRBL Idle"
    where: str                  # "X 0.000  Y 0.000  Z 0.000 mm"
    alarm: bool = False         # locked: the console names it after a command
    moving: bool = False        # a command interrupted there must stop the head
    raw: Any = None             # the backend's own status


class Backend:
    """The interface; see the two implementations for what each method does there."""

    kind = ""
    link: Any = None
    port_name = ""
    simulated = False

    # ---- connection ----------------------------------------------------------------
    def describe(self) -> str:
        """The connection line."""
        raise NotImplementedError

    def after_connect(self, console) -> None:
        """Whatever a fresh connection needs (our firmware: the console's feed)."""

    def close(self) -> None:
        raise NotImplementedError

    def session(self) -> ContextManager:
        """Held while a command runs: the toolbar's poller waits meanwhile."""
        return nullcontext()

    def unsupported(self, command: str) -> str | None:
        """Why `command` cannot run on this machine, or None."""
        return None

    def use_config(self, config: MachineConfig) -> None:
        """The console plans with `config` from now on (a new feed rate)."""

    # ---- state -------------------------------------------------------------------
    def view(self, timeout_s: float = 1.0) -> MachineView | None:
        """A fresh status, None when the machine did not answer."""
        raise NotImplementedError

    def poll(self) -> MachineView | None:
        """For the toolbar's thread while the prompt waits."""
        return self.view()

    def after_command(self, view: MachineView | None) -> list[str]:
        """Lines to print after a command (an alarm, named once; the unlock hint)."""
        return []

    def status_line(self, config: MachineConfig) -> str:
        """The `status` command's line."""
        raise NotImplementedError

    def stop_if_moving(self, console, view: MachineView | None) -> None:
        """After an interrupted command: never leave the head moving."""

    # ---- commands -----------------------------------------------------------------
    def home(self, console) -> None:
        raise NotImplementedError

    def unlock(self, console) -> None:
        raise NotImplementedError

    def jog_with_keypad(self, console, units: int) -> None:
        raise NotImplementedError

    def feed_refusal(self, config: MachineConfig, mm_s: float) -> str | None:
        """Why the machine cannot run at `mm_s`, or None."""
        raise NotImplementedError

    def set_feed(self, console, mm_s: float) -> str:
        """Make `mm_s` the machine's feed; returns a note for the confirmation line."""
        raise NotImplementedError

    def check_before_planning(self, console) -> None:
        """Refuse (GalileoError) before reading a file when no job could run here."""

    def plot(self, console, planned, config: MachineConfig) -> None:
        """Stream a planned file (plan.pipeline.PlannedFile) with the progress bar."""
        raise NotImplementedError

    def resume(self, console) -> None:
        """Continue the job this machine's journal says was interrupted or stopped:
        our firmware's (console/resume.py) unless the backend keeps its own."""
        from galileo_cnc.console.resume import resume_job
        resume_job(console)


def open_backend(port: str | None, baud: int, config: MachineConfig, config_path=None,
                 profile: MachineConfig | None = None, on_message=None) -> Backend:
    """The backend for what answers on `port`; GalileoError (LinkError) when none."""
    found, kind, handle = open_board(port, baud)   # a probed port stays open: see there
    if kind == GRBL:
        from galileo_cnc.console.grbl_backend import GrblBackend
        return GrblBackend.open(found, baud, config, config_path, profile, handle=handle)
    from galileo_cnc.console.galileo_backend import GalileoBackend
    return GalileoBackend.open(found, baud, config, config_path, profile, on_message,
                               handle=handle)


__all__ = ["Backend", "MachineView", "open_backend", "GALILEO", "GRBL"]
