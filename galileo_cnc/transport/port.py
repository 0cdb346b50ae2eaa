"""Opening ports: pyserial for everything (DESIGN.md §2, Transport).

Real ports by name (COMx, /dev/tty...), pseudo-terminals by path, and any
pyserial URL, including `sim://` for the built-in simulated machine
(galileo_cnc.sim.protocol_sim) and `simavr://` for the real firmware running in
simavr (galileo_cnc.simavr.protocol_simavr), which importing this module registers.
"""

from __future__ import annotations

import serial

from galileo_cnc.config.hardware import DEFAULT_BAUD

SIM_URL = "sim://"
SIMAVR_URL = "simavr://"
#: pyserial imports `<package>.protocol_<scheme>` from each of these for a URL.
HANDLER_PACKAGES = ("galileo_cnc.sim", "galileo_cnc.simavr")


def register_url_schemes() -> None:
    """Let `serial.serial_for_url` find `sim://` and `simavr://` (imported only when used)."""
    for package in HANDLER_PACKAGES:
        if package not in serial.protocol_handler_packages:
            serial.protocol_handler_packages.append(package)


register_url_schemes()


def is_simulated(url_or_name: str) -> bool:
    return url_or_name.lower().startswith(SIM_URL)


def with_sim_config(url_or_name: str, config_path) -> str:
    """`sim://` simulates the machine of the profile at `config_path` (if any)."""
    if config_path is None or not is_simulated(url_or_name) or "config=" in url_or_name:
        return url_or_name
    return url_or_name + ("&" if "?" in url_or_name else "?") + f"config={config_path}"


def open_port(url_or_name: str, baud: int = DEFAULT_BAUD, timeout: float | None = 1.0,
              **kwargs) -> serial.SerialBase:
    """Open a port by name, path or pyserial URL (`sim://[NAME][?speed=S&config=PATH]`)."""
    return serial.serial_for_url(url_or_name, baudrate=baud, timeout=timeout, **kwargs)
