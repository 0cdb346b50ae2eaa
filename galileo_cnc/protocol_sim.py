"""pyserial URL handler for `sim://`: the built-in simulated machine as a port.

Found by `serial.serial_for_url("sim://...")` once "galileo_cnc" is in
`serial.protocol_handler_packages` (galileo_cnc.transport adds it). Options in
the query: `config=PATH` (a machine profile TOML). Every open is a power-on:
a fresh machine that sends its banner, as the firmware does after reset.
"""

from __future__ import annotations

import numbers
import threading
import time
import urllib.parse

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from .config import load_config
from .simulator import SimulatedMachine


class Serial(SerialBase):
    """A pyserial port whose other end is `SimulatedMachine`."""

    BAUDRATES = (9600, 19200, 38400, 57600, 115200, 230400)

    def __init__(self, *args, **kwargs):
        self._rx = bytearray()
        self._rx_cond = threading.Condition()
        self._cancel = False
        self.machine: SimulatedMachine | None = None
        super().__init__(*args, **kwargs)

    # ---- open / close -------------------------------------------------------------
    def open(self):
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        config = self.from_url(self.port)
        self._reconfigure_port()
        with self._rx_cond:
            self._rx.clear()
        self.machine = SimulatedMachine(config, self._deliver)
        self.is_open = True
        self.machine.reset()                # the banner, as after a reset

    def close(self):
        if self.is_open:
            self.is_open = False
            with self._rx_cond:
                self._rx_cond.notify_all()
        super().close()

    def from_url(self, url):
        parts = urllib.parse.urlsplit(url)
        if parts.scheme != "sim":
            raise SerialException(f"expected a URL of the form sim://[?config=PATH], got {url!r}")
        config_path = None
        for option, values in urllib.parse.parse_qs(parts.query, True).items():
            if option == "config":
                config_path = values[0]
            else:
                raise SerialException(f"sim://: unknown option {option!r} (known: config)")
        try:
            return load_config(config_path)
        except Exception as exc:    # a bad profile is a port that cannot be opened
            raise SerialException(f"sim://: {exc}") from exc

    def _reconfigure_port(self):
        if not isinstance(self._baudrate, numbers.Integral) or not 0 < self._baudrate < 2 ** 32:
            raise ValueError(f"invalid baudrate: {self._baudrate!r}")

    # ---- data ---------------------------------------------------------------------
    def _deliver(self, data: bytes) -> None:
        with self._rx_cond:
            self._rx.extend(data)
            self._rx_cond.notify_all()

    @property
    def in_waiting(self):
        if not self.is_open:
            raise PortNotOpenError()
        with self._rx_cond:
            return len(self._rx)

    def read(self, size=1):
        if not self.is_open:
            raise PortNotOpenError()
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        with self._rx_cond:
            self._cancel = False
            while len(self._rx) < size and self.is_open and not self._cancel:
                if deadline is None:
                    self._rx_cond.wait()
                else:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        break
                    self._rx_cond.wait(left)
            data = bytes(self._rx[:size])
            del self._rx[:size]
            return data

    def write(self, data):
        if not self.is_open:
            raise PortNotOpenError()
        data = to_bytes(data)
        self.machine.receive(data)
        return len(data)

    def cancel_read(self):
        with self._rx_cond:
            self._cancel = True
            self._rx_cond.notify_all()

    def cancel_write(self):
        pass

    def flush(self):
        pass

    def reset_input_buffer(self):
        if not self.is_open:
            raise PortNotOpenError()
        with self._rx_cond:
            self._rx.clear()

    def reset_output_buffer(self):
        if not self.is_open:
            raise PortNotOpenError()

    @property
    def out_waiting(self):
        return 0

    # ---- modem lines (nothing to do) -------------------------------------------------
    def _update_break_state(self):
        pass

    def _update_rts_state(self):
        pass

    def _update_dtr_state(self):
        pass

    @property
    def cts(self):
        return True

    @property
    def dsr(self):
        return True

    @property
    def ri(self):
        return False

    @property
    def cd(self):
        return True

    # ---- for tests and the preview -----------------------------------------------------
    def trace(self):
        """The step trace the simulated machine has executed since the port opened."""
        return self.machine.trace()
