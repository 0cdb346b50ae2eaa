"""pyserial URL handler for `sim://`: the built-in simulated machine as a port.

Found by `serial.serial_for_url("sim://...")` once "galileo_cnc" is in
`serial.protocol_handler_packages` (galileo_cnc.transport adds it).

    sim://[NAME][?speed=S&config=PATH]

`speed` is how many times faster than real time the machine runs (default 1;
0 = instant: every move is done when its `ok` goes out); `config` a machine
profile TOML. Plain `sim://` is a power-on at every open: a fresh machine that
sends its banner, as the firmware does after reset. `sim://NAME` is a machine
that keeps power in this process while the port is closed, as a board whose USB
cable is pulled: it goes on executing its queue, and opening it again neither
resets it nor sends a banner (galileo_cnc.simulator.named_machine,
forget_named_machines).
"""

from __future__ import annotations

import math
import numbers
import re
import threading
import time
import urllib.parse

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from galileo_cnc.config.hardware import BAUD_RATES
from galileo_cnc.config.machine import load_config
from galileo_cnc.sim.simulator import SimulatedMachine, open_named_machine

_NAME_RE = re.compile(r"[A-Za-z0-9_.-]+")
_FORM = "sim://[NAME][?speed=S&config=PATH]"


class Serial(SerialBase):
    """A pyserial port whose other end is `SimulatedMachine`."""

    BAUDRATES = BAUD_RATES

    def __init__(self, *args, **kwargs):
        self._rx = bytearray()
        self._rx_cond = threading.Condition()
        self._cancel = False
        self.machine: SimulatedMachine | None = None
        self._named = False
        super().__init__(*args, **kwargs)

    # ---- open / close -------------------------------------------------------------
    def open(self):
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        name, config, speed = self.from_url(self.port)
        self._reconfigure_port()
        with self._rx_cond:
            self._rx.clear()
        if name:
            try:
                machine, powered_on = open_named_machine(name, config, speed)
            except ValueError as exc:
                raise SerialException(str(exc)) from exc
            if not machine.attach(self._deliver):
                raise SerialException(f"sim://{name} is already open")
        else:
            machine, powered_on = SimulatedMachine(config, self._deliver, speed), True
        self.machine, self._named = machine, bool(name)
        self.is_open = True
        if powered_on:
            machine.reset()                 # the banner, as after a reset

    def close(self):
        if self.is_open:
            self.is_open = False
            if self._named:
                self.machine.detach()       # the cable is pulled: the board runs on
            else:
                self.machine.close()        # power off
            with self._rx_cond:
                self._rx_cond.notify_all()
        super().close()

    def from_url(self, url):
        """(name, config, speed) from `sim://[NAME][?speed=S&config=PATH]`."""
        parts = urllib.parse.urlsplit(url)
        if parts.scheme != "sim" or parts.path or (
                parts.netloc and not _NAME_RE.fullmatch(parts.netloc)):
            raise SerialException(f"expected a URL of the form {_FORM}, got {url!r}")
        config_path, speed = None, 1.0
        for option, values in urllib.parse.parse_qs(parts.query, True).items():
            if option == "config":
                config_path = values[0]
            elif option == "speed":
                try:
                    speed = float(values[0])
                except ValueError:
                    speed = -1.0
                if not (math.isfinite(speed) and speed >= 0):
                    raise SerialException(f"sim://: speed must be a number >= 0, "
                                          f"got {values[0]!r}")
            else:
                raise SerialException(f"sim://: unknown option {option!r} "
                                      f"(known: speed, config)")
        try:
            config = load_config(config_path)
        except Exception as exc:    # a bad profile is a port that cannot be opened
            raise SerialException(f"sim://: {exc}") from exc
        return parts.netloc, config, speed

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
        """The step trace the simulated machine has executed since it powered on."""
        return self.machine.trace()
