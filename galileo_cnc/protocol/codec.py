"""Lines on the wire: the check both sides put on every line (CRC-16 behind a separator
that says the length's parity), framing with the sequence number, encoding and decoding
commands, and reading the firmware's replies (docs/protocol.md).
"""

from __future__ import annotations

import binascii
import re
from dataclasses import dataclass
from typing import NamedTuple

from galileo_cnc.errors import GalileoError
from galileo_cnc.command_text import field_text, number_text
from galileo_cnc.protocol.spec import (BANNER_NAME, BY_MNEMONIC, CHECK_BYTES, CHECK_SEPARATORS,
                                       COMMANDS, CRC16_INIT, ERROR_BY_CODE, FLAG, MAX_LINE_BYTES,
                                       PROTOCOL_VERSION, SEQ_MAX, STATES, CommandSpec, ErrorSpec)


# ---- errors on the host ---------------------------------------------------------------
class ProtocolError(GalileoError):
    """A line or reply that does not follow docs/protocol.md."""


class ProtocolVersionError(ProtocolError):
    """The firmware speaks a different protocol version: the host refuses it."""


class LineRejected(ProtocolError):
    """A command line the machine side refuses: `code` set, or a resend request."""

    def __init__(self, message: str, code: int | None = None, resend: bool = False,
                 seq: int | None = None):
        self.code = code
        self.resend = resend
        self.seq = seq  # the line's sequence number, if it matched
        super().__init__(message)


