"""Properties of the G-code reader and writer, checked with hypothesis.

- Any input, however broken, gives a Program or a GcodeError, nothing else.
- The short path for plain G0/G1 lines and the general path agree.
- Numbers and R-form arc centres are exact: the nearest nanometre.
- write_gcode then read_gcode gives the same ops back.
"""

from __future__ import annotations

import contextlib
import tempfile
from decimal import Decimal, localcontext
from fractions import Fraction
from math import isqrt
from pathlib import Path

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from galileo_cnc.errors import GcodeError
from galileo_cnc.program.ops import NO_TOOL, OpKind, ProgramBuilder
from galileo_cnc.readers.gcode import read_gcode, write_gcode
from galileo_cnc.readers.gcode.arcs import r_form_centre_offset, round_half_away
from galileo_cnc.readers.gcode.lexer import scaled
from galileo_cnc.readers.gcode.reader import _FAST_LINE, _Reader

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "square-and-circle.nc"

RICH_PROGRAM = """%
(a bit of everything the reader knows)
N1 G21 G90 G17 G94 ; preamble
N2 F1200 T1 M6
N3 G0 X10.5 Y-2 Z5
N4 M3 S1000
N5 G1 X20 Y0
Y10
N8 G2 X10 Y10 I-5 J0
G3 X0 Y0 R-10
G91 G1 X1.25 Y.5
G90 G92 X0 Y0
G1 Z-0.5 X3
G0 X7 Y7
G1 X8
G4 P250
G04 X0.5
G20 F10 X0.1 Y0.1
G21 G28 X1 Y1
N20 G1 X1*83
M5
M30
%
"""
SEEDS = [RICH_PROGRAM, SAMPLE.read_text()]

