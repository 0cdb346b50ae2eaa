"""Jogging, homing and unlocking a GRBL board (the console's `setup`, `home`, `unlock`).

A jog is `$J=G91 G21 X.. F..` (jogging.md): relative, in mm, whatever modes the
job left, and it changes no parser state. With soft limits on, GRBL refuses a
jog leaving the travel with error:15 instead of alarming; we check first, so
the user sees which axis and limit. The real-time 0x85 cancels a jog: GRBL
decelerates on the path, flushes the queued jogs and goes back to Idle.
"""

from __future__ import annotations

from galileo_cnc.grbl.link import JOG_CANCEL, GrblLink
from galileo_cnc.grbl.reports import GrblError, Status
from galileo_cnc.grbl.travel import AXES, TravelError, _mm

#: GRBL's error:15, "Travel exceeded": a jog target outside the soft limits.
JOG_TRAVEL_EXCEEDED = 15
MM = 1_000_000                  # nm

# The console's numeric keypad: 8/2 = Y+/-, 6/4 = X+/-, 7/1 = Z up/down.
KEYPAD = {"8": ("Y", 1), "2": ("Y", -1), "6": ("X", 1), "4": ("X", -1),
          "7": ("Z", 1), "1": ("Z", -1)}


class JogError(GrblError):
    """GRBL refused a jog, homing or unlock."""


def keypad_jog(key: str, step_mm: float) -> tuple[str, float] | None:
    """(axis, signed distance in mm) for a keypad key, None for any other key."""
    found = KEYPAD.get(key)
    return None if found is None else (found[0], found[1] * step_mm)


def jog_text(axis: str, distance_mm: float, feed_mm_min: float) -> str:
    # 4 decimals (0.1 um) is finer than any step; GRBL reads 8 digits at most
    return f"$J=G91 G21 {axis}{_decimal(distance_mm, 4)} F{_decimal(feed_mm_min, 1)}"


def _decimal(value: float, places: int) -> str:
    text = f"{value:.{places}f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def jog(link: GrblLink, axis: str, distance_mm: float, feed_mm_min: float, *,
        check_travel: bool = True) -> str:
    """Queues one jog and returns once GRBL has accepted it (the move runs on;
    `wait_jog` waits for its end, `cancel_jog` stops it). Returns the line sent."""
    axis = axis.upper()
    if axis not in AXES:
        raise ValueError(f"no axis {axis!r} on GRBL (X, Y or Z)")
    if feed_mm_min <= 0:
        raise ValueError(f"jog feed must be positive, got {feed_mm_min:g} mm/min")
    text = jog_text(axis, distance_mm, feed_mm_min)
    settings = link.settings
    if check_travel and settings is not None and settings.soft_limits:
        refusal = travel_refusal(link.status(), settings, axis, round(distance_mm * MM))
        if refusal is not None:
            raise TravelError(refusal)
    reply = link.command(text)
    if reply.ok:
        return text
    if reply.code == JOG_TRAVEL_EXCEEDED:
        raise JogError(f"GRBL refused the jog {text!r}: it would leave the soft limits "
                       f"({reply.text})", reply.code)
    raise JogError(f"GRBL refused the jog {text!r}: {reply.text}", reply.code)


def travel_refusal(status: Status, settings, axis: str, distance_nm: int) -> str | None:
    """Why GRBL would refuse a jog of `distance_nm` along `axis` (soft limits on), None
    if it would not. GRBL checks a jog's target only (jog_execute): a head outside the
    travel (a failed `$H`, ALARM:9, leaves it beyond the switch side) gets a jog only
    when it ends inside; the text says how far that is. Work coordinates first, as
    the jog line shows them, machine after."""
    a = AXES.index(axis)
    here = status.mpos_nm[a]
    target = here + distance_nm
    low = -settings.max_travel_nm(a)
    if low <= target <= 0:
        return None
    wco = status.mpos_nm[a] - status.wpos_nm[a]
    text = (f"jog refused: {axis} would go to {_mm(target - wco)} mm (work; machine "
            f"{_mm(target)} mm), outside GRBL's travel: work {_mm(low - wco)}..{_mm(-wco)} "
            f"mm, machine {_mm(low)}..0 mm (${130 + a}={settings[130 + a]})")
    if low <= here <= 0:
        return text
    edge = 0 if here > 0 else low
    return (f"{text}; {axis} stands outside it, and GRBL takes only a jog that ends "
            f"inside: jog {axis} by {_mm(edge - here)} mm or more in one jog, or home ($H) "
            f"once the switches work")


def wait_jog(link: GrblLink, max_reports: int = 100_000) -> Status:
    """Status reports until GRBL leaves Jog. Polling Idle is enough here, unlike
    for G-code (link.wait_idle): a jog is planned and started before its `ok`."""
    for _ in range(max_reports):
        status = link.status()
        if status.state not in ("Jog", "Hold"):     # Hold: a cancel still decelerating
            return status
    raise GrblError(f"GRBL still jogging after {max_reports} status reports")


def cancel_jog(link: GrblLink) -> Status:
    """0x85: GRBL decelerates to a stop on the path and drops the queued jogs;
    returns the status once it is back in Idle (no effect when not jogging)."""
    link.realtime(JOG_CANCEL)
    status = wait_jog(link)
    if status.state != "Idle":
        raise GrblError(f"GRBL is {status.state} after a jog cancel")
    return status


def home(link: GrblLink) -> Status:
    """`$H`: GRBL seeks its switches, pulls off, and sets machine zero there."""
    if link.settings is not None and not link.settings.homing:
        raise JogError("homing is off on this GRBL ($22=0): turn it on with $22=1 "
                       "once limit switches are fitted, or set work zero by hand")
    reply = link.command("$H")          # answered when the cycle is over (or ALARM:8/9)
    if not reply.ok:
        raise JogError(f"GRBL refused $H: {reply.text}", reply.code)
    return link.status()


def unlock(link: GrblLink) -> Status:
    """`$X`: leaves the alarm lock without homing; the position may be wrong."""
    reply = link.command("$X")
    if not reply.ok:
        raise JogError(f"GRBL refused $X: {reply.text}", reply.code)
    return link.status()
