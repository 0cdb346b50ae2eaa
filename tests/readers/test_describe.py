"""Ops in words and mm for messages (program/describe.py; issue 31, item 14)."""

import pytest

from galileo_cnc.program.describe import describe_op, mm_text
from galileo_cnc.program.ops import NO_TOOL, Aperture, OpKind, ProgramBuilder

K = OpKind
MM = 1_000_000


def _program(fmt, *rows):
    builder = ProgramBuilder("t")
    for row in rows:
        builder.emit(*row)
    apertures = {10: Aperture(10, "circle", (500_000,))} if fmt == "gerber" else {}
    return builder.build(fmt, "mm", apertures=apertures)


ROWS = [(int(K.MOVE), 195 * MM, 10 * MM), (int(K.PEN_DOWN), 195 * MM, 10 * MM),
        (int(K.ARC_CCW), 195 * MM, 30 * MM, 0, 10 * MM, 10),
        (int(K.ARC_CW), 195 * MM, 10 * MM, 0, -10 * MM, 10),
        (int(K.LINE), 12_345_600, -250_000, 0, 0, 10), (int(K.FLASH), 1 * MM, 2 * MM, 0, 0, 10),
        (int(K.SELECT), 0, 0, 0, 0, 10), (int(K.PEN_UP),), (int(K.DWELL), 0, 0, 0, 0, NO_TOOL, 250),
        (int(K.FEED), 0, 0, 0, 0, NO_TOOL, 10 * MM), (int(K.REGION_BEGIN),),
        (int(K.REGION_END),), (int(K.POLARITY), 0, 0, 0, 0, NO_TOOL, 0)]
WORDS = [
    "the pen-up move to X 195 Y 10 mm (file coordinates)",
    "lowering the pen at X 195 Y 10 mm (file coordinates)",
    "the counter-clockwise arc from X 195 Y 10 to X 195 Y 30 mm (centre X 195 Y 20, "
    "file coordinates)",
    "the clockwise arc from X 195 Y 30 to X 195 Y 10 mm (centre X 195 Y 20, file coordinates)",
    "the line from X 195 Y 10 to X 12.3456 Y -0.25 mm (file coordinates)",
    "the flash of D10 (0.5 mm round) at X 1 Y 2 mm (file coordinates)",
    "the change to D10 (0.5 mm round)", "lifting the pen", "a pause of 250 ms",
    "the feed of 10 mm/s (600 mm/min)", "the start of a filled region (G36)",
    "the end of a filled region (G37)", "a polarity change (%LP)"]


@pytest.mark.parametrize("index", range(len(ROWS)))
def test_every_kind_of_op_in_words_and_mm(index):
    assert describe_op(_program("gerber", *ROWS), index) == WORDS[index]


def test_a_draw_before_any_point_and_a_gcode_pen():
    program = _program("gcode", (int(K.LINE), MM, 0, 0, 0, 2), (int(K.SELECT), 0, 0, 0, 0, 2))
    assert describe_op(program, 0) == "the line from where the pen was to X 1 Y 0 mm " \
        "(file coordinates)"
    assert describe_op(program, 1) == "the change to pen 2"
    assert (mm_text(-1), mm_text(-40_000), mm_text(25_400_000)) == ("0", "-0.04", "25.4")
