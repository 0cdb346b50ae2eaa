"""Finding the plotter: which serial ports there are and which one is ours.

With no `--port`, the console and `plot` look for a known board by its USB
VID:PID (Arduino, CH340, FTDI, CP210x and Intel Galileo bridges), then for any
other USB serial port that answers with our banner (plain UARTs such as ttyS0
are never probed: name them with --port), and fall back to the built-in simulated
machine `sim://`, saying so on the connection line.

`identify_board` also recognises a stock GRBL 1.1 board by its banner
(`Grbl 1.1h ['$' for help]`), or, when it stayed silent, by its `error:N`
reply to our version request and its `[VER:...]` reply to `$I`; `open_board`
says which backend a port needs and leaves it open for that link (docs/grbl.md).
"""

from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass

import serial
from serial.tools import list_ports as pyserial_list_ports

from galileo_cnc import protocol as P
from galileo_cnc.config.hardware import BANNER_WAIT_S, DEFAULT_BAUD
from galileo_cnc.transport.port import SIM_URL, SIMAVR_URL, is_pseudo_terminal, open_port

#: USB bridges found on Arduino-class boards (VID, PID) -> what they usually are.
KNOWN_BOARDS = {
    (0x2341, 0x0043): "Arduino Uno",
    (0x2341, 0x0001): "Arduino Uno",
    (0x2341, 0x0243): "Arduino Uno R3",
    (0x2A03, 0x0043): "Arduino Uno (arduino.org)",
    (0x2341, 0x0042): "Arduino Mega 2560",
    (0x1A86, 0x7523): "CH340 USB-serial (Uno clone)",
    (0x0403, 0x6001): "FTDI FT232 USB-serial",
    (0x10C4, 0xEA60): "CP210x USB-serial",
    (0x8086, 0xBABE): "Intel Galileo",
}

#: What `identify_board` finds on a port.
GALILEO = "galileo"
GRBL = "grbl"

#: Stock GRBL's start-up banner (grbl.h GRBL_VERSION, report.c); galileo_cnc.grbl
#: reads it from here, so the transport stage never imports the GRBL backend.
GRBL_BANNER = re.compile(r"^Grbl (?P<version>\d+\.\d+[a-z]?) \['\$' for help\]$")


def grbl_banner_version(line: str) -> str | None:
    """'1.1h' for GRBL's start-up banner, else None."""
    match = GRBL_BANNER.match(line.strip())
    return match["version"] if match else None

#: Set to skip probing real ports (tests, machines with unrelated serial devices).
NO_PROBE_ENV = "GALILEO_CNC_NO_PROBE"


@dataclass(frozen=True, slots=True)
class PortInfo:
    device: str
    description: str
    known_board: bool
    usb: bool = False


def list_ports() -> list[PortInfo]:
    """The serial ports pyserial sees, known boards first."""
    found = []
    for port in pyserial_list_ports.comports():
        board = KNOWN_BOARDS.get((port.vid, port.pid)) if port.vid is not None else None
        description = board or (port.description if port.description != "n/a" else "")
        found.append(PortInfo(port.device, description or "serial port", board is not None,
                              port.vid is not None))
    found.sort(key=lambda p: (not p.known_board, p.device))
    return found


def identify_board(device: str, baud: int, wait_s: float = BANNER_WAIT_S) -> str | None:
    """GALILEO for our firmware, GRBL for stock GRBL 1.1, None for anything else."""
    try:
        port, kind = open_identified(device, baud, wait_s)
    except (serial.SerialException, OSError, ValueError):
        return None
    port.close()
    return kind


def open_identified(device: str, baud: int, wait_s: float = BANNER_WAIT_S
                    ) -> tuple[serial.SerialBase, str | None]:
    """`device` opened once and who answers on it (GALILEO, GRBL or None). The caller
    keeps the open port for its link: an Uno resets when its port is opened (2.5 s
    and a lost position), so probing and then opening again would reset it twice.
    Opening errors propagate."""
    port = open_port(device, baud, timeout=0.2)
    try:
        return port, _identify(port, wait_s, booting=not is_pseudo_terminal(device))
    except BaseException:
        port.close()
        raise


