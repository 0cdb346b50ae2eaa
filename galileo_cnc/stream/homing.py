"""Homing: the frame a reset cannot take away (`plot --home`, and `--resume` after a reset).

A reset restarts the machine's position at 0 wherever the head stands, so a job's
frame survives a reset only if it can be found again: the end stops. `plot --home`
homes before the job (Home: Z first when it has an end stop, then X, then Y; each
homed axis's position and origin become 0 at its switch), so the job's work
coordinates are machine coordinates from the switches, and homing again after a reset
puts them back exactly.

Z without an end stop keeps the origin the user set (the pen heights count from it):
after a reset the pen's height is known only once the pen stands at that origin
again, so the user puts it there and Z 0 is set where it stands before homing.
"""

from __future__ import annotations

from galileo_cnc import protocol as P
from galileo_cnc.config.machine import NO_PIN, MachineConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import Home, PenUp, SetOrigin
from galileo_cnc.transport.link import MachineLink


class HomingError(GalileoError):
    """The machine cannot be homed (no end stops for X and Y)."""


def check_homeable(config: MachineConfig) -> None:
    """HomingError unless the profile has end-stop pins for X and Y (before anything moves)."""
    missing = [axis for axis, pin in (("X", config.x_home_pin), ("Y", config.y_home_pin))
               if pin == NO_PIN]
    if missing:
        raise HomingError(f"--home: the profile has no end-stop pin for {' and '.join(missing)} "
                          f"(x_home_pin, y_home_pin in [machine]): this machine cannot be "
                          f"homed, so a job's frame cannot be found again after a reset")


def z_has_end_stop(config: MachineConfig) -> bool:
    return config.z_home_pin != NO_PIN


def home(link: MachineLink) -> P.Status:
    """Home every axis with an end stop and wait until it is done; MachineAlarm when a
    switch is not found (or already pressed). Z without an end stop lifts the pen
    first: X and Y must not drag it over the paper."""
    if not z_has_end_stop(link.config):
        link.send(PenUp())
    link.send(Home())
    return link.wait_idle()


def home_after_reset(link: MachineLink) -> P.Status:
    """Find a homed job's frame again after a reset. Z without an end stop: the pen
    stands at its Z origin (the user put it there), so Z 0 is set here first; homing
    then sets X and Y (their origins become 0 at the switches, as when the job began)."""
    check_homeable(link.config)
    if not z_has_end_stop(link.config):
        link.send(SetOrigin())
    return home(link)
