"""The wire protocol's one definition: the line check, framing, commands, replies, headers."""

from pathlib import Path

import pytest
from hypothesis import given, strategies as st

from firmware_support import framed as _framed
from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.firmware_headers import config_header, protocol_header
from galileo_cnc.job import (ArcTo, Dwell, EndJob, Flash, Home, Jog, LineTo, Motors, PenDown,
                             PenUp, Rapid, SetFeed, SetOrigin)
from galileo_cnc.protocol.codec import first_range_problem, range_problem

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "galileo"

coord = st.integers(P.COORD.lo, P.COORD.hi)
commands = st.one_of(
    st.builds(Rapid, coord, coord),
    st.builds(LineTo, coord, coord),
    st.builds(LineTo, coord, coord, coord),
    st.builds(ArcTo, coord, coord, coord, coord, st.booleans()),
    st.just(PenUp()), st.just(PenDown()),
    st.builds(Flash), st.builds(Flash, st.integers(P.MS.lo, P.MS.hi)),
    st.builds(Dwell, st.integers(P.MS.lo, P.MS.hi)),
    st.builds(SetFeed, st.integers(P.FEED.lo, P.FEED.hi)),
    st.builds(Jog, coord, coord, coord),
    st.just(SetOrigin()), st.just(Home()), st.builds(Motors, st.booleans()), st.just(EndJob()),
    st.just(P.QueryStatus()), st.just(P.QueryVersion()), st.just(P.Unlock()),
)


def test_crc16_is_crc16_ccitt_false():
    assert P.crc16(b"123456789") == 0x29B1  # the catalogue check value of CRC-16/CCITT-FALSE
    assert P.crc16(b"") == 0xFFFF


def test_crc16_catches_what_xor_misses():
    # XOR is blind to order and to a dropped pair of equal bytes; the CRC is not.
    def xor(data):
        out = 0
        for b in data:
            out ^= b
        return out
    assert xor(b"N12 L 100 20") == xor(b"N21 L 100 20")
    assert P.crc16(b"N12 L 100 20") != P.crc16(b"N21 L 100 20")
    assert xor(b"N5 L 100 0") == xor(b"N5 L 1 0")
    assert P.crc16(b"N5 L 100 0") != P.crc16(b"N5 L 1 0")


def test_frame_line_format():
    line = P.encode_command(LineTo(100, -20), 7)        # 12 bytes of text: `*`
    assert line == b"N7 L 100 -20*%04X\n" % P.crc16(b"N7 L 100 -20*")
    line = P.encode_command(LineTo(100, -2), 7)         # 11 bytes: `#`
    assert line == b"N7 L 100 -2#%04X\n" % P.crc16(b"N7 L 100 -2#")
    assert P.encode_command(ArcTo(1, 2, 3, 4, cw=True), 8).startswith(b"N8 CW 1 2 3 4")
    assert P.encode_command(ArcTo(1, 2, 3, 4, cw=False), 9).startswith(b"N9 CCW 1 2 3 4")
    assert P.encode_command(Flash(), 1).startswith(b"N1 FL")
    assert P.encode_command(Motors(True), 1).startswith(b"N1 M 1")
    assert P.unchecked(line[:-1]) == b"N7 L 100 -2"
    assert P.unchecked(line[:-6] + b"*" + line[-5:-1]) is None     # the other separator
    assert P.unchecked(line[:-1].lower()) is None                  # hex is upper-case


def _received(wire: bytes) -> list[bytes]:
    """The lines a receiver assembles from `wire` (`\r` ignored, `\n` ends a line)."""
    return [line for line in wire.replace(b"\r", b"").split(b"\n") if line]


def _single_byte_errors(line: bytes):
    """Every line one byte fault away from `line` (its newline kept): each byte dropped,
    doubled, or with one of its bits flipped."""
    text = line[:-1]
    for i in range(len(text)):
        yield text[:i] + text[i + 1:] + b"\n"
        yield text[:i + 1] + text[i:] + b"\n"
        for bit in range(8):
            yield text[:i] + bytes((text[i] ^ 1 << bit,)) + text[i + 1:] + b"\n"


