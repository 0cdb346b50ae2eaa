"""A command line for the machine: one line typed at a front end, sent, its reply shown.

As UGS, CNCjs, bCNC and Candle have it. On GRBL a line goes as it is (GRBL's `$`
commands, G-code) and every line GRBL answers is shown, then its `ok` or `error:N`
in GRBL's words; a G-code line is followed until GRBL stands still, and where it
stands is said. Our firmware reads no G-code: a line is read as a G-code file's
line would be (with the modes of the lines typed before it: G90/G91, G20/G21, F, the
pen), from where the head stands, planned and streamed as a job of one line (not
journalled: `resume` keeps the interrupted job). `$` commands are GRBL's; the few a
user of GRBL types first ($$, $H, $X) get our firmware's equivalents.
"""

from __future__ import annotations

import re
from typing import Callable

from galileo_cnc.backends.base import position_mm_text, position_text
from galileo_cnc.errors import GalileoError
from galileo_cnc.program.ops import ProgramBuilder

#: A line for the machine rather than a console command: a `$` command, GRBL's real-time
#: `?`, or a G-code word (letter, then a number) first, after an optional N word.
_MACHINE_LINE = re.compile(r"\s*(\$|\?\s*$|(N\d+\s*)?[GMXYZFTSP]\s*[-+.\d])", re.IGNORECASE)
#: GRBL's settings command, `$N=value`: GRBL's settings change with it.
_SETTING = re.compile(r"\s*\$(\d+\s*=|RST=)", re.IGNORECASE)
SOURCE = "typed line"


def is_machine_line(text: str) -> bool:
    """Whether `text` is meant for the machine (`$22=1`, `$$`, `G0 X10`), not a command."""
    return _MACHINE_LINE.match(text) is not None


def changes_grbl_settings(text: str) -> bool:
    return _SETTING.match(text) is not None


def run_home_or_unlock(machine, text: str, say: Callable[[str], None]) -> bool:
    """`$H` and `$X` as the console's `home` and `unlock` (homing may take longer than
    a reply is waited for; an unlock after a limit alarm needs a reset first); True
    when `text` was one of them."""
    word = text.strip().upper()
    if word == "$H":
        machine.home(say)
        say(machine.origin_after_home())
        return True
    if word == "$X":
        machine.unlock(say)
        return True
    return False


# ---- GRBL ------------------------------------------------------------------------------------
def send_to_grbl(link, text: str, say: Callable[[str], None]) -> bool:
    """Send `text` as it is; GRBL's lines and its ok or error shown. True when GRBL
    answered ok. A G-code line is followed until GRBL stands still (its moves run).
    Raises GrblError on an alarm (the caller settles it)."""
    if text.strip() == "?":
        status = link.status()
        say(f"<{status.state}> work {position_text(status.wpos_nm)}, machine "
            f"{position_text(status.mpos_nm)}")
        return True
    reply = link.command(text)
    for line in reply.lines:
        say(line)
    if not reply.ok:
        say(f"error:{reply.code}: {reply.text}")
        return False
    say("ok")
    if not text.lstrip().startswith("$"):
        status = link.wait_idle()
        say(f"GRBL stands at {position_text(status.wpos_nm)} (work)")
    return True


# ---- our firmware ----------------------------------------------------------------------------
class GcodeLines:
    """G-code lines read one at a time with the modes of the lines before them, each
    from where the head stands: what a G-code file's reader would make of them."""

    def __init__(self) -> None:
        from galileo_cnc.readers.gcode.reader import _Reader

        self._reader = _Reader(SOURCE)

    def read(self, text: str, where_nm: tuple[int, int]):
        """The Program of one line, the head at `where_nm` (work, nm); GcodeError
        names the line's column."""
        reader = self._reader
        reader.out = ProgramBuilder(SOURCE)
        reader.x, reader.y = where_nm           # the program frame is the work frame
        reader.ended = False                # M2 ends a file, not the console
        reader.home_rows = []
        return reader.run([text])


def galileo_settings(config) -> list[str]:
    """`$$` on our firmware: what GRBL's settings say, from the profile."""
    return [f"steps/mm {config.steps_per_mm:g} (GRBL's $100-$102)",
            f"travel X {config.x_travel_mm:g} mm, Y {config.y_travel_mm:g} mm "
            f"(GRBL's $130/$131)",
            f"feed {config.feed_mm_s:g} mm/s (F{config.feed_mm_s * 60:g} in mm/min)",
            "our firmware has no $ settings: they are the profile's [machine] keys"]


def refuse_dollar(text: str) -> str:
    return (f"{text.strip()}: `$` commands are GRBL's, and this machine runs the "
            f"galileo-cnc firmware: $$ lists its settings (the profile's), $H homes "
            f"(home), $X unlocks (unlock); G-code lines are sent as jobs of one line")


def run_galileo_line(machine, text: str, say: Callable[[str], None]) -> bool:
    """One G-code line as a job of one line on our firmware; True when it ran to its end."""
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file
    from galileo_cnc.stream.streamer import JobStreamer

    link, config = machine.link, machine.config
    status = link.status()
    if status.state == "alarm":         # a job would find the machine stopped
        raise GalileoError(f"{text.strip()}: not sent, the machine is locked (alarm): "
                           f"type unlock (or home), then send it again")
    where = (status.x_steps * config.nm_per_step, status.y_steps * config.nm_per_step)
    if machine.gcode_lines is None:             # the first line typed on this connection
        machine.gcode_lines = GcodeLines()
    lines = machine.gcode_lines
    program = lines.read(text, where)
    for warning in program.warnings:
        say(str(warning))
    if len(program) == 0:
        say("ok (nothing moves: what the line set holds for the next lines)")
        return True
    planned = plan_file(program, config, (0, 0),
                        options=PlanOptions(mode="centre", file_order=True))
    streamer = JobStreamer(link, planned.job, planned.plotted, journal=None)
    result = streamer.run()
    here = position_mm_text(link.status(), config)
    if not result.completed:
        say(f"stopped ({result.reason}); the head stands at {here} (work)")
        return False
    say(f"ok: the head stands at {here} (work)")
    return True


def send_to_galileo(machine, text: str, say: Callable[[str], None]) -> bool:
    """`$$`, `$H`, `$X` as our firmware's equivalents, other `$` lines refused with
    why; G-code as a job of one line."""
    word = text.strip().upper()
    if word == "$$":
        for line in galileo_settings(machine.config):
            say(line)
        return True
    if run_home_or_unlock(machine, text, say):
        return True
    if word == "?":
        say(machine.status_line(machine.config))
        return True
    if word.startswith("$"):
        raise GalileoError(refuse_dollar(text))
    return run_galileo_line(machine, text, say)
