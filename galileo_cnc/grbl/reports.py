"""What GRBL 1.1 sends back, parsed: status reports, settings, build info, errors.

doc/markdown/interface.md is the reference. Positions stay the decimal text
GRBL sent, turned into exact integer nanometres (`decimal_text_to_nm`); feeds
and speeds are the integers GRBL prints.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl import codes
from galileo_cnc.grbl.numbers import decimal_text_to_nm
from galileo_cnc.transport.discovery import grbl_banner_version

# GRBL 0.9 and 1.0 reply with ok/error:Text instead of codes; only 1.1 is driven.
SUPPORTED_MAJOR_MINOR = "1.1"


class GrblError(GalileoError):
    """GRBL refused something or reported an alarm; the text is GRBL's own."""

    def __init__(self, message: str, code: int | None = None, alarm: bool = False):
        self.code = code
        self.alarm = alarm
        super().__init__(message)


def _code_text(prefix: str, table: dict, code: int) -> str:
    entry = table.get(code)
    if entry is None:
        return f"{prefix}:{code}: unknown GRBL {prefix.lower()}"
    message, description = entry
    return f"{prefix}:{code}: {message} ({description})"


def error_text(code: int) -> str:
    """`error:N` as GRBL's doc/csv words it: 'error:20: Unsupported command (...)'."""
    return _code_text("error", codes.ERRORS, code)


def alarm_text(code: int) -> str:
    """`ALARM:N` likewise: 'ALARM:2: Soft limit (...)'."""
    return _code_text("ALARM", codes.ALARMS, code)


def banner_version(line: str) -> str | None:
    """'1.1h' for GRBL's start-up banner, else None (transport.discovery's pattern)."""
    return grbl_banner_version(line)


def _nm_vector(text: str) -> tuple[int, ...]:
    return tuple(decimal_text_to_nm(part) for part in text.split(","))


def _ints(text: str) -> tuple[int, ...]:
    return tuple(int(part) for part in text.split(","))


@dataclass(slots=True)
class Status:
    """One `<...>` report. Absent fields are None (or empty); `wco_nm` is the
    report's own WCO, which GRBL sends only now and then (see StatusTracker)."""

    state: str
    substate: int | None = None
    mpos_nm: tuple[int, ...] | None = None
    wpos_nm: tuple[int, ...] | None = None
    wco_nm: tuple[int, ...] | None = None
    planner_free: int | None = None        # Bf: blocks
    rx_free: int | None = None             # Bf: bytes
    line_number: int | None = None         # Ln:
    feed: int | None = None                # F: or FS: (mm/min, or in/min with $13=1)
    spindle: int | None = None             # FS: (rpm)
    pins: str = ""                         # Pn: triggered inputs, e.g. "XZ"
    overrides: tuple[int, ...] | None = None  # Ov: feed, rapid, spindle (%)
    accessories: str | None = None         # A: e.g. "SF"; None when not reported
    unknown: dict[str, str] = field(default_factory=dict)  # fields of later versions


def _set_state(s: Status, value: str) -> None:
    name, _, sub = value.partition(":")
    s.state = name
    s.substate = int(sub) if sub else None


def _bf(s: Status, v: str) -> None:
    s.planner_free, s.rx_free = _ints(v)


def _fs(s: Status, v: str) -> None:
    s.feed, s.spindle = _ints(v)


_FIELDS = {
    "MPos": lambda s, v: setattr(s, "mpos_nm", _nm_vector(v)),
    "WPos": lambda s, v: setattr(s, "wpos_nm", _nm_vector(v)),
    "WCO": lambda s, v: setattr(s, "wco_nm", _nm_vector(v)),
    "Bf": _bf,
    "Ln": lambda s, v: setattr(s, "line_number", int(v)),
    "F": lambda s, v: setattr(s, "feed", int(float(v))),
    "FS": _fs,
    "Pn": lambda s, v: setattr(s, "pins", v),
    "Ov": lambda s, v: setattr(s, "overrides", _ints(v)),
    "A": lambda s, v: setattr(s, "accessories", v),
}