def _real_lines() -> list[bytes]:
    """What goes over the wire for the sample board, both ways: its commands at the
    sequence numbers they get (and a few more), and the machine's replies to them."""
    from galileo_cnc.machine import simulate
    from galileo_cnc.plan.offsets import proposed_offset
    from galileo_cnc.plan.planner import plan_program
    from galileo_cnc.readers import read_file
    program = read_file(Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr")
    job = plan_program(program, None, proposed_offset(program))
    lines = []
    for seq0 in (1, 9_990, P.SEQ_MAX - len(job)):
        for k, cmd in enumerate(job.commands):
            seq = seq0 + k
            lines.append(P.encode_command(cmd, seq))
            lines.append(P.checked(b"ok N%d" % seq))
            lines.append(P.checked(b"rs N%d" % seq))
    end = simulate(job.commands).final_position
    lines.append(P.checked(P.Status("idle", *end, 0, len(job)).text().encode()))
    lines.append(P.checked(P.format_error(5, 12, "X would reach -5, below 0").encode()))
    return lines


def test_every_single_byte_fault_of_real_lines_is_detected():
    """A dropped or doubled byte (an overrun, a framing error) shifts the rest of the
    line; one CRC-8 in 256 let it through (protocol 3). The separator's parity catches
    every one of them and CRC-16 every flipped bit: no such line is believed."""
    lines = _real_lines()
    assert len(lines) > 400
    believed, tried = [], 0
    for line in lines:
        assert P.unchecked(line[:-1]) is not None
        for garbled in _single_byte_errors(line):
            tried += 1
            believed += [(line, garbled) for text in _received(garbled)
                         if P.unchecked(text) is not None]
    assert tried > 70_000 and believed == []


@given(commands, st.integers(0, P.SEQ_MAX))
def test_every_command_round_trips_within_the_line_limit(cmd, seq):
    line = P.encode_command(cmd, seq)
    assert len(line) <= P.MAX_LINE_BYTES and line.endswith(b"\n")
    decoded = P.decode_line(line)
    assert (decoded.seq, decoded.command) == (seq, cmd)
    assert P.unchecked(line[:-1]).split(b" ")[1] == decoded.mnemonic.encode()


def test_the_longest_line_fits():
    worst = ArcTo(P.COORD.lo, P.COORD.lo, P.COORD.lo, P.COORD.lo, cw=False)
    assert len(P.encode_command(worst, P.SEQ_MAX)) <= P.MAX_LINE_BYTES


def test_out_of_range_arguments_are_refused_on_the_host():
    with pytest.raises(P.ProtocolError):
        P.encode_command(LineTo(P.COORD.hi + 1, 0), 1)
    with pytest.raises(P.ProtocolError):
        P.encode_command(Dwell(-1), 1)
    with pytest.raises(P.ProtocolError):
        P.frame_line(P.SEQ_MAX + 1, "S")


@given(st.lists(st.one_of(commands, st.builds(LineTo, coord, coord, st.integers())),
                max_size=8),
       st.integers(-10 ** 12, 10 ** 12), st.sampled_from([Rapid, ArcTo, Dwell, SetFeed, Jog]))
def test_the_planners_range_check_finds_what_range_problem_finds(job, value, kind):
    # one command with a value that may be out of range, somewhere in a valid job
    bad = {Rapid: lambda: Rapid(0, value), ArcTo: lambda: ArcTo(1, 2, value, 0, cw=False),
           Dwell: lambda: Dwell(value), SetFeed: lambda: SetFeed(value),
           Jog: lambda: Jog(0, 0, value)}[kind]()
    job = job[:len(job) // 2] + [bad] + job[len(job) // 2:]
    expected = next(((at, problem) for at, command in enumerate(job)
                     if (problem := range_problem(command)) is not None), None)
    assert first_range_problem(job) == expected


@pytest.mark.parametrize("raw, resend, code", [
    (b"N3 L 1 2*0000\n", True, None),               # wrong checksum
    (b"N3 L 1 2\n", True, None),                    # no checksum
    (b"garbage\n", True, None),
    (b"N" + b"9" * 70 + b"\n", False, 2),           # over-long
])
def test_decode_rejections(raw, resend, code):
    with pytest.raises(P.LineRejected) as info:
        P.decode_line(raw)
    assert info.value.resend is resend and info.value.code == code


@pytest.mark.parametrize("body, code", [
    (b"L 1 2", 1),           # no sequence number
    (b"N3 XYZ 1", 3),        # unknown mnemonic
    (b"N3 L 1", 4),          # too few arguments
    (b"N3 L 1 2 3 4", 4),    # too many
    (b"N3 M 2", 4),          # flag out of range
    (b"N3 DW -1", 4),
])
def test_decode_errors_with_codes(body, code):
    with pytest.raises(P.LineRejected) as info:
        P.decode_line(_framed(body))
    assert info.value.code == code and not info.value.resend


def test_sequence_rules():
    assert P.decode_line(_framed(b"N5 S"), expected_seq=5)[0] == 5
    with pytest.raises(P.LineRejected) as info:
        P.decode_line(_framed(b"N6 S"), expected_seq=5)
    assert info.value.resend
    assert P.decode_line(_framed(b"N0 S"), expected_seq=5)[0] == 0  # N0 always resyncs
    assert P.next_seq(P.SEQ_MAX) == 1 and P.next_seq(1) == 2


def test_parse_replies():
    def parse(text: str) -> P.Reply:
        return P.parse_reply(P.checked(text.encode()))
    assert P.parse_reply(b"ok N12*%04X\n" % P.crc16(b"ok N12*")) == P.Reply("ok", 12)
    r = parse("error:5 N13 soft limit: X would reach -1, below 0")
    assert (r.kind, r.seq, r.code, r.error.name) == ("error", 13, 5, "SOFT_LIMIT")
    assert r.text.startswith("soft limit")
    r = parse("error:2 line too long")
    assert (r.kind, r.seq, r.code) == ("error", None, 2)
    assert parse("rs N4") == P.Reply("rs", 4)
    r = parse("alarm:11 end-stop not found")
    assert r.kind == "alarm" and r.error.alarm
    assert parse("msg:13 step interrupt overrun, timing slipped").kind == "msg"
    status = P.Status("run", -5, 7, 300, 3, 41)
    r = parse(status.text())
    assert r.kind == "status" and r.status == status
    r = parse("ok N2 " + status.text())
    assert r.kind == "ok" and r.seq == 2 and r.status == status
    banner = P.Banner(P.FIRMWARE_VERSION, P.PROTOCOL_VERSION, P.RX_BUFFER_BYTES, P.QUEUE_BLOCKS,
                      "60d6fe2c")
    r = P.parse_reply(P.checked(banner.text().encode())[:-1] + b"\r\n")
    assert r.kind == "banner" and r.banner == banner
    # a banner of protocol 3 or older carries no check: read, so that it can be refused
    old = P.parse_reply("galileo-cnc 0.1.0 proto 1 rx 128 queue 8")   # before the digest
    assert old.banner.protocol_version == 1 and old.banner.config_digest == ""
    with pytest.raises(P.ProtocolVersionError):
        P.check_banner(old.banner)
    with pytest.raises(P.ProtocolError):
        parse("hello there")
    with pytest.raises(P.ProtocolError, match="check"):    # garbled: not believed
        P.parse_reply(P.checked(b"ok N12").replace(b"N12", b"N13"))
    with pytest.raises(P.ProtocolError, match="check"):
        P.parse_reply(b"ok N12\n")                          # no check at all


def test_host_refuses_other_protocol_versions():
    good = P.Banner("0.1.0", P.PROTOCOL_VERSION, 128, 8)
    assert P.check_banner(good) is good
    with pytest.raises(P.ProtocolVersionError):
        P.check_banner(P.Banner("9.9.9", P.PROTOCOL_VERSION + 1, 128, 8))


def test_error_table_is_consistent():
    codes = [e.code for e in P.ERRORS]
    assert len(set(codes)) == len(codes) and min(codes) >= 1
    assert len({e.name for e in P.ERRORS}) == len(codes)
    assert P.format_error(5, 3, "X") == "error:5 N3 soft limit: X"
    assert P.format_error(11) == "alarm:11 end-stop not found"


def test_no_single_bit_error_of_line_text_makes_a_realtime_byte():
    # exhaustive: every byte a line can hold (printable ASCII and `\n`), every bit
    alphabet = set(range(0x20, 0x7F)) | {0x0A}
    assert P.LINE_TEXT_BYTES == alphabet
    realtime = {byte[0] for byte in P.REALTIME_BYTES.values()}
    assert len(realtime) == 4
    for text in alphabet:
        assert text not in realtime
        for bit in range(8):
            assert text ^ (1 << bit) not in realtime, (hex(text), bit)
    # nor does one flipped bit turn one real-time byte into another
    for a in realtime:
        for b in realtime - {a}:
            assert bin(a ^ b).count("1") >= 2
    # every line the encoder can write stays within that alphabet
    for spec in P.COMMANDS:
        kwargs = dict(spec.fixed)
        kwargs.update({field: kind.lo for field, kind in spec.args})
        line = P.encode_command(spec.cls(**kwargs), P.SEQ_MAX)
        assert set(line) <= alphabet, line


def test_committed_protocol_header_is_generated():
    assert (FIRMWARE / "protocol.h").read_text() == protocol_header(), \
        "regenerate: python -m galileo_cnc.firmware_headers"


def test_committed_config_header_is_generated():
    assert (FIRMWARE / "config.h").read_text() == config_header(MachineConfig()), \
        "regenerate: python -m galileo_cnc.firmware_headers"


def test_protocol_header_carries_the_definition():
    text = protocol_header()
    assert f"#define PROTO_VERSION {P.PROTOCOL_VERSION}" in text
    assert "#define PROTO_CHECK_SEP_EVEN '*'" in text and "#define PROTO_CHECK_SEP_ODD '#'" in text
    for e in P.ERRORS:
        assert f"ERR_{e.name} = {e.code}," in text and f'"{e.text}"' in text
    for spec in P.COMMANDS:
        assert (f'{{"{spec.mnemonic}", {spec.min_args}, {len(spec.args)}, {spec.blocks},'
                in text)


def test_sequence_is_checked_before_the_command_as_the_firmware_does():
    with pytest.raises(P.LineRejected) as info:
        P.decode_line(_framed(b"N7 zap"), expected_seq=5)
    assert info.value.resend and info.value.seq is None
    with pytest.raises(P.LineRejected) as info:
        P.decode_line(_framed(b"N5 zap"), expected_seq=5)
    assert (info.value.code, info.value.seq) == (3, 5)  # matched, then refused


def test_what_the_wire_cannot_carry_is_said_in_mm_with_the_wire_form_in_brackets():
    # issue 31 item 14: `Rapid: x_steps=-159999992640` reached the user
    steps_per_mm = MachineConfig().steps_per_mm
    assert first_range_problem([Rapid(1, 2), Rapid(-159999992640, 5)], steps_per_mm) == (
        1, "X -999999954.000 mm is beyond what a machine command carries (X -62499.994 mm .. "
           "X 62499.994 mm) [x_steps=-159999992640 outside -9999999..9999999]")
    assert first_range_problem([SetFeed(160_000_000)], steps_per_mm) == (
        0, "feed 1000000 mm/s is beyond what a machine command carries (feed 0 mm/s .. feed "
           "62499.99375 mm/s) [feed_steps_per_s=160000000 outside 0..9999999]")
    assert first_range_problem([Dwell(10**10)], steps_per_mm) == (
        0, "a dwell of 10000000 s is longer than a machine command carries (2000 s at most) "
           "[ms=10000000000 outside 0..2000000]")          # a dwell in seconds, as G4 P
