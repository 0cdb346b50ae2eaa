"""Small machine commands: status, ports, connect, home, unlock (what differs
between our firmware and GRBL lives in the Machine, backends/)."""

from __future__ import annotations

from galileo_cnc.transport.discovery import list_ports


def status(console, arguments: list[str]) -> None:
    console.say(console.machine.status_line(console.config))


def ports(console, arguments: list[str]) -> None:
    found = list_ports()
    current = console.machine.port_name if console.machine else None
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
    console.machine.home(console.say)


def unlock(console, arguments: list[str]) -> None:
    console.machine.unlock(console.say)
