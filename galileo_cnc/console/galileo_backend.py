"""The console on galileo-cnc firmware (a board, `sim://`, `simavr://`): MachineLink.

What the commands did before GRBL came: the link is thread-safe (its own reader
thread), jobs stream through stream.streamer.JobStreamer and are journalled, so
`resume` can continue them.
"""

from __future__ import annotations

from galileo_cnc.config.machine import MIN_FEED_STEPS_PER_S, MachineConfig
from galileo_cnc.console.backend import Backend, MachineView
from galileo_cnc.console.job_screen import JobScreen, report
from galileo_cnc.console.keypad import jog_with_keypad
from galileo_cnc.console.units import position_mm_text
from galileo_cnc.job import Home, SetFeed
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.protocol import Unlock
from galileo_cnc.stream.journal import Journal
from galileo_cnc.stream.streamer import JobStreamer
from galileo_cnc.transport.link import LinkError, MachineLink

#: States in which the head may be moving: a command interrupted there must stop it.
MOVING_STATES = ("run", "hold", "homing")


class GalileoBackend(Backend):
    kind = "galileo"

    def __init__(self, link: MachineLink):
        self.link = link

    @classmethod
    def open(cls, port: str | None, baud: int, config: MachineConfig, config_path=None,
             profile: MachineConfig | None = None, on_message=None,
             handle=None) -> "GalileoBackend":
        """`handle`: the port already open and probed (discovery.open_board)."""
        link = (MachineLink.attach(handle, port, baud, config, config_path, profile=profile,
                                   booted=True) if handle is not None else
                MachineLink.open(port, baud, config, config_path, profile=profile))
        link.on_message = on_message
        return cls(link)

    @property
    def port_name(self) -> str:
        return self.link.port_name

    @property
    def simulated(self) -> bool:
        return self.link.simulated

    def describe(self) -> str:
        return self.link.describe()

    def after_connect(self, console) -> None:
        try:  # the machine starts with its own default feed; make it ours
            self.link.send(SetFeed(console.config.feed_steps_per_s))
        except LinkError as error:
            console.say(f"could not set the feed rate: {error}")

    def close(self) -> None:
        self.link.close()

    def use_config(self, config: MachineConfig) -> None:
        self.link.config = config               # the journal keeps the link's copy

    # ---- state -------------------------------------------------------------------
    def view(self, timeout_s: float = 1.0) -> MachineView | None:
        try:
            status = self.link.status(timeout_s=timeout_s)
        except LinkError:
            return None
        return MachineView(status.state, position_mm_text(status, self.link.config),
                           alarm=status.state == "alarm",
                           moving=status.state in MOVING_STATES, raw=status)

    def after_command(self, view: MachineView | None) -> list[str]:
        if view is not None and view.alarm:
            return ["the machine is locked (alarm): check it, then type unlock"]
        return []

    def status_line(self, config: MachineConfig) -> str:
        state = self.link.status()
        return (f"state {state.state}, {position_mm_text(state, config)} "
                f"(steps X {state.x_steps} Y {state.y_steps} Z {state.z_steps}), "
                f"queue {state.queue_blocks}, feed {config.feed_mm_s:g} mm/s")

    def stop_if_moving(self, console, view: MachineView | None) -> None:
        if view is not None and view.moving:
            console.say("stopping the machine (ramping down)")
            self.link.abort()

    # ---- commands -----------------------------------------------------------------
    def home(self, console) -> None:
        console.say("homing...")
        self.link.send(Home())
        state = self.link.wait_idle()
        console.say(f"homed: {position_mm_text(state, console.config)}")

    def unlock(self, console) -> None:
        alarm = self.link.take_alarm()
        self.link.send_protocol(Unlock())
        state = self.link.status()
        cause = f" (it was alarm:{alarm.code} {alarm.text})" if alarm else ""
        console.say(f"unlocked{cause}: state {state.state}, "
                    f"{position_mm_text(state, console.config)}")

    def jog_with_keypad(self, console, units: int) -> None:
        jog_with_keypad(console, units)

    def feed_refusal(self, config: MachineConfig, mm_s: float) -> str | None:
        steps_per_s = config.feed_steps_per_s_of(mm_s)
        if MIN_FEED_STEPS_PER_S <= steps_per_s <= config.max_feed_steps_per_s:
            return None
        lowest = MIN_FEED_STEPS_PER_S / config.steps_per_mm
        highest = config.max_feed_steps_per_s / config.steps_per_mm
        return f"refused: the machine runs {lowest:g} .. {highest:g} mm/s"

    def set_feed(self, console, mm_s: float) -> str:
        self.link.send(SetFeed(console.config.feed_steps_per_s_of(mm_s)))
        return ""

    def check_before_planning(self, console) -> None:
        self.link.check_config()        # a board built for another machine: say so first

    def plot(self, console, planned, config: MachineConfig) -> None:
        job, program = planned.job, planned.plotted
        timing = console.plans.timing(job, console.config)   # kept: getg again, resume
        pens = len(job.pen_changes)
        console.say(f"{len(job)} machine commands, {pens} pen change{'s' * (pens != 1)}, "
                    f"estimated time {duration_text(timing.total_s)}")
        streamer = JobStreamer(self.link, job, program, journal=Journal.default(),
                               timing=timing)
        result = JobScreen(console, program.source, len(job)).run(streamer.run,
                                                                  streamer.abort)
        report(console, result)
