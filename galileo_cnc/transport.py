"""Opening ports: pyserial for everything (DESIGN.md §2, Transport).

Real ports by name (COMx, /dev/tty...), pseudo-terminals by path, and any
pyserial URL, including `sim://` for the built-in simulated machine
(galileo_cnc.protocol_sim) and `simavr://` for the real firmware running in
simavr (galileo_cnc.protocol_simavr), which importing this module registers.
"""

from __future__ import annotations

import serial


SIM_URL = "sim://"
SIMAVR_URL = "simavr://"      # the real firmware in simavr (galileo_cnc.protocol_simavr)
DEFAULT_BAUD = 115200


def register_sim_scheme() -> None:
    """Let `serial.serial_for_url("sim://...")` find galileo_cnc.protocol_sim."""
    if "galileo_cnc" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("galileo_cnc")


register_sim_scheme()


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
