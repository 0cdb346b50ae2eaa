"""Jogging with the numeric keypad, as the seed's setup screen did.

7/1 Z up/down, 8/2 Y +/-, 4/6 X -/+ (with NumLock off the keypad sends
Home/End and the arrows, which do the same); 0 or o sets the origin here; q
leaves. One small prompt_toolkit application reads single keys; every jog is
one `Jog` command of the distance chosen before.
"""

from __future__ import annotations

from prompt_toolkit.application import Application
from prompt_toolkit.key_binding import KeyBindings
from prompt_toolkit.layout import Layout, Window
from prompt_toolkit.layout.controls import FormattedTextControl

from galileo_cnc import protocol as P
from galileo_cnc.backends.base import position_mm_text
from galileo_cnc.backends.galileo import GalileoMachine
from galileo_cnc.console.units import NM_PER_JOG_UNIT, jog_units_to_steps, refusal_text
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import AXIS_NAMES
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.command_text import mm_text
from galileo_cnc.transport.link import LinkError, PortGone

#: key -> direction (x, y, z); each key has a NumLock-off twin.
KEYPAD = {
    "8": (0, 1, 0), "up": (0, 1, 0),
    "2": (0, -1, 0), "down": (0, -1, 0),
    "4": (-1, 0, 0), "left": (-1, 0, 0),
    "6": (1, 0, 0), "right": (1, 0, 0),
    "7": (0, 0, 1), "home": (0, 0, 1),
    "1": (0, 0, -1), "end": (0, 0, -1),
}
ORIGIN_KEYS = ("0", "o", "O", "insert")   # Insert is keypad 0 with NumLock off
LEAVE_KEYS = ("q", "Q", "escape")
#: how often the line is redrawn (and the position asked for while the head moves)
REFRESH_S = 0.2
HINT = "7/1 Z up/down  8/2 Y+/Y-  4/6 X-/X+  0 or o: origin here (X, Y and Z)  q: back"


class KeypadJog:
    def __init__(self, console, units: int, machine=None):
        """`machine`: the console's (a GalileoMachine over `console.link` by default)."""
        self.console = console
        self.machine = machine if machine is not None else GalileoMachine(console.link)
        self.step = jog_units_to_steps(units, console.config)
        self.units = units
        self.note = ""
        view = self.machine.view()
        if view is None:
            raise LinkError("the machine did not answer its status request")
        self.status = view.raw

    def line(self) -> str:
        if self.status.state != "idle" or self.status.queue_blocks:
            self._refresh()                     # the head is moving: show where it is now
        where = position_mm_text(self.status, self.console.config)
        note = f"\n{self.note}" if self.note else ""      # wrapped: a refusal is long
        jog_mm = self.units * NM_PER_JOG_UNIT / NM_PER_MM
        return (f"jog {self.units} units = {jog_mm:g} mm   {where}{note}\n{HINT}")

    def jog(self, direction: tuple[int, int, int]) -> None:
        axis = next(a for a, d in enumerate(direction) if d)
        distance_nm = direction[axis] * self.units * NM_PER_JOG_UNIT
        try:
            self.machine.jog(axis, distance_nm, self.console.config.feed_mm_s)
            self.note = ""
        except PortGone:
            raise
        except GalileoError as refused:
            self.note = self._jog_refusal(refused, axis, direction[axis] * self.step)
        self._refresh()

    def _jog_refusal(self, refused: GalileoError, axis: int, steps: int) -> str:
        """A refused jog in the jog line's work coordinates (and the machine's)."""
        reply = getattr(refused, "reply", None)
        code = getattr(reply, "code", None)
        if code == P.ERROR_BY_NAME["LOCKED"].code:
            return ("refused: the machine is locked (alarm): leave with q and type unlock "
                    "(home again once the cause is fixed)")
        limit = P.parse_soft_limit(reply.text) if code == \
            P.ERROR_BY_NAME["SOFT_LIMIT"].code else None
        if limit is None:
            return refusal_text(refused, self.console.config)
        # the jogs before it have ended: where this one began is the status's position
        self.status = self.machine.wait_still()
        name, value, bound = limit
        work_from = (self.status.x_steps, self.status.y_steps, self.status.z_steps)[axis]
        return jog_refusal_text(self.console.config, axis, work_from, steps, value, bound)

    def set_origin(self) -> None:
        self._do(self.machine.set_origin, None)

    def _do(self, action, note: str | None) -> None:
        """`note`: what to show when `action` worked; None: what `action` returns."""
        try:
            said = action()
            self.note = said if note is None else note
        except PortGone:
            raise
        except GalileoError as refused:          # e.g. the jog would leave the travel
            self.note = refusal_text(refused, self.console.config)
        self._refresh()

    def _refresh(self) -> None:
        view = self.machine.view(timeout_s=1.0)
        if view is not None:                     # else the next redraw asks again
            self.status = view.raw

    def stop(self) -> None:
        self.machine.cancel_jog()
        self.note = "stopped"

    def run(self) -> None:
        keys = KeyBindings()
        for key, direction in KEYPAD.items():
            keys.add(key)(lambda event, d=direction: self.jog(d))
        for key in ORIGIN_KEYS:
            keys.add(key)(lambda event: self.set_origin())
        for key in LEAVE_KEYS:
            keys.add(key)(lambda event: event.app.exit())

        @keys.add("c-c")
        def _interrupt(event) -> None:
            self.stop()
            event.app.exit()

        # redrawn while a jog runs, so the position follows the head (line() asks)
        app: Application = Application(
            layout=Layout(Window(FormattedTextControl(self.line), wrap_lines=True)),
            key_bindings=keys, full_screen=False, refresh_interval=REFRESH_S)
        app.run()


def jog_refusal_text(config, axis: int, work_from: int, steps: int, value: int,
                     bound: int) -> str:
    """`value`, `bound`: the machine's refusal (machine steps); the jog went from
    `work_from` by `steps` (work steps). Says it in work coordinates, as the jog line
    does, the machine's in brackets, and how to get out when the head stands outside."""
    spm = config.steps_per_mm
    name = AXIS_NAMES[axis]
    offset = value - (work_from + steps)            # machine = work + offset
    side = "beyond the travel's end" if value > bound else "below the travel's start"
    text = (f"refused: {name} would reach {mm_text(value - offset, spm)}, {side} at "
            f"{mm_text(bound - offset, spm)} [{value - offset} steps] (work coordinates; "
            f"machine {mm_text(value, spm)}, {mm_text(bound, spm)})")
    here = work_from + offset
    lo, hi = config.travel_min_steps[axis], config.travel_max_steps[axis]
    if axis == 2 and config.home_pins[2] == -1:
        return (f"{text}; Z has no end-stop: it keeps within "
                f"{mm_text(hi - lo, spm)} of every height since power-on")
    if not lo <= here <= hi:
        back = "+" if here < lo else "-"
        return (f"{text}; {name} stands outside the travel: jog {name}{back} back into it "
                f"(or home)")
    return text


def jog_with_keypad(console, units: int) -> None:
    keypad = KeypadJog(console, units, console.machine)
    keypad.run()
    status = console.machine.wait_still()
    console.say(f"position {position_mm_text(status, console.config)}")