def _identify(port, wait_s: float, booting: bool = True) -> str | None:
    """Who answers: a banner, else our `V` (asked once a board reset by the opening
    has had half the wait to boot; at once where nothing booted), else GRBL's `?`."""
    deadline = time.monotonic() + wait_s
    ask_at = deadline - wait_s / 2 if booting else time.monotonic()
    asked = status_asked = False
    while time.monotonic() < deadline:
        line = port.readline()
        if line.endswith(b"\n"):
            if _carries_banner(line):
                return GALILEO
            text = line.decode("ascii", errors="replace").strip()
            if grbl_banner_version(text):
                return GRBL
            # GRBL answers our framed `V` with error:N; `$I` then says who it is
            if asked and text.startswith("error:") and text[6:].isdigit():
                port.write(b"$I\n")
            if text.startswith("[VER:1.1") or _is_grbl_status(text):
                return GRBL
        elif not line and not asked and time.monotonic() >= ask_at:
            port.write(P.frame_line(0, "V"))
            asked = True
        elif not line and asked and not status_asked and time.monotonic() > deadline - wait_s / 4:
            # no answer to `V` either: a GRBL in a feed hold reads no line until it is
            # resumed, but answers its real-time `?` (ours would have answered `V`)
            port.write(b"?")
            status_asked = True
    return None


def _is_grbl_status(text: str) -> bool:
    """A GRBL 1.1 status report: `<Hold:0|MPos:1.000,2.000,0.000|...>`."""
    return (text.startswith("<") and text.endswith(">")
            and ("|MPos:" in text or "|WPos:" in text))


def open_board(port: str | None, baud: int = DEFAULT_BAUD
               ) -> tuple[str, str, serial.SerialBase | None]:
    """(device, GALILEO or GRBL, its port left open or None): where `plot` and the
    console go for `port`. None: the first board that answers, GRBL or ours, else
    `sim://`; `sim://` and `simavr://` are never probed (`simavr://?firmware=grbl` is
    GRBL); any other port is asked who answers, and what is not GRBL goes to our link
    (whose own open or greeting says what is wrong with it)."""
    if port is None:
        return find_open_board(baud)
    if port.startswith(SIMAVR_URL) and "firmware=grbl" in port:
        return port, GRBL, None
    if port.startswith((SIM_URL, SIMAVR_URL)):
        return port, GALILEO, None
    try:
        handle, kind = open_identified(port, baud)
    except (serial.SerialException, OSError, ValueError):
        return port, GALILEO, None
    return port, (GRBL if kind == GRBL else GALILEO), handle


def find_open_board(baud: int = DEFAULT_BAUD) -> tuple[str, str, serial.SerialBase | None]:
    """(port, GALILEO or GRBL, the port left open for the link): a known board,
    else a USB port that answers, else (`sim://`, GALILEO, None). See
    `open_identified` for why the port stays open."""
    if os.environ.get(NO_PROBE_ENV):
        return SIM_URL, GALILEO, None
    for port in _candidates():
        try:
            handle, kind = open_identified(port.device, baud)
        except (serial.SerialException, OSError, ValueError):
            continue
        if kind is not None:
            return port.device, kind, handle
        handle.close()
    return SIM_URL, GALILEO, None


def _carries_banner(line: bytes) -> bool:
    try:
        return P.parse_reply(line).banner is not None
    except P.ProtocolError:
        return False


def find_port(baud: int = DEFAULT_BAUD) -> str:
    """A known board with our firmware, else another USB port answering with our
    banner, else `sim://`."""
    if os.environ.get(NO_PROBE_ENV):
        return SIM_URL
    for port in _candidates():
        if identify_board(port.device, baud) == GALILEO:
            return port.device
    return SIM_URL


def _candidates() -> list[PortInfo]:
    """The ports worth probing, known boards first; plain UARTs (ttyS*) need --port."""
    ports = list_ports()
    return [p for p in ports if p.known_board] + \
        [p for p in ports if p.usb and not p.known_board]
