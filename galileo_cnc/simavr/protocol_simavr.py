"""pyserial URL handler for `simavr://`: a real firmware, running in simavr, as a port.

    simavr://[?firmware=galileo|grbl&elf=PATH&config=PATH&realtime=0|1&trace=0|1&probe=SURFACE&$N=VALUE...]

Opening the port starts the project's harness (galileo_cnc.simavr.board.SimulatedBoard,
docs/harness.md; found by $GALILEO_SIMAVR, PATH or the checkout) on a firmware ELF and
opens the pseudo-terminal its UART0 is bridged to; closing the port stops the board.

- `firmware=galileo` (the default): our firmware, $GALILEO_FIRMWARE, else
  firmware/build-uno/galileo.elf of the checkout (built by `make -C firmware`).
- `firmware=grbl`: stock GRBL 1.1h, built from third_party/grbl-1.1h (or
  $GALILEO_GRBL_SOURCE) with its own Makefile in a temporary folder and cached
  (galileo_cnc.simavr.grbl_firmware, docs/grbl.md), on GRBL's pins, with the harness's
  timer corrections. Its EEPROM starts empty (GRBL's defaults, 250 steps/mm):
  `$N=VALUE` options are GRBL settings written once GRBL has booted, before the port
  is handed over (then a soft reset, so the opener reads a fresh banner), as a user
  would have stored them in a real board's EEPROM:
  `simavr://?firmware=grbl&$100=160&$101=160&$102=160`.
- `probe=Z0[:AMP:PX:PY]` (GRBL): its probe pin (A5) touches a surface at Z0 GRBL
  machine steps from power-up (negative is down), waved by AMP sin(2 pi x/PX)
  sin(2 pi y/PY) over the X, Y steps: what G38.2 finds (docs/harness.md "Probe").
- `elf=PATH` runs that ELF instead (for either firmware).
- `config=PATH` (our firmware): a machine profile TOML whose home pins and
  `sim_x/y/z_endstop_steps` place the board's end-stops, as on `sim://`; without it
  the default profile's (X and Y switches 400 steps below where the board powers
  up), so `home` and `plot --home` find them.
- `realtime=1` (the default) paces the simulated chip to wall time, as a board runs;
  `realtime=0` lets simavr run as fast as it can (about 5x).
- `trace=1` records the step and direction pins' edges (`port.board.trace()`,
  readable after the port is closed: `plot --trace` on our firmware).

Found by `serial.serial_for_url` once "galileo_cnc.simavr" is in
`serial.protocol_handler_packages` (galileo_cnc.transport.port adds it).
"""

from __future__ import annotations

import re
import time
import urllib.parse
from dataclasses import dataclass
from pathlib import Path

from serial.serialposix import Serial as PosixSerial
from serial.serialutil import SerialException

from galileo_cnc.config.machine import NO_PIN, MachineConfig, load_config
from galileo_cnc.errors import GalileoError
from galileo_cnc.simavr.board import (SimulatedBoard, SimulatedBoardError, firmware_missing_message,
                                      firmware_path, harness_available, harness_missing_message)

_FORM = ("simavr://[?firmware=galileo|grbl&elf=PATH&config=PATH&realtime=0|1&trace=0|1"
         "&probe=Z0[:AMP:PX:PY]&$N=VALUE]")
GALILEO, GRBL = "galileo", "grbl"
_SETTING = re.compile(r"^\$(\d{1,3})$")
_NUMBER = re.compile(r"^-?\d+(\.\d+)?$")
#: How long GRBL may take to boot and answer a setting (wall time; it boots in ms).
GRBL_BOOT_TIMEOUT_S = 20.0


@dataclass(frozen=True)
class SimavrUrl:
    firmware: str = GALILEO
    elf: Path | None = None             # None: the firmware's default ELF
    realtime: bool = True
    trace: bool = False
    settings: tuple[tuple[int, str], ...] = ()     # GRBL's $N=VALUE, in URL order
    config: Path | None = None          # the profile placing our firmware's end-stops
    probe: object = None                # GRBL's ProbeSurface (grbl_firmware), or None


