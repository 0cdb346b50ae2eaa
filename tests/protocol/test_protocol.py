"""The wire protocol's one definition: framing, CRC-8, commands, replies, headers."""

from pathlib import Path

import pytest
from hypothesis import given, strategies as st

from firmware_support import framed as _framed
from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.firmware_headers import config_header, protocol_header
from galileo_cnc.job import (ArcTo, Dwell, EndJob, Flash, Home, Jog, LineTo, Motors, PenDown,
                             PenUp, Rapid, SetFeed, SetOrigin)

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


def test_crc8_is_crc8_smbus():
    assert P.crc8(b"123456789") == 0xF4  # the catalogue check value of CRC-8/SMBUS
    assert P.crc8(b"") == 0


def test_crc8_catches_what_xor_misses():
    # XOR is blind to order and to a dropped pair of equal bytes; CRC-8 is not.
    def xor(data):
        out = 0
        for b in data:
            out ^= b
        return out
    assert xor(b"N12 L 100 20") == xor(b"N21 L 100 20")
    assert P.crc8(b"N12 L 100 20") != P.crc8(b"N21 L 100 20")
    assert xor(b"N5 L 100 0") == xor(b"N5 L 1 0")
    assert P.crc8(b"N5 L 100 0") != P.crc8(b"N5 L 1 0")


def test_frame_line_format():
    line = P.encode_command(LineTo(100, -20), 7)
    assert line == b"N7 L 100 -20*%02X\n" % P.crc8(b"N7 L 100 -20")
    assert P.encode_command(ArcTo(1, 2, 3, 4, cw=True), 8).startswith(b"N8 CW 1 2 3 4*")
    assert P.encode_command(ArcTo(1, 2, 3, 4, cw=False), 9).startswith(b"N9 CCW 1 2 3 4*")
    assert P.encode_command(Flash(), 1).startswith(b"N1 FL*")
    assert P.encode_command(Motors(True), 1).startswith(b"N1 M 1*")


@given(commands, st.integers(0, P.SEQ_MAX))
def test_every_command_round_trips_within_the_line_limit(cmd, seq):
    line = P.encode_command(cmd, seq)
    assert len(line) <= P.MAX_LINE_BYTES and line.endswith(b"\n")
    decoded = P.decode_line(line)
    assert (decoded.seq, decoded.command) == (seq, cmd)
    assert line.split(b" ")[1].split(b"*")[0] == decoded.mnemonic.encode()


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


@pytest.mark.parametrize("raw, resend, code", [
    (b"N3 L 1 2*00\n", True, None),                 # wrong checksum
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
    assert P.parse_reply(b"ok N12\n") == P.Reply("ok", 12)
    r = P.parse_reply("error:5 N13 soft limit: X would reach -1, below 0")
    assert (r.kind, r.seq, r.code, r.error.name) == ("error", 13, 5, "SOFT_LIMIT")
    assert r.text.startswith("soft limit")
    r = P.parse_reply("error:2 line too long")
    assert (r.kind, r.seq, r.code) == ("error", None, 2)
    assert P.parse_reply("rs N4") == P.Reply("rs", 4)
    r = P.parse_reply("alarm:11 end-stop not found")
    assert r.kind == "alarm" and r.error.alarm
    assert P.parse_reply("msg:13 step interrupt overrun, timing slipped").kind == "msg"
    status = P.Status("run", -5, 7, 300, 3, 41)
    r = P.parse_reply(status.text())
    assert r.kind == "status" and r.status == status
    r = P.parse_reply("ok N2 " + status.text())
    assert r.kind == "ok" and r.seq == 2 and r.status == status
    banner = P.Banner(P.FIRMWARE_VERSION, P.PROTOCOL_VERSION, P.RX_BUFFER_BYTES, P.QUEUE_BLOCKS,
                      "60d6fe2c")
    r = P.parse_reply(banner.text() + "\r\n")
    assert r.kind == "banner" and r.banner == banner
    old = P.parse_reply("galileo-cnc 0.1.0 proto 1 rx 128 queue 8")   # before the digest
    assert old.banner.protocol_version == 1 and old.banner.config_digest == ""
    with pytest.raises(P.ProtocolVersionError):
        P.check_banner(old.banner)
    with pytest.raises(P.ProtocolError):
        P.parse_reply("hello there")


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
