"""Small machine commands: status, ports, connect, home, unlock."""

from __future__ import annotations

from galileo_cnc.console.units import position_mm_text
from galileo_cnc.job import Home
from galileo_cnc.protocol import Unlock
from galileo_cnc.transport.discovery import list_ports


def status(console, arguments: list[str]) -> None:
    state = console.link.status()
    console.say(f"state {state.state}, {position_mm_text(state, console.config)} "
                f"(steps X {state.x_steps} Y {state.y_steps} Z {state.z_steps}), "
                f"queue {state.queue_blocks}, feed {console.config.feed_mm_s:g} mm/s")


def ports(console, arguments: list[str]) -> None:
    found = list_ports()
    current = console.link.port_name if console.link else None
    if not found:
        console.say("no serial ports found (sim:// is always there)")
    for port in found:
        mark = "*" if port.device == current else " "
        board = "  (known board)" if port.known_board else ""
        console.say(f"{mark} {port.device:<20} {port.description}{board}")
    if current and current not in {p.device for p in found}:
        console.say(f"* {current}")


def connect(console, arguments: list[str]) -> None:
    console.connect(arguments[0] if arguments else None)


def home(console, arguments: list[str]) -> None:
    console.say("homing...")
    console.link.send(Home())
    state = console.link.wait_idle()
    console.say(f"homed: {position_mm_text(state, console.config)}")


def unlock(console, arguments: list[str]) -> None:
    alarm = console.link.take_alarm()
    console.link.send_protocol(Unlock())
    state = console.link.status()
    cause = f" (it was alarm:{alarm.code} {alarm.text})" if alarm else ""
    console.say(f"unlocked{cause}: state {state.state}, "
                f"{position_mm_text(state, console.config)}")
