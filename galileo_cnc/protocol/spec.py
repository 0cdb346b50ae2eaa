"""What the wire carries, defined once: version, sizes, commands, errors, states, bytes.

The firmware's protocol.h is generated from this module (galileo_cnc.firmware_headers);
the codec beside it frames and reads lines. It depends on the machine commands
(galileo_cnc.job) and nothing downstream.
"""


from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from galileo_cnc.job import (ArcTo, Dwell, EndJob, Flash, Home, Jog, LineTo, Motors, PenDown,
                             PenUp, Rapid, SetFeed, SetOrigin)

# 2: the banner names the build's config; `C` lists it. 3: real-time bytes that no
# single-bit error of line text can produce; a refused line is not counted (its number
# is expected again), so nothing behind it runs and status `N` shows the refusal.
# 4: CRC-16 in place of CRC-8, a separator that says the length's parity (every lost or
# doubled byte is caught), and the same check on every line the machine sends.
# 5: LX, CWX, CCX: a line or arc that ends at a planned ramp index (junction speeds,
# docs/motion.md §5.7), the index first.
PROTOCOL_VERSION = 5
FIRMWARE_VERSION = "0.1.0"
BANNER_NAME = "galileo-cnc"
MAX_LINE_BYTES = 64          # including the newline
RX_BUFFER_BYTES = 128        # the firmware's receive ring; the host counts characters against it
QUEUE_BLOCKS = 8             # planned blocks the firmware queues (a Rapid is two, a Flash three)
SEQ_MAX = 65535              # after SEQ_MAX comes 1; N0 is always accepted and restarts at 1
CRC16_POLY = 0x1021          # CRC-16/CCITT-FALSE: x^16 + x^12 + x^5 + 1,
CRC16_INIT = 0xFFFF          # init 0xFFFF, no reflection (avr-libc's _crc_xmodem_update)
#: The byte before the check: `*` after text of an even number of bytes, `#` after an odd
#: one, so a single lost, doubled or inserted byte (a UART's usual failure, which a CRC
#: catches only 65 535 times in 65 536) always shows. They lie two bits apart.
CHECK_SEPARATORS = (b"*", b"#")
CHECK_BYTES = 5              # separator and four upper-case hex digits

# Real-time bytes: acted on in the receive interrupt, never part of a line. Line text is
# printable ASCII and `\n`; every byte one bit away from it is barred (GRBL's `!` is a
# space with bit 0 set, 0x18 is `8` without bit 5). Of the bytes left (0x80..0x9F but
# 0x8A, and 0xFF, which an idle or broken line reads as) these four lie at least three
# bits apart, so one flipped bit cannot turn one into another either.
LINE_TEXT_BYTES = frozenset(range(0x20, 0x7F)) | {0x0A}
RT_STATUS = b"\x83"
RT_HOLD = b"\x8c"
RT_RESUME = b"\x95"
RT_ABORT = b"\x9a"
REALTIME_BYTES = {"STATUS": RT_STATUS, "HOLD": RT_HOLD, "RESUME": RT_RESUME, "ABORT": RT_ABORT}

STATES = ("idle", "run", "hold", "alarm", "homing")


@dataclass(frozen=True, slots=True)
class ArgKind:
    """An integer argument's accepted range (checked before any meaning is applied)."""

    name: str
    lo: int
    hi: int


COORD = ArgKind("COORD", -9_999_999, 9_999_999)     # steps
MS = ArgKind("MS", 0, 2_000_000)                    # milliseconds (2000 ticks each)
FEED = ArgKind("FEED", 0, 9_999_999)                # steps/s (the firmware checks 10..F_MAX)
FLAG = ArgKind("FLAG", 0, 1)
INDEX = ArgKind("INDEX", 0, 9_999_999)              # ramp index (the firmware caps it at R)
ARG_KINDS = (COORD, MS, FEED, FLAG, INDEX)


# ---- protocol-only commands (no motion) ---------------------------------------------
@dataclass(frozen=True, slots=True)
class QueryStatus:
    """`S`: the reply is `ok N<seq> status:...`."""


@dataclass(frozen=True, slots=True)
class QueryVersion:
    """`V`: the reply is `ok N<seq> <banner>` (for hosts that missed the reset banner)."""


@dataclass(frozen=True, slots=True)
class QueryConfig:
    """`C`: the reply is `ok N<seq> config NAME=value ...`, the values the firmware was
    built with (config.h), so the host can name what differs from its profile."""


@dataclass(frozen=True, slots=True)
class Unlock:
    """`U`: leave the alarm state and start a new job after `E` (EndJob)."""


@dataclass(frozen=True, slots=True)
class CommandSpec:
    """One mnemonic: the command class, its fields in wire order with their kinds.

    Fields from `optional_from` on may be omitted (None in the command object).
    `junction`: the form for a move whose `exit_index` is set (its first argument).
    `fixed` holds fields implied by the mnemonic (CW / CCW set ArcTo.cw).
    `blocks` is the queue room the command reserves before it is planned (per homed
    axis for HOME); the firmware reads it from the generated table.
    """

    name: str
    mnemonic: str
    cls: type
    args: tuple[tuple[str, ArgKind], ...] = ()
    optional_from: Optional[int] = None
    fixed: tuple[tuple[str, object], ...] = ()
    blocks: int = 0
    junction: bool = False

    @property
    def min_args(self) -> int:
        return len(self.args) if self.optional_from is None else self.optional_from