# ---- the check on every line ----------------------------------------------------------
def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (check value 0x29B1 for `123456789`)."""
    return binascii.crc_hqx(data, CRC16_INIT)


def checked(text: bytes) -> bytes:
    """`text` as a line on the wire, either way: text, separator, CRC-16 over both, newline."""
    separator = CHECK_SEPARATORS[len(text) % 2]
    return text + separator + b"%04X\n" % crc16(text + separator)


_HEX4 = re.compile(rb"[0-9A-F]{4}")


def unchecked(line: bytes) -> bytes | None:
    """The text of a received line (newline and `\r` removed) if its check holds, else
    None: the firmware's test, step for step (a separator of the wrong parity, hex
    digits that are not four upper-case ones, or a CRC that differs)."""
    n = len(line) - CHECK_BYTES
    if n < 1 or line[n:n + 1] != CHECK_SEPARATORS[n % 2]:
        return None
    digits = line[n + 1:]
    if not _HEX4.fullmatch(digits) or int(digits, 16) != crc16(line[:n + 1]):
        return None
    return line[:n]


# ---- framing ----
def next_seq(seq: int) -> int:
    """The sequence number after `seq` (1 .. SEQ_MAX, then 1 again)."""
    return 1 if seq >= SEQ_MAX else seq + 1


def frame_line(seq: int, text: str) -> bytes:
    """`N<seq> <text>*HHHH\\n`; raises ProtocolError if it would exceed MAX_LINE_BYTES."""
    if not 0 <= seq <= SEQ_MAX:
        raise ProtocolError(f"sequence number {seq} outside 0..{SEQ_MAX}")
    line = checked(f"N{seq} {text}".encode("ascii"))
    if len(line) > MAX_LINE_BYTES:
        raise ProtocolError(f"line of {len(line)} bytes exceeds {MAX_LINE_BYTES}: {line!r}")
    return line


_SPECS_OF_CLASS: dict[type, list[CommandSpec]] = {}
for _spec in COMMANDS:
    _SPECS_OF_CLASS.setdefault(_spec.cls, []).append(_spec)


def _spec_of(cmd: object) -> CommandSpec:
    for spec in _SPECS_OF_CLASS.get(type(cmd), ()):
        if (all(getattr(cmd, f) == v for f, v in spec.fixed)
                and spec.junction == (getattr(cmd, "exit_index", None) is not None)):
            return spec
    raise ProtocolError(f"no wire form for {cmd!r}")


def range_problem(cmd: object, steps_per_mm: float | None = None) -> str | None:
    """What of a command the wire cannot carry ('ms=1000000000 outside 0..2000000'),
    else None: the planner asks before anything is sent. With `steps_per_mm`, a
    length or feed is said in mm (the wire's form in brackets)."""
    spec = _spec_of(cmd)
    for field, kind in spec.args:
        value = getattr(cmd, field)
        if value is not None and not kind.lo <= int(value) <= kind.hi:
            wire = f"{field}={int(value)} outside {kind.lo}..{kind.hi}"
            if steps_per_mm is None:
                return wire
            if field == "ms":               # a dwell: said in seconds, as G4 P is read
                return (f"a dwell of {number_text(int(value) / 1000)} s is longer than a "
                        f"machine command carries ({number_text(kind.hi / 1000)} s at most) "
                        f"[{wire}]")
            if not field.endswith(("_steps", "_steps_per_s")):
                return wire
            return (f"{field_text(field, int(value), steps_per_mm)} is beyond what a machine "
                    f"command carries ({field_text(field, kind.lo, steps_per_mm)} .. "
                    f"{field_text(field, kind.hi, steps_per_mm)}) [{wire}]")
    return None


def _ranges_of_class(cls: type) -> tuple[tuple[str, int, int], ...] | None:
    """(field, lo, hi) of every argument, when all of the class's wire forms carry
    the same arguments (ArcTo's CW and CCW do); else None."""
    forms = {spec.args for spec in _SPECS_OF_CLASS.get(cls, ())}
    if len(forms) != 1:
        return None
    return tuple((field, kind.lo, kind.hi) for field, kind in forms.pop())


def first_range_problem(commands: list, steps_per_mm: float | None = None
                        ) -> tuple[int, str] | None:
    """(index, range_problem) of the first command the wire cannot carry, else None:
    range_problem over a whole job, with each class's ranges looked up once
    (hellboard's 137k-command ink job: 0.25 -> 0.1 s)."""
    ranges: dict[type, tuple | None] = {}
    for at, cmd in enumerate(commands):
        cls = type(cmd)
        if cls not in ranges:
            ranges[cls] = _ranges_of_class(cls)
        checks = ranges[cls]
        if checks is None:
            problem = range_problem(cmd, steps_per_mm)
            if problem is not None:
                return at, problem
            continue
        for field, lo, hi in checks:
            value = getattr(cmd, field)
            if value is not None and not lo <= value <= hi:
                problem = range_problem(cmd, steps_per_mm)      # its message (and its int())
                if problem is not None:
                    return at, problem
    return None


def command_text(cmd: object) -> str:
    """The mnemonic and arguments of a command, without framing: `L 100 -20`."""
    spec = _spec_of(cmd)
    parts = [spec.mnemonic]
    for i, (field, kind) in enumerate(spec.args):
        value = getattr(cmd, field)
        if value is None:
            if spec.optional_from is None or i < spec.optional_from:
                raise ProtocolError(f"{cmd!r}: {field} is required on the wire")
            break
        value = int(value)
        if not kind.lo <= value <= kind.hi:
            raise ProtocolError(f"{cmd!r}: {field}={value} outside {kind.lo}..{kind.hi}")
        parts.append(str(value))
    return " ".join(parts)


def encode_command(cmd: object, seq: int) -> bytes:
    """A complete framed line for a machine (or protocol-only) command."""
    return frame_line(seq, command_text(cmd))


class DecodedLine(NamedTuple):
    seq: int
    command: object
    mnemonic: str


_SEQUENCE = re.compile(r"N(\d{1,6})")
_MNEMONIC = re.compile(r"[A-Z]{0,3}")
_ARGUMENT = re.compile(r"(-?)(\d*)")


def decode_line(line: bytes, expected_seq: int | None = None) -> DecodedLine:
    """Parse one received line exactly as the firmware's `handle_line` does, check for
    check and in the same order (the simulated machine answers with it; its tests
    compare every reply with the firmware's in simavr).

    Raises LineRejected: `resend` for a missing or bad checksum or a sequence
    mismatch, else an error `code`; `seq` is set once the sequence number matched
    (the refusal names it; the number is not counted, so it is expected again).
    """
    line = line.rstrip(b"\n").replace(b"\r", b"")
    if len(line) + 1 > MAX_LINE_BYTES:
        raise LineRejected("line too long", code=2)
    text = unchecked(line)
    if text is None:
        raise LineRejected("checksum", resend=True)
    body = text.decode("latin-1")
    m = _SEQUENCE.match(body)
    rest = body[m.end():] if m else ""
    if m is None or len(m.group(1)) > 5 or int(m.group(1)) > SEQ_MAX or not rest.startswith(" "):
        raise LineRejected("malformed line", code=1)
    seq = int(m.group(1))
    if expected_seq is not None and seq != 0 and seq != expected_seq:
        raise LineRejected(f"expected N{expected_seq}", resend=True)
    mm = _MNEMONIC.match(rest, 1)
    mnemonic, p = mm.group(0), rest[mm.end():]
    spec = BY_MNEMONIC.get(mnemonic) if mnemonic else None
    if spec is None or (p and p[0] != " "):
        raise LineRejected("unknown command", code=3, seq=seq)
    values: list[int] = []
    while p.startswith(" ") and len(values) < len(spec.args):
        am = _ARGUMENT.match(p, 1)
        digits = am.group(2)
        if not 1 <= len(digits) <= 9:
            raise LineRejected("bad argument", code=4, seq=seq)
        value = -int(digits) if am.group(1) else int(digits)
        kind = spec.args[len(values)][1]
        if not kind.lo <= value <= kind.hi:
            raise LineRejected("bad argument", code=4, seq=seq)
        values.append(value)
        p = p[am.end():]
    if p or len(values) < spec.min_args:
        raise LineRejected("bad argument", code=4, seq=seq)
    kwargs = dict(spec.fixed)
    for (field, kind), value in zip(spec.args, values):
        kwargs[field] = bool(value) if kind is FLAG else value
    return DecodedLine(seq, spec.cls(**kwargs), spec.mnemonic)


# ---- replies --------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Status:
    state: str
    x_steps: int          # work position
    y_steps: int
    z_steps: int
    queue_blocks: int
    last_seq: int         # last line the firmware accepted

    def text(self) -> str:
        return (f"status:{self.state} X{self.x_steps} Y{self.y_steps} Z{self.z_steps} "
                f"Q{self.queue_blocks} N{self.last_seq}")


@dataclass(frozen=True, slots=True)
class Banner:
    firmware_version: str
    protocol_version: int
    rx_buffer_bytes: int
    queue_blocks: int
    config_digest: str = ""       # MachineConfig.firmware_digest() of the build ("" before proto 2)

    def text(self) -> str:
        digest = f" config {self.config_digest}" if self.config_digest else ""
        return (f"{BANNER_NAME} {self.firmware_version} proto {self.protocol_version} "
                f"rx {self.rx_buffer_bytes} queue {self.queue_blocks}{digest}")


@dataclass(frozen=True, slots=True)
class Reply:
    """One line from the firmware. `kind`: ok, error, rs, status, alarm, msg, banner."""

    kind: str
    seq: int | None = None
    code: int | None = None
    text: str = ""
    status: Status | None = None
    banner: Banner | None = None

    @property
    def error(self) -> ErrorSpec | None:
        return ERROR_BY_CODE.get(self.code) if self.code is not None else None


_STATUS_RE = re.compile(r"^status:([a-z]+) X(-?\d+) Y(-?\d+) Z(-?\d+) Q(\d+) N(\d+)$")
_BANNER_RE = re.compile(rf"^{BANNER_NAME} (\S+) proto (\d+) rx (\d+) queue (\d+)"
                        r"(?: config ([0-9a-f]{8}))?$")
_CODE_RE = re.compile(r"^(error|alarm|msg):(\d+)(?: N(\d+))?(?: (.*))?$")
_OK_RE = re.compile(r"^ok N(\d+)(?: (.*))?$")


def _status(text: str) -> Status | None:
    m = _STATUS_RE.match(text)
    if m is None or m.group(1) not in STATES:
        return None
    return Status(m.group(1), *(int(g) for g in m.group(2, 3, 4, 5, 6)))


def _banner(text: str) -> Banner | None:
    m = _BANNER_RE.match(text)
    if m is None:
        return None
    return Banner(m.group(1), *(int(g) for g in m.group(2, 3, 4)), m.group(5) or "")


def parse_reply(line: bytes | str) -> Reply:
    """Decode one line from the firmware; ProtocolError for a line whose check fails
    (garbled on the way: better lost than believed) or that is undocumented.

    A banner without a valid check is still read when it names another protocol
    version (before 4 replies had none), so that `check_banner` can say what to do.
    """
    raw = line.encode("latin-1") if isinstance(line, str) else line
    raw = raw.rstrip(b"\n").replace(b"\r", b"")
    text = unchecked(raw)
    if text is None:
        old = _banner(raw.decode("ascii", "replace"))
        if old is not None and old.protocol_version != PROTOCOL_VERSION:
            return Reply("banner", text=raw.decode("ascii"), banner=old)
        raise ProtocolError(f"garbled reply from the machine (its check fails): {raw!r}")
    return reply_of_text(text.decode("ascii", "replace"))


def reply_of_text(text: str) -> Reply:
    """Decode the text of a firmware line whose check held."""
    if (m := _OK_RE.match(text)) is not None:
        payload = m.group(2) or ""
        return Reply("ok", int(m.group(1)), text=payload, status=_status(payload),
                     banner=_banner(payload))
    if (m := _CODE_RE.match(text)) is not None:
        return Reply(m.group(1), None if m.group(3) is None else int(m.group(3)),
                     int(m.group(2)), m.group(4) or "")
    if text.startswith("rs N") and text[4:].isdigit():
        return Reply("rs", int(text[4:]))
    if (status := _status(text)) is not None:
        return Reply("status", status.last_seq, text=text, status=status)
    if (banner := _banner(text)) is not None:
        return Reply("banner", text=text, banner=banner)
    raise ProtocolError(f"unexpected reply from the machine: {text!r}")


def check_banner(banner: Banner) -> Banner:
    """Refuse firmware whose protocol version differs from ours."""
    if banner.protocol_version != PROTOCOL_VERSION:
        raise ProtocolVersionError(
            f"firmware {banner.firmware_version} speaks protocol {banner.protocol_version}, "
            f"this host speaks {PROTOCOL_VERSION}: update the firmware (make -C firmware) "
            f"or the host")
    return banner


_SOFT_LIMIT_RE = re.compile(r"([XYZ]) would reach (-?\d+), (below|above) (-?\d+)")


def soft_limit_detail(axis: str, value: int, limit: int) -> str:
    """The firmware's detail after `error:5 soft limit: ` (machine steps)."""
    return f"{axis} would reach {value}, {'above' if value > limit else 'below'} {limit}"


def parse_soft_limit(text: str) -> tuple[str, int, int] | None:
    """(axis, value, limit) from a soft-limit refusal's text, None if it is none."""
    m = _SOFT_LIMIT_RE.search(text)
    return None if m is None else (m.group(1), int(m.group(2)), int(m.group(4)))


def format_error(code: int, seq: int | None = None, detail: str = "") -> str:
    """The firmware's error reply text for `code` (used by the simulated machine)."""
    spec = ERROR_BY_CODE[code]
    prefix = "alarm" if spec.alarm else "error"
    where = "" if seq is None else f" N{seq}"
    return f"{prefix}:{code}{where} {spec.text}{(': ' + detail) if detail else ''}"
