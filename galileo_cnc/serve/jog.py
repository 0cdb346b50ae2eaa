"""A jog from the page: held (a button pressed: the head moves until it is let go, or
the page goes away) or a step of a distance; the stop button ends either.

A held jog is short jogs, each a tenth of a second of travel at the machine's feed,
sent so that the machine has never more than AHEAD_S of them queued: the head moves
without a pause, and a jog to the end of the travel stops where the machine refuses
the next one. When the client lets go (or its connection closes), Machine.cancel_jog
ramps the head down and drops what was queued: it stands within a ramp's time.
"""

from __future__ import annotations

import threading
import time

from galileo_cnc.errors import GalileoError
from galileo_cnc.program.ops import NM_PER_MM

CHUNK_S = 0.1
AHEAD_S = 0.25
AXES = ("x", "y", "z")


def jog(machine, config, axis: int, direction: int, cancelled: threading.Event,
        distance_mm: float | None, publish) -> list[str]:
    """In the machine's thread. `distance_mm`: one step of that length, waited out;
    None: held until `cancelled`. What to tell the user."""
    feed = config.feed_mm_s
    name = f"{AXES[axis].upper()}{'+' if direction > 0 else '-'}"
    if distance_mm is not None:
        machine.jog(axis, direction * round(distance_mm * NM_PER_MM), feed)
        # the stop button may end it while it runs at full feed (at least this long);
        # only its ramp down at the end is waited out whatever comes
        if cancelled.wait(distance_mm / feed):
            machine.cancel_jog()
            return [f"jog {name} {distance_mm:g} mm stopped"]
        machine.wait_still()
        return [f"jog {name} {distance_mm:g} mm"]
    chunk_nm = max(1, round(feed * CHUNK_S * NM_PER_MM))
    began, sent_nm = time.monotonic(), 0
    note = ""
    try:
        while not cancelled.is_set():
            ahead = feed * (time.monotonic() - began + AHEAD_S) * NM_PER_MM
            if sent_nm < ahead:
                machine.jog(axis, direction * chunk_nm, feed)
                sent_nm += chunk_nm
            else:
                cancelled.wait(CHUNK_S / 5)
    except GalileoError as refused:     # the end of the travel: the queued jogs run out
        note = f"jog {name} ended: {refused}"
        publish("message", {"text": note})
        machine.wait_still()
        return [note]
    machine.cancel_jog()
    return [f"jog {name} let go"]