_XY = (("x_steps", COORD), ("y_steps", COORD))
COMMANDS = (
    CommandSpec("RAPID", "R", Rapid, _XY, blocks=2),          # pen up, travel
    CommandSpec("LINE", "L", LineTo, _XY + (("z_steps", COORD),), optional_from=2, blocks=1),
    CommandSpec("ARC_CW", "CW", ArcTo, _XY + (("i_steps", COORD), ("j_steps", COORD)),
                fixed=(("cw", True),), blocks=1),
    CommandSpec("ARC_CCW", "CCW", ArcTo, _XY + (("i_steps", COORD), ("j_steps", COORD)),
                fixed=(("cw", False),), blocks=1),
    CommandSpec("LINE_X", "LX", LineTo, (("exit_index", INDEX),) + _XY + (("z_steps", COORD),),
                optional_from=3, blocks=1, junction=True),
    CommandSpec("ARC_CW_X", "CWX", ArcTo, (("exit_index", INDEX),) + _XY
                + (("i_steps", COORD), ("j_steps", COORD)), fixed=(("cw", True),), blocks=1,
                junction=True),
    CommandSpec("ARC_CCW_X", "CCX", ArcTo, (("exit_index", INDEX),) + _XY
                + (("i_steps", COORD), ("j_steps", COORD)), fixed=(("cw", False),), blocks=1,
                junction=True),
    CommandSpec("PEN_UP", "PU", PenUp, blocks=1),
    CommandSpec("PEN_DOWN", "PD", PenDown, blocks=1),
    CommandSpec("FLASH", "FL", Flash, (("dwell_ms", MS),), optional_from=0,
                blocks=3),                                    # down, dwell, up
    CommandSpec("DWELL", "DW", Dwell, (("ms", MS),), blocks=1),
    CommandSpec("FEED", "F", SetFeed, (("feed_steps_per_s", FEED),)),
    CommandSpec("JOG", "J", Jog, (("dx_steps", COORD), ("dy_steps", COORD),
                                  ("dz_steps", COORD)), blocks=1),
    CommandSpec("ORIGIN", "O", SetOrigin, blocks=1),
    CommandSpec("HOME", "H", Home, blocks=3),                 # seek, pull-off, origin per axis
    CommandSpec("MOTORS", "M", Motors, (("on", FLAG),)),
    CommandSpec("END_JOB", "E", EndJob, blocks=1),
    CommandSpec("STATUS", "S", QueryStatus),
    CommandSpec("VERSION", "V", QueryVersion),
    CommandSpec("UNLOCK", "U", Unlock),
    CommandSpec("CONFIG", "C", QueryConfig),
)
BY_MNEMONIC = {spec.mnemonic: spec for spec in COMMANDS}
#: Commands that are answered even in alarm or after EndJob (no motion).
PROTOCOL_ONLY = ("STATUS", "VERSION", "UNLOCK", "CONFIG")


def blocks_needed(spec: CommandSpec, home_axes: int) -> int:
    """Queue blocks `spec` reserves: the firmware's `planner_blocks_needed`."""
    return spec.blocks * home_axes if spec.name == "HOME" else spec.blocks


@dataclass(frozen=True, slots=True)
class ErrorSpec:
    """A numbered error. `alarm` errors arrive as `alarm:CODE` and lock the machine."""

    code: int
    name: str
    text: str
    alarm: bool = False


ERRORS = (
    ErrorSpec(1, "BAD_LINE", "malformed line"),
    ErrorSpec(2, "LINE_TOO_LONG", "line too long"),
    ErrorSpec(3, "UNKNOWN_COMMAND", "unknown command"),
    ErrorSpec(4, "BAD_ARGUMENT", "bad argument"),
    ErrorSpec(5, "SOFT_LIMIT", "soft limit"),
    ErrorSpec(6, "FEED_RANGE", "feed out of range"),
    ErrorSpec(7, "ARC_TOO_LARGE", "arc radius too large"),
    ErrorSpec(8, "JOB_ENDED", "job has ended, send U"),
    ErrorSpec(9, "LOCKED", "alarm, send U"),
    ErrorSpec(10, "HOME_SWITCH_ACTIVE", "end-stop already active, jog away", alarm=True),
    ErrorSpec(11, "HOME_NOT_FOUND", "end-stop not found", alarm=True),
    ErrorSpec(12, "HOME_PULLOFF", "end-stop still active after pull-off", alarm=True),
    ErrorSpec(13, "STEP_OVERRUN", "step interrupt overrun, timing slipped"),
    ErrorSpec(14, "ABORTED", "aborted", alarm=True),
)
ERROR_BY_CODE = {e.code: e for e in ERRORS}
ERROR_BY_NAME = {e.name: e for e in ERRORS}
