"""`setup`'s keypad jog on a machine that queues jogs (GRBL): every key is one jog
of the distance chosen before (Machine.jog: GRBL's `$J=`), at the console's feed rate.

The keys are those of keypad.py (8/2 Y, 4/6 X, 7/1 Z, NumLock-off twins, 0/o the
origin, q back). GRBL queues jogs; 0x85 (`cancel_jog`) makes it decelerate on the
path and drop them. It is sent on q, Escape and Ctrl-C, and when a held key is let
go: a terminal reports no key release, but a held key repeats (the same key
again within HELD_GAP_S), so while repeats come the head is kept about one jog
ahead of where it stands, and when they stop for RELEASE_S the jog is cancelled.
"""

from __future__ import annotations

import asyncio
import time

from prompt_toolkit.application import Application
from prompt_toolkit.key_binding import KeyBindings
from prompt_toolkit.layout import Layout, Window
from prompt_toolkit.layout.controls import FormattedTextControl

from galileo_cnc.backends.base import position_text
from galileo_cnc.console.keypad import HINT, LEAVE_KEYS, ORIGIN_KEYS, REFRESH_S
from galileo_cnc.console.units import NM_PER_JOG_UNIT
from galileo_cnc.grbl.jog import keypad_jog
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.program.ops import NM_PER_MM

#: the keypad's keys with NumLock off, as the digits grbl.jog.keypad_jog knows
KEYS = {"8": "8", "up": "8", "2": "2", "down": "2", "4": "4", "left": "4",
        "6": "6", "right": "6", "7": "7", "home": "7", "1": "1", "end": "1"}
#: the same key again this soon is the terminal's auto-repeat: the key is held
HELD_GAP_S = 0.1
#: no repeat for this long: the held key was let go (cancel the jog)
RELEASE_S = 0.25
AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


class GrblKeypadJog:
    def __init__(self, console, machine, units: int):
        self.console = console
        self.machine = machine
        self.units = units
        self.step_mm = units * NM_PER_JOG_UNIT / NM_PER_MM
        self.feed_mm_min = console.config.feed_mm_s * 60
        self.note = ""
        view = machine.view()
        if view is None:
            raise GrblError("GRBL did not answer its status query")
        self.status = view.raw
        self.target_nm = list(self.status.mpos_nm)     # where the queued jogs end
        self.held = False
        self._last_key: str | None = None
        self._last_at = 0.0
        self._release_at = 0.0

    def line(self) -> str:
        if self.status.state != "Idle":
            self._refresh()                 # the head is moving: show where it is now
        note = f"\n{self.note}" if self.note else ""      # wrapped: a refusal is long
        return (f"jog {self.units} units = {self.step_mm:g} mm at F{self.feed_mm_min:g}   "
                f"{position_text(self.status.wpos_nm)} ({self.status.state}){note}\n{HINT}")

    def _refresh(self) -> None:
        view = self.machine.view(timeout_s=1.0)
        if view is None:
            return                          # the next redraw asks again
        self.status = view.raw
        if self.status.state == "Idle":
            self.target_nm = list(self.status.mpos_nm)

    def press(self, key: str, app: Application) -> None:
        now = time.monotonic()
        repeat = key == self._last_key and now - self._last_at < HELD_GAP_S
        if self.held and key != self._last_key:
            self.cancel("another key: jog cancelled (0x85)")
        self.held = repeat or (self.held and key == self._last_key)
        self._last_key, self._last_at = key, now
        axis, distance_mm = keypad_jog(key, self.step_mm)
        if not self.held or self._ahead_nm(axis) <= round(self.step_mm * NM_PER_MM):
            self._jog(axis, distance_mm)
        if self.held:
            self._release_at = now + RELEASE_S
            asyncio.get_running_loop().call_later(RELEASE_S + 0.02, self._check_release, app)

    def _ahead_nm(self, axis: str) -> int:
        """How far the queued jogs still take the head along `axis`."""
        self._refresh()
        a = AXIS_INDEX[axis]
        return abs(self.target_nm[a] - self.status.mpos_nm[a])

    def _jog(self, axis: str, distance_mm: float) -> None:
        try:
            self.machine.jog(AXIS_INDEX[axis], round(distance_mm * NM_PER_MM),
                             self.console.config.feed_mm_s)
        except GrblError as refused:        # TravelError, JogError: GRBL's or our words
            self.note = str(refused)
        else:
            self.target_nm[AXIS_INDEX[axis]] += round(distance_mm * NM_PER_MM)
            self.note = ""
        self._refresh()

    def _check_release(self, app: Application) -> None:
        if self.held and time.monotonic() >= self._release_at:
            self.held = False
            self._last_key = None
            self.cancel("key released: jog cancelled (0x85)")
            app.invalidate()

    def cancel(self, note: str) -> None:
        """0x85: GRBL decelerates on its path and drops the queued jogs."""
        try:
            self.status = self.machine.cancel_jog()
        except GrblError as problem:
            self.note = str(problem)
            return
        self.target_nm = list(self.status.mpos_nm)
        self.note = note

    def set_origin(self) -> None:
        """G10 L20 P0: the current coordinate system's zero is here (GRBL keeps G54-G59
        in its EEPROM)."""
        self.held = False
        try:
            self.note = self.machine.set_origin()
        except GrblError as problem:
            self.note = str(problem)
            return
        self._refresh()

    def leave(self, app: Application) -> None:
        self.held = False
        if self.status.state != "Idle" or self.target_nm != list(self.status.mpos_nm):
            self.cancel("stopped (0x85)")
        app.exit()

    def run(self) -> None:
        keys = KeyBindings()
        for key, digit in KEYS.items():
            keys.add(key)(lambda event, d=digit: self.press(d, event.app))
        for key in ORIGIN_KEYS:
            keys.add(key)(lambda event: self.set_origin())
        for key in LEAVE_KEYS + ("c-c",):
            keys.add(key)(lambda event: self.leave(event.app))
        app: Application = Application(
            layout=Layout(Window(FormattedTextControl(self.line), wrap_lines=True)),
            key_bindings=keys, full_screen=False, refresh_interval=REFRESH_S)
        app.run()


def jog_with_keypad(console, machine, units: int) -> None:
    keypad = GrblKeypadJog(console, machine, units)
    keypad.run()
    status = machine.wait_still()
    machine.make_view(status)
    console.say(f"position {position_text(status.wpos_nm)} (work), machine "
                f"{position_text(status.mpos_nm)}")
