"""`setup`: the seed's menu: 1) jog with the numeric keypad, 2) feed rate."""

from __future__ import annotations

import math

from galileo_cnc.console.units import NM_PER_JOG_UNIT, refusal_text
from galileo_cnc.errors import GalileoError
from galileo_cnc.transport.link import PortGone

MENU = """setup
  1) jog the head with the numeric keypad (and set the origin)
  2) feed rate
  q) back to the prompt"""
DEFAULT_JOG_UNITS = 100          # 1 mm


def run(console, arguments: list[str]) -> None:
    while True:
        console.say(MENU)
        choice = console.ask("choice: ").lower()
        if choice in ("", "q", "quit", "exit"):
            return
        action = _ACTIONS.get(choice)
        if action is None:
            console.say("choose 1, 2 or q")
            continue
        try:
            action(console)
        except PortGone:
            raise                               # the console says how to reconnect
        except GalileoError as refused:         # the menu stays: try another value
            console.say(refusal_text(refused, console.config))


def jog(console) -> None:
    units = _ask_jog_units(console)
    if units is not None:
        console.jog_with_keypad(units)


def _ask_jog_units(console) -> int | None:
    while True:
        answer = console.ask(f"jog distance in units of {NM_PER_JOG_UNIT // 1000} um "
                             f"(1000 = 1 cm, 0 goes back) [{DEFAULT_JOG_UNITS}]: ")
        if not answer:
            return DEFAULT_JOG_UNITS
        if answer.lower() == "q" or answer.strip() == "0":   # 0: the seed's way back
            return None
        try:
            units = int(answer)
        except ValueError:
            console.say("a whole number, please (100 = 1 mm)")
            continue
        if units < 0:
            console.say("the distance must be more than 0 (0 goes back)")
            continue
        return units


def feed(console) -> None:
    config = console.config
    answer = console.ask(f"feed rate in mm/s [{config.feed_mm_s:g}]: ")
    if not answer:
        return
    try:
        mm_s = float(answer)
    except ValueError:
        mm_s = math.nan
    if not math.isfinite(mm_s):
        console.say(f"not a number: {answer!r}")
        return
    steps_per_s = config.feed_steps_per_s_of(mm_s)
    refusal = console.machine.feed_refusal(config, mm_s)
    if refusal is not None:
        console.say(refusal)
        return
    if mm_s > config.feed_warn_mm_s:
        console.say(f"warning: {mm_s:g} mm/s ({config.feed_rpm(mm_s):.0f} rpm) is above "
                    f"{config.feed_warn_mm_s:g} mm/s ({config.feed_rpm(config.feed_warn_mm_s):.0f} "
                    "rpm): the motors may stall and lose steps")
        if not console.confirm("use it anyway?", default=False):
            console.say(f"feed rate stays {config.feed_mm_s:g} mm/s")
            return
    note = console.machine.set_feed(console.config, mm_s)
    console.use_config(config.replace(feed_mm_s=mm_s))
    console.say(f"feed rate {mm_s:g} mm/s ({steps_per_s} steps/s, "
                f"{config.feed_rpm(mm_s):.0f} rpm){note}")


_ACTIONS = {"1": jog, "2": feed}