def parse_url(url: str) -> SimavrUrl:
    """The options of `simavr://[?...]`; SerialException naming a bad one."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "simavr" or parts.netloc or parts.path:
        raise SerialException(f"expected a URL of the form {_FORM}, got {url!r}")
    firmware, elf, realtime, trace, settings = GALILEO, None, True, False, []
    config = probe = None
    try:
        pairs = urllib.parse.parse_qsl(parts.query, keep_blank_values=True,
                                       strict_parsing=bool(parts.query))
    except ValueError:
        raise SerialException(f"simavr://: cannot read the options {parts.query!r} "
                              f"(expected {_FORM})") from None
    for option, value in pairs:
        setting = _SETTING.match(option)
        if option == "firmware" and value in (GALILEO, GRBL):
            firmware = value
        elif option == "elf" and value:
            elf = Path(value)
        elif option == "config" and value:
            config = Path(value)
        elif option == "realtime" and value in ("0", "1"):
            realtime = value == "1"
        elif option == "trace" and value in ("0", "1"):
            trace = value == "1"
        elif option == "probe" and value:
            from galileo_cnc.simavr.grbl_firmware import ProbeSurface
            try:
                probe = ProbeSurface.parse(value)
            except ValueError as exc:
                raise SerialException(f"simavr://: probe={value!r}: {exc}") from None
        elif setting and _NUMBER.match(value):
            settings.append((int(setting[1]), value))
        else:
            raise SerialException(f"simavr://: bad option {option}={value!r} "
                                  f"(expected {_FORM})")
    if settings and firmware != GRBL:
        raise SerialException(f"simavr://: ${settings[0][0]}={settings[0][1]} is a GRBL "
                              f"setting: add firmware=grbl")
    if config is not None and firmware != GALILEO:
        raise SerialException("simavr://: config= places our firmware's end-stops; GRBL's "
                              "limit switches come with firmware=grbl")
    if probe is not None and firmware != GRBL:
        raise SerialException("simavr://: probe= is GRBL's probe pin (A5): add firmware=grbl")
    return SimavrUrl(firmware, elf, realtime, trace, tuple(settings), config, probe)


def endstops(config: MachineConfig) -> list[tuple[str, int, int]]:
    """The harness's end-stops for a profile: each axis with a home pin closes its
    switch at the profile's sim_*_endstop_steps from power-up, as sim:// does."""
    return [(axis, pin, trip) for axis, pin, trip in
            zip("XYZ", config.home_pins, config.sim_endstop_steps) if pin != NO_PIN]


def _board_for(options: SimavrUrl) -> SimulatedBoard:
    """The (not yet started) board the URL asks for; SerialException saying what is
    missing and which Debian package or make command provides it."""
    if options.firmware == GRBL:
        from galileo_cnc.simavr import grbl_firmware
        if not harness_available():
            raise SerialException(f"simavr://: {harness_missing_message()}")
        elf = options.elf
        if elf is None:
            try:
                elf = grbl_firmware.build_grbl()
            except GalileoError as exc:
                raise SerialException(f"simavr://?firmware=grbl: {exc}") from None
        elif not elf.is_file():
            raise SerialException(f"simavr://: no GRBL firmware at {elf} (leave out elf= "
                                  f"to build GRBL 1.1h from its source)")
        return grbl_firmware.grbl_board(elf, trace=options.trace, realtime=options.realtime,
                                        probe=options.probe)
    elf = options.elf if options.elf is not None else firmware_path()
    if elf is None:        # say what else is missing too, so one look fixes both
        harness = "" if harness_available() else f"; and {harness_missing_message()}"
        raise SerialException(f"simavr://: {firmware_missing_message()}{harness}")
    if not elf.is_file():
        raise SerialException(f"simavr://: no firmware at {elf}: build it with "
                              f"`make -C firmware` (in a checkout) or pass ?elf=PATH")
    try:
        config = load_config(options.config)
    except (OSError, GalileoError) as exc:
        raise SerialException(f"simavr://?config={options.config}: {exc}") from None
    return SimulatedBoard(elf, trace=options.trace, realtime=options.realtime,
                          endstops=endstops(config))


class Serial(PosixSerial):
    """A pseudo-terminal to a `SimulatedBoard` that lives as long as the port is open."""

    def __init__(self, *args, **kwargs):
        self.board: SimulatedBoard | None = None
        self.firmware: str | None = None
        super().__init__(*args, **kwargs)

    def open(self):
        options = parse_url(self._port)
        board = _board_for(options)
        try:
            self.board = board.start()
        except SimulatedBoardError as exc:
            raise SerialException(f"simavr://: {exc}") from exc
        self.firmware = options.firmware
        self._port = self.portstr = self.board.port   # the pty the harness bridges UART0 to
        try:
            super().open()
            if options.settings:
                self._write_grbl_settings(options.settings)
        except BaseException:
            self._stop_board()
            super().close()
            raise

    def _write_grbl_settings(self, settings) -> None:
        """GRBL's settings, written as a user would once (they land in the simulated
        EEPROM), then a soft reset: the opener reads a fresh banner, as on a board
        that resets on open."""
        timeout = self.timeout
        self.timeout = 0.2
        try:
            self._grbl_line(lambda line: line.startswith("Grbl "), "its banner")
            for number, value in settings:
                self.write(f"${number}={value}\n".encode("ascii"))
                reply = self._grbl_line(lambda line: line == "ok" or line.startswith("error:"),
                                        f"an answer to ${number}={value}")
                if reply != "ok":
                    raise SerialException(f"simavr://?firmware=grbl: GRBL refused "
                                          f"${number}={value}: {reply}")
            self.write(b"\x18")
        finally:
            self.timeout = timeout

    def _grbl_line(self, wanted, what: str) -> str:
        deadline = time.monotonic() + GRBL_BOOT_TIMEOUT_S
        partial = b""
        while time.monotonic() < deadline:
            partial += self.readline()
            if partial.endswith(b"\n"):
                line, partial = partial.decode("ascii", errors="replace").strip(), b""
                if wanted(line):
                    return line
        raise SerialException(f"simavr://?firmware=grbl: GRBL gave no {what} within "
                              f"{GRBL_BOOT_TIMEOUT_S:g} s")

    def close(self):
        super().close()
        self._stop_board()

    def _stop_board(self) -> None:
        if self.board is not None:
            self.board.close()
            self.board = None
