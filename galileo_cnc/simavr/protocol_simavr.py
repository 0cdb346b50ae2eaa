"""pyserial URL handler for `simavr://`: the real firmware, running in simavr, as a port.

    simavr://[?elf=PATH&realtime=0|1&trace=0|1]

Opening the port starts the project's harness (galileo_cnc.simavr.board.SimulatedBoard,
docs/harness.md; found by $GALILEO_SIMAVR, PATH or the checkout) on the firmware ELF
(default: $GALILEO_FIRMWARE, else firmware/build-uno/galileo.elf of the checkout,
built by `make -C firmware`) and opens the pseudo-terminal its
UART0 is bridged to; closing the port stops the board. `realtime=1` (the default)
paces the simulated chip to wall time, as a board runs; `realtime=0` lets simavr
run as fast as it can. `trace=1` records the step and direction pins' edges
(`port.board.step_trace()`, readable after the port is closed: `plot --trace`).
Found by `serial.serial_for_url` once "galileo_cnc.simavr" is
in `serial.protocol_handler_packages` (galileo_cnc.transport.port adds it).
"""

from __future__ import annotations

import urllib.parse
from pathlib import Path

from serial.serialposix import Serial as PosixSerial
from serial.serialutil import SerialException

from galileo_cnc.simavr.board import (SimulatedBoard, SimulatedBoardError, firmware_missing_message,
                                      firmware_path, harness_available, harness_missing_message)

_FORM = "simavr://[?elf=PATH&realtime=0|1&trace=0|1]"


def parse_url(url: str) -> tuple[Path | None, bool, bool]:
    """(ELF, realtime, trace) from `simavr://[?elf=PATH&realtime=0|1&trace=0|1]`."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "simavr" or parts.netloc or parts.path:
        raise SerialException(f"expected a URL of the form {_FORM}, got {url!r}")
    elf, realtime, trace = firmware_path(), True, False
    for option, values in urllib.parse.parse_qs(parts.query, True).items():
        if option == "elf":
            elf = Path(values[0])
        elif option == "realtime" and values[0] in ("0", "1"):
            realtime = values[0] == "1"
        elif option == "trace" and values[0] in ("0", "1"):
            trace = values[0] == "1"
        else:
            raise SerialException(f"simavr://: bad option {option}={values[0]!r} "
                                  f"(expected {_FORM})")
    return elf, realtime, trace


class Serial(PosixSerial):
    """A pseudo-terminal to a `SimulatedBoard` that lives as long as the port is open."""

    def __init__(self, *args, **kwargs):
        self.board: SimulatedBoard | None = None
        super().__init__(*args, **kwargs)

    def open(self):
        url = self._port
        elf, realtime, trace = parse_url(url)
        if elf is None:        # say what else is missing too, so one look fixes both
            harness = "" if harness_available() else f"; and {harness_missing_message()}"
            raise SerialException(f"simavr://: {firmware_missing_message()}{harness}")
        if not elf.is_file():
            raise SerialException(f"simavr://: no firmware at {elf}: build it with "
                                  f"`make -C firmware` (in a checkout) or pass ?elf=PATH")
        try:
            self.board = SimulatedBoard(elf, trace=trace, realtime=realtime).start()
        except SimulatedBoardError as exc:
            raise SerialException(f"simavr://: {exc}") from exc
        self._port = self.portstr = self.board.port   # the pty the harness bridges UART0 to
        try:
            super().open()
        except BaseException:
            self._stop_board()
            raise

    def close(self):
        super().close()
        self._stop_board()

    def _stop_board(self) -> None:
        if self.board is not None:
            self.board.close()
            self.board = None
