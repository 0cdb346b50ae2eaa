"""Opening ports: pyserial for everything (DESIGN.md §2, Transport).

Real ports by name (COMx, /dev/tty...), pseudo-terminals by path, and any
pyserial URL, including `sim://` for the built-in simulated machine
(galileo_cnc.sim.protocol_sim) and `simavr://` for the real firmware running in
simavr (galileo_cnc.simavr.protocol_simavr), which importing this module registers.
"""

from __future__ import annotations

import errno
import os
import re

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


def is_pseudo_terminal(device: str) -> bool:
    """A pty (socat, a simulator, a serial-over-network bridge): it has no DTR line, so
    opening it resets nothing and there is no boot loader to wait out."""
    try:
        return os.path.realpath(device).startswith("/dev/pts/")
    except (OSError, ValueError):
        return False


def with_sim_config(url_or_name: str, config_path) -> str:
    """`sim://` simulates the machine of the profile at `config_path` (if any)."""
    if config_path is None or not is_simulated(url_or_name) or "config=" in url_or_name:
        return url_or_name
    return url_or_name + ("&" if "?" in url_or_name else "?") + f"config={config_path}"


def with_step_trace(url_or_name: str) -> str:
    """`simavr://` recording its step pins, for a trace of what the firmware stepped
    (sim:// always knows its steps; a board cannot report them)."""
    if not url_or_name.lower().startswith(SIMAVR_URL) or "trace=" in url_or_name:
        return url_or_name
    return url_or_name + ("&" if "?" in url_or_name else "?") + "trace=1"


def port_error_text(error: BaseException) -> str:
    """What went wrong with a port, in the user's words rather than pyserial's
    ('[Errno 2] could not open port /dev/x: [Errno 2] No such file or directory: ...')."""
    errno_ = getattr(error, "errno", None)
    text = str(error)
    if errno_ == errno.ENOENT or "No such file" in text:
        return "no such port (the ports command lists the ports there are)"
    if errno_ in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return ("permission denied: add yourself to the dialout group "
                "(sudo usermod -aG dialout $USER, then log in again)")
    if errno_ == errno.EBUSY or "busy" in text.lower():
        return "the port is busy: another program has it open"
    if errno_ == errno.EIO or "returned no data" in text or "Input/output error" in text:
        return "the device stopped answering (unplugged or reset?)"
    # pyserial wraps the OS's words: keep the innermost, without "[Errno N]"
    inner = re.sub(r"\[Errno \d+\] ", "", text).split(": ")
    return inner[-1] if len(inner) > 1 and not text.startswith(("sim", "simavr")) else text


def open_port(url_or_name: str, baud: int = DEFAULT_BAUD, timeout: float | None = 1.0,
              **kwargs) -> serial.SerialBase:
    """Open a port by name, path or pyserial URL (`sim://[NAME][?speed=S&config=PATH]`)."""
    return serial.serial_for_url(url_or_name, baudrate=baud, timeout=timeout, **kwargs)