GCODE_ALPHABET = "GMNXYZIJRFPTS0123456789.-+ ()*;%\n\tgxyz"
FUZZ = settings(max_examples=400, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@contextlib.contextmanager
def general_path_only():
    _Reader.use_fast_path = False
    try:
        yield
    finally:
        _Reader.use_fast_path = True


def outcome(text: str):
    """The op table (without positions) and warnings, or the error, as comparable data."""
    try:
        program = read_gcode("fuzz.nc", text)
    except GcodeError as err:
        return ("error", str(err))
    return ("ok", program.table.tolist(), [str(w) for w in program.warnings],
            program.units, program.metadata)


def both_paths(text: str):
    fast = outcome(text)
    with general_path_only():
        general = outcome(text)
    assert fast == general
    return fast


# ---- robustness ---------------------------------------------------------------

@FUZZ
@given(st.binary(max_size=300))
def test_random_bytes_give_a_program_or_a_gcode_error(data):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.nc"
        path.write_bytes(data)
        with contextlib.suppress(GcodeError):
            read_gcode(path)
    both_paths(data.decode("utf-8", "replace"))


@FUZZ
@given(st.text(max_size=200))
def test_random_text_gives_a_program_or_a_gcode_error(text):
    both_paths(text)


@FUZZ
@given(st.text(alphabet=GCODE_ALPHABET, max_size=200))
def test_gcode_like_noise_gives_a_program_or_a_gcode_error(text):
    both_paths(text)


@st.composite
def mutated_programs(draw):
    text = draw(st.sampled_from(SEEDS))
    for _ in range(draw(st.integers(1, 6))):
        at = draw(st.integers(0, len(text)))
        action = draw(st.sampled_from(["insert", "delete", "replace", "duplicate"]))
        if action == "insert":
            text = text[:at] + draw(st.text(alphabet=GCODE_ALPHABET, min_size=1, max_size=4)) + text[at:]
        elif action == "delete":
            text = text[:at] + text[at + draw(st.integers(1, 8)):]
        elif action == "replace" and at < len(text):
            text = text[:at] + draw(st.characters()) + text[at + 1:]
        else:
            end = at + draw(st.integers(1, 40))
            text = text[:at] + text[at:end] + text[at:]
    return text


@FUZZ
@given(mutated_programs())
def test_mutated_programs_give_a_program_or_a_gcode_error(text):
    both_paths(text)


blanks = st.sampled_from(["", " ", "\t", "  "])


@st.composite
def short_path_numbers(draw):
    """Numbers around the short path's limits of 6 integer and 6 decimal digits."""
    sign = draw(st.sampled_from(["", "-", "+"]))
    whole = draw(st.text("0123456789", max_size=7))
    fraction = draw(st.text("0123456789", max_size=7))
    dot = "." if draw(st.booleans()) or not whole else ""
    if not whole and not fraction:
        whole = "0"
    return sign + whole + dot + fraction


@st.composite
def short_path_lines(draw):
    """[N..] [G0|G1] [X..] [Y..] [F..] [; ..] with the spellings and spacing files use."""
    parts = [draw(blanks)]
    if draw(st.booleans()):
        parts.append(f"{draw(st.sampled_from('Nn'))}{draw(blanks)}{draw(st.integers(0, 10**13))} ")
    if draw(st.booleans()):
        parts.append(draw(st.sampled_from(["G0", "G1", "g01", "G00", "G1.0", "G0.", "G2", "G10"])))
    for letter in draw(st.sampled_from(["X", "Y", "XY", "xy", "YX", ""])):
        parts.append(f"{draw(blanks)}{letter}{draw(blanks)}{draw(short_path_numbers())}")
    if draw(st.booleans()):
        feed = draw(st.sampled_from(["F1500", "f 0.5", "F0", "F.00001", "F1234567", "F-5", "F9."]))
        parts.append(f"{draw(blanks)}{feed}")
    parts.append(draw(st.sampled_from(["", " ", "; note", " ;(x*1)", " (c)"])))
    return "".join(parts)


@settings(max_examples=300, deadline=None)
@given(st.lists(short_path_lines(), max_size=8),
       st.sampled_from(["", "G91\n", "G20\n", "M3\n", "G2 X0 I1\n", "G92 X1 Y-1\n", "M2\n"]))
def test_lines_the_short_path_takes_read_as_on_the_general_path(lines, prefix):
    both_paths(prefix + "\n".join(lines))


def test_the_short_path_is_taken():
    text = "N7 G1 X1.5 Y-2 F600 ; go\nX3\nG0\nF100\n"
    for line in text.splitlines():
        assert _FAST_LINE.fullmatch(line)
    assert both_paths(text)[0] == "ok"


# ---- exact numbers ------------------------------------------------------------

decimal_texts = st.builds(
    lambda sign, whole, fraction, dot: sign + whole + ("." + fraction if dot or not whole else ""),
    st.sampled_from(["", "-", "+"]), st.text("0123456789", max_size=7),
    st.text("0123456789", min_size=1, max_size=24), st.booleans())


@given(decimal_texts, st.sampled_from([(1_000_000, 1), (25_400_000, 1), (1_000_000, 60),
                                       (25_400_000, 60), (1, 1), (1000, 1)]))
def test_decimal_numbers_round_half_away_from_zero_exactly(text, scale_divisor):
    scale, divisor = scale_divisor
    exact = Fraction(text) * scale / divisor
    expected = round_half_away(exact.numerator, exact.denominator)
    assert scaled(text, scale, divisor) == expected


def _exact_centre(dx: int, dy: int, r: int, clockwise: bool):
    with localcontext() as ctx:
        ctx.prec = 80
        chord_sq = Decimal(dx * dx + dy * dy)
        k = ((4 * Decimal(r) ** 2 - chord_sq) / chord_sq).sqrt()
        s = 1 if (r > 0) != clockwise else -1
        return (Decimal(dx) - s * dy * k) / 2, (Decimal(dy) + s * dx * k) / 2


coordinate = st.integers(-10**9, 10**9)


@given(coordinate, coordinate, st.integers(0, 10**9), st.booleans(), st.booleans())
def test_r_form_centre_is_the_nearest_nanometre(dx, dy, extra, clockwise, long_way):
    assume((dx, dy) != (0, 0))
    r = (isqrt(dx * dx + dy * dy) + 2) // 2 + extra  # at least half the chord
    if long_way:
        r = -r
    i, j = r_form_centre_offset(dx, dy, r, clockwise)
    exact_i, exact_j = _exact_centre(dx, dy, r, clockwise)
    assert abs(i - exact_i) <= Decimal("0.5") and abs(j - exact_j) <= Decimal("0.5")


@given(st.integers(1, 10**4), st.integers(1, 100), st.integers(1, 100), st.booleans(),
       st.sampled_from([(1, 1), (1, -1), (-1, 1), (-1, -1)]))
def test_r_form_centre_is_exact_when_the_geometry_is(scale, m, n, swap, signs):
    # A Pythagorean triple puts the start (the origin) on an integer circle about
    # (i, j); the end is the start mirrored through the centre's horizontal line.
    assume(m != n)
    i, j, r = scale * (m * m - n * n), scale * 2 * m * n, scale * (m * m + n * n)
    if swap:
        i, j = j, i
    i, j = i * signs[0], j * signs[1]
    assume(j != 0)
    centres = {r_form_centre_offset(0, 2 * j, sign * r, clockwise)
               for sign in (1, -1) for clockwise in (True, False)}
    assert centres == {(i, j), (-i, j)}


# ---- round trip ---------------------------------------------------------------

def mm_text(nm: int, decimals: int = 6) -> str:
    """nm as a millimetre decimal string (exact for 6 decimals)."""
    sign = "-" if nm < 0 else ""
    whole, fraction = divmod(abs(nm), 1_000_000)
    return f"{sign}{whole}.{fraction:06d}"[: len(f"{sign}{whole}.") + decimals]


lengths = st.integers(-200_000_000, 200_000_000)  # +-200 mm in nm


def decorate(draw, words: str) -> str:
    """Maybe a line number in front, a comment behind."""
    if draw(st.booleans()):
        words = f"N{draw(st.integers(0, 99999))} {words}"
    return words + draw(st.sampled_from(["", " ; note", " (note)", "  "]))


def restore(inch: bool, absolute: bool) -> str:
    """The line that puts units and distance mode back after an arc written in mm, G91."""
    return ("G20 " if inch else "G21 ") + ("G90" if absolute else "G91")


@st.composite
def gcode_programs(draw):
    """Valid G-code touching every feature, and arcs that close exactly."""
    lines = ["G21 G90"]
    inch = False
    absolute = True
    straight_motion = True  # a line of bare coordinates would be an arc after G2/G3
    for _ in range(draw(st.integers(0, 30))):
        kind = draw(st.sampled_from(["G0", "G1", "modal", "arc", "r-arc", "pen", "z", "feed",
                                     "tool", "dwell", "units", "distance", "g92", "g28", "comment"]))
        # Lengths are drawn in nm and written with 6 (mm) or 5 (inch) decimals.
        def num():
            value = draw(lengths)
            return mm_text(value, 5 if inch else draw(st.integers(0, 6)))
        if kind in ("arc", "r-arc"):
            straight_motion = False
        if kind == "modal" and not straight_motion:
            kind = "G1"
        if kind in ("G0", "G1"):
            straight_motion = True
            axes = draw(st.sampled_from(["X", "Y", "XY"]))
            code = draw(st.sampled_from([kind, kind.lower(), kind[0] + "0" + kind[1], kind + ".0"]))
            lines.append(decorate(draw, code + "".join(f" {a}{num()}" for a in axes)))
        elif kind == "modal":
            lines.append(decorate(draw, f"X{num()} Y{num()}"))
        elif kind == "arc":
            i, j = draw(lengths) // 10, draw(lengths) // 10
            assume((i, j) != (0, 0))
            rx, ry = -i, -j  # start relative to the centre, turned k quarter turns
            for _ in range(draw(st.integers(0, 3))):
                rx, ry = -ry, rx
            code = draw(st.sampled_from(["G2", "G3"]))
            lines += ["G21 G91", f"{code} X{mm_text(i + rx)} Y{mm_text(j + ry)} "
                      f"I{mm_text(i)} J{mm_text(j)}", restore(inch, absolute)]
        elif kind == "r-arc":
            dx, dy = draw(lengths) // 10, draw(lengths) // 10
            assume((dx, dy) != (0, 0))
            r = isqrt(dx * dx + dy * dy) // 2 + 10_000 + draw(st.integers(0, 10**7))
            r = -r if draw(st.booleans()) else r
            code = draw(st.sampled_from(["G2", "G3"]))
            lines += ["G21 G91", f"{code} X{mm_text(dx)} Y{mm_text(dy)} R{mm_text(r)}",
                      restore(inch, absolute)]
        elif kind == "pen":
            lines.append(draw(st.sampled_from(["M3", "M5", "M03", "M4", "M05"])))
        elif kind == "z":
            lines.append(f"Z{draw(st.sampled_from(['-1', '0', '0.5', '5', '-0.001']))}")
        elif kind == "feed":
            lines.append(f"F{draw(st.integers(1, 5000))}.{draw(st.integers(0, 99))}")
        elif kind == "tool":
            lines.append(f"T{draw(st.integers(0, 20))} M6")
        elif kind == "dwell":
            lines.append(draw(st.sampled_from(["G4 P", "G04 X"])) + str(draw(st.integers(0, 3000))))
        elif kind == "units":
            inch = draw(st.booleans())
            lines.append("G20" if inch else "G21")
        elif kind == "distance":
            absolute = draw(st.booleans())
            lines.append("G90" if absolute else "G91")
        elif kind == "g92":
            lines.append(draw(st.sampled_from(["G92", f"G92 X{num()}", f"G92 X{num()} Y{num()}",
                                               "G92.1", "G92 Z0"])))
        elif kind == "g28":
            lines.append(draw(st.sampled_from(["G28", f"G28 X{num()} Y{num()}"])))
        else:
            lines.append(draw(st.sampled_from(["(note)", "; note", ""])))
    lines.append(draw(st.sampled_from(["M2", "M30", ""])))
    return "\n".join(lines) + "\n"


def same_ops(a, b) -> bool:
    return a.table[:, :7].tolist() == b.table[:, :7].tolist()


@settings(max_examples=300, deadline=None)
@given(gcode_programs())
def test_generated_gcode_reads_the_same_on_both_paths_and_round_trips(text):
    result = both_paths(text)
    assert result[0] == "ok", result
    program = read_gcode("gen.nc", text)
    written = write_gcode(program)
    again = read_gcode("written.nc", written)
    assert same_ops(again, program), written
    assert again.metadata["home_rows"] == program.metadata["home_rows"]
    assert write_gcode(again).splitlines()[1:] == written.splitlines()[1:]


@st.composite
def op_programs(draw):
    """Programs built op by op, in the form any reader leaves them."""
    builder = ProgramBuilder("ops")
    tool, feed = NO_TOOL, None
    home_rows = []
    x = y = 0
    for _ in range(draw(st.integers(0, 40))):
        kind = draw(st.sampled_from(list(OpKind)[:10]))
        if kind == OpKind.FLASH:
            continue
        if kind in (OpKind.MOVE, OpKind.LINE):
            if kind == OpKind.MOVE and draw(st.booleans()) and draw(st.booleans()):
                home_rows.append(builder.count())
                x, y = 0, 0
            else:
                x, y = draw(lengths) * 5, draw(lengths) * 5
            builder.emit(int(kind), x, y, tool=tool if kind == OpKind.LINE else NO_TOOL)
        elif kind in (OpKind.ARC_CW, OpKind.ARC_CCW):
            i, j = draw(lengths), draw(lengths)
            assume((i, j) != (0, 0))
            rx, ry = -i, -j
            for _ in range(draw(st.integers(0, 3))):
                rx, ry = -ry, rx
            x, y = x + i + rx, y + j + ry
            builder.emit(int(kind), x, y, i, j, tool)
        elif kind == OpKind.SELECT:
            tool = draw(st.integers(0, 99))
            builder.emit(int(kind), tool=tool)
        elif kind == OpKind.DWELL:
            builder.emit(int(kind), value=draw(st.integers(0, 10**7)))
        elif kind == OpKind.FEED:
            value = draw(st.integers(1, 10**9))
            if value != feed:
                feed = value
                builder.emit(int(kind), value=value)
        else:
            builder.emit(int(kind))
    return builder.build("gcode", "mm", metadata={"home_rows": home_rows})


@settings(max_examples=300, deadline=None)
@given(op_programs())
def test_programs_written_as_gcode_read_back_to_the_same_ops(program):
    again = read_gcode("written.nc", write_gcode(program))
    assert same_ops(again, program)
    assert again.metadata["home_rows"] == program.metadata["home_rows"]
