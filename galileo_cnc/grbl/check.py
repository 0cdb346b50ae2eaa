"""`plot --check` on GRBL: run a job through GRBL's check mode (`$C`).

In check mode GRBL parses and plans every line as it would for real but moves
nothing, ignores dwells and keeps the spindle off (commands.md). Leaving it
soft-resets GRBL (system.c: mc_reset), and the reset clears the parser state
(gc_init): modal modes, feed, the G92 and tool length offsets are lost, G54-G59
are read back from EEPROM, the machine position is kept. Check mode also
writes EEPROM: a checked `G10 L2/L20` changes G54-G59 for real (gcode.c has no
check-mode guard there). So `check_job` reads `$G` and `$#` before, and after
the reset puts back what differs:

- G54-G59 (by `G10 L2`), the G92 offset (by `G92`, from the machine position),
  the tool length offset (`G43.1`);
- the modal state of `$G`: plane, units, distance and feed mode, coordinate
  system, G0/G1, F, S, T.

Not restored: M3/M4 and coolant (the reset stopped them; turning a spindle or a
servo pen back on is the operator's call), overrides (back to 100 %), G28/G30
(setting them needs the machine there: a change is reported as a warning).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from galileo_cnc.grbl.gcode import GcodeLine
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.numbers import decimal_text_to_nm
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.stream import GrblStreamError, LineError, stream

_PARAM = re.compile(r"^\[(G5[4-9]|G28|G30|G92|TLO):([-0-9.,]+)\]$")
COORD_SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59")


@dataclass(slots=True)
class CheckReport:
    lines: int = 0
    errors: list[LineError] = field(default_factory=list)
    alarm: str = ""                 # "file:line: ALARM:2: ..." if check mode alarmed
    restored: list[str] = field(default_factory=list)   # lines sent after the reset
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.errors and not self.alarm

    def __str__(self) -> str:
        text = [f"{self.lines} lines checked, {len(self.errors)} rejected"
                + (":" if self.errors else "")]
        text += [f"  {error}" for error in self.errors]
        if self.alarm:
            text.append(f"  stopped by {self.alarm}")
        text += [f"  warning: {warning}" for warning in self.warnings]
        return "\n".join(text)


def parser_state(link: GrblLink) -> dict[str, str]:
    """`$G` as {group letter + word}: {'G': [...], 'F': '750', ...}; G/M words in order."""
    reply = link.command_checked("$G")
    words = next(line for line in reply.lines if line.startswith("[GC:"))[4:-1].split()
    return {"G": [w for w in words if w[0] == "G"], "M": [w for w in words if w[0] == "M"],
            **{w[0]: w[1:] for w in words if w[0] in "FST"}}


def parameters(link: GrblLink) -> dict[str, tuple[str, ...]]:
    """`$#`: {'G54': ('0.000', '0.000', '0.000'), ..., 'G92': ..., 'TLO': ('0.000',)}."""
    found = {}
    for line in link.command_checked("$#").lines:
        match = _PARAM.match(line)
        if match:
            found[match[1]] = tuple(match[2].split(","))
    return found


def check_job(link: GrblLink, lines: Sequence[GcodeLine], *,
              where: Callable[[int], str] = lambda command: "") -> CheckReport:
    """Every line through `$C`; returns the report (each `error:N` with its file
    line). GRBL is left as it was before, except for what the module doc names."""
    if link.status().state != "Idle":
        raise GrblError(f"check mode needs GRBL Idle, it is {link.tracker.last.state}")
    modes, before = parser_state(link), parameters(link)
    link.command_checked("$C")
    report = CheckReport(lines=len(lines))
    try:
        result = stream(link, lines, where=where, stop_on_error=False, wait_idle=False,
                        travel_check=False)
        report.errors = result.errors
    except GrblStreamError as stopped:
        if not stopped.alarm:
            raise
        # a soft limit alarms even in check mode; GRBL then waits for a reset
        report.errors = stopped.errors
        report.alarm = str(stopped)
    if report.alarm:
        link.soft_reset()
        # nothing moved in check mode, so the position is still known: unlocking is safe
        link.command_checked("$X")
    else:
        link.command_checked("$C")      # [MSG:Disabled], ok, then the reset's banner
        link.wait_banner()
    _restore(link, modes, before, report)
    return report


def _restore(link, modes, before, report) -> None:
    after = parameters(link)
    units = "G20" if link.settings is not None and link.settings.report_inches else "G21"
    sends = [units]                     # $# and $G print in these units
    for p, name in enumerate(COORD_SYSTEMS, start=1):
        if after.get(name) != before.get(name) and name in before:
            sends.append(f"G10 L2 P{p} " + _axes(before[name]))
    for name in ("G28", "G30"):
        if after.get(name) != before.get(name):
            report.warnings.append(f"the check changed {name} (now {','.join(after[name])}, "
                                   f"was {','.join(before[name])}); set it again with "
                                   f"{name}.1 at that position")
    tlo = before.get("TLO", ("0",))[0]
    if decimal_text_to_nm(tlo) != 0:
        sends.append(f"G43.1 Z{tlo}")
    coord = next((g for g in modes["G"] if g in COORD_SYSTEMS), "G54")
    motion = [g for g in modes["G"] if g in ("G0", "G1")]
    keep = [g for g in modes["G"] if g in ("G17", "G18", "G19", "G90", "G91", "G93", "G94")]
    values = [f"{k}{modes[k]}" for k in "FST" if k in modes]
    sends.append(" ".join(keep + [coord] + motion + values))
    g92 = before.get("G92")
    if g92 is not None and any(decimal_text_to_nm(v) for v in g92):
        sends.append("G92 " + _g92_words(link, coord, g92, before))
    final_units = next((g for g in modes["G"] if g in ("G20", "G21")), "G21")
    if final_units != units:
        sends.append(final_units)
    for text in sends:
        link.command_checked(text)
    report.restored = sends


def _axes(values) -> str:
    return " ".join(f"{axis}{value}" for axis, value in zip("XYZ", values))


def _g92_words(link, coord, g92, before) -> str:
    """G92 sets the offset from a work position: WPos = MPos - WCS - G92 - TLO
    (gcode.c), so the offset comes back by naming the work position it gives."""
    mpos = link.status().mpos_nm
    wcs = [decimal_text_to_nm(v) for v in before[coord]]
    tlo = [0, 0, decimal_text_to_nm(before.get("TLO", ("0",))[0])]
    words = []
    for a in range(3):
        work_nm = mpos[a] - wcs[a] - decimal_text_to_nm(g92[a]) - tlo[a]
        words.append(f"{'XYZ'[a]}{_mm(work_nm)}")
    return " ".join(words)


def _mm(nm: int) -> str:
    """3 decimals: $# and status reports give whole micrometres."""
    sign = "-" if nm < 0 else ""
    um = (abs(nm) + 500) // 1000
    return f"{sign}{um // 1000}.{um % 1000:03d}"