def parse_status(line: str) -> Status:
    """`<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:...>`: fields in any order."""
    line = line.strip()
    if not (line.startswith("<") and line.endswith(">")):
        raise GrblError(f"not a GRBL status report: {line!r}")
    parts = line[1:-1].split("|")
    status = Status(state="")
    _set_state(status, parts[0])
    for part in parts[1:]:
        name, sep, value = part.partition(":")
        parse = _FIELDS.get(name)
        try:
            if parse is None or not sep:
                status.unknown[name] = value
            else:
                parse(status, value)
        except ValueError:
            raise GrblError(f"bad {name!r} field in GRBL status report: {line!r}") from None
    if status.mpos_nm is None and status.wpos_nm is None:
        raise GrblError(f"GRBL status report without a position: {line!r}")
    return status


class StatusTracker:
    """Keeps the last WCO (and Ov/A) across reports, so every report yields both
    machine and work position (interface.md: WPos = MPos - WCO)."""

    def __init__(self) -> None:
        self.wco_nm: tuple[int, ...] = (0, 0, 0)
        self.overrides: tuple[int, ...] = (100, 100, 100)
        self.accessories = ""
        self.last: Status | None = None

    def update(self, status: Status) -> Status:
        if status.wco_nm is not None:
            self.wco_nm = status.wco_nm
        if status.overrides is not None:
            self.overrides = status.overrides
            # A: comes only with Ov:; its absence there means nothing is on
            self.accessories = status.accessories or ""
        if status.mpos_nm is None:
            status.mpos_nm = tuple(w + o for w, o in zip(status.wpos_nm, self.wco_nm))
        if status.wpos_nm is None:
            status.wpos_nm = tuple(m - o for m, o in zip(status.mpos_nm, self.wco_nm))
        self.last = status
        return status


# ---- $$ settings and $I build info ----------------------------------------------

SETTING = re.compile(r"^\$(?P<number>\d+)=(?P<value>-?\d+(?:\.\d*)?)$")


@dataclass(frozen=True, slots=True)
class BuildInfo:
    """`[VER:1.1h.20190830:]` and `[OPT:V,15,128]` from `$I`."""

    version: str
    options: str = ""
    planner_blocks: int | None = None
    rx_buffer_bytes: int | None = None
    user_text: str = ""


def parse_build_info(lines: list[str]) -> BuildInfo:
    version, options, blocks, rx, user = "", "", None, None, ""
    for line in lines:
        if line.startswith("[VER:") and line.endswith("]"):
            version, _, user = line[5:-1].partition(":")
        elif line.startswith("[OPT:") and line.endswith("]"):
            fields = line[5:-1].split(",")
            options = fields[0]
            if len(fields) >= 3:
                blocks, rx = int(fields[1]), int(fields[2])
    if not version:
        raise GrblError(f"no [VER:] line in GRBL's $I reply: {lines!r}")
    return BuildInfo(version, options, blocks, rx, user)


@dataclass(frozen=True, slots=True)
class GrblSettings:
    """`$$` as GRBL printed it: each value keeps its text (GRBL parsed that text
    into its float, numbers.read_float gives the same float back)."""

    text: dict[int, str]

    def __getitem__(self, number: int) -> str:
        return self.text[number]

    def integer(self, number: int) -> int:
        return int(self.text[number].split(".")[0])

    def flag(self, number: int) -> bool:
        return self.integer(number) != 0

    def steps_per_mm_text(self, axis: int) -> str:
        return self.text[100 + axis]

    def max_rate_mm_min(self, axis: int) -> str:
        return self.text[110 + axis]

    def accel_mm_s2(self, axis: int) -> str:
        return self.text[120 + axis]

    def max_travel_nm(self, axis: int) -> int:
        return decimal_text_to_nm(self.text[130 + axis])

    @property
    def soft_limits(self) -> bool:
        return self.flag(20)

    @property
    def homing(self) -> bool:
        return self.flag(22)

    @property
    def report_inches(self) -> bool:
        return self.flag(13)

    def describe(self, number: int) -> str:
        entry = codes.SETTINGS.get(number)
        name = f"{entry[0]} ({entry[1]})" if entry else "unknown setting"
        return f"${number}={self.text[number]}  {name}"


def parse_settings(lines: list[str]) -> GrblSettings:
    text = {}
    for line in lines:
        match = SETTING.match(line.strip())
        if match:
            text[int(match["number"])] = match["value"]
    missing = [n for n in (13, 20, 22, 100, 101, 102, 110, 111, 112, 120, 121, 122,
                           130, 131, 132) if n not in text]
    if missing:
        raise GrblError("GRBL's $$ reply lacks " + ", ".join(f"${n}" for n in missing))
    return GrblSettings(text)
