"""Preview images (galileo_cnc/render.py): strokes from the trace over the artwork."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.job import Flash, PenDown, PenUp, Rapid
from galileo_cnc.machine import simulate
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind
from galileo_cnc.readers import read_file
from galileo_cnc.preview.artwork import ART
from galileo_cnc.preview.render import STROKE, render_preview

from corpus import CORPUS

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
BOARD = SAMPLES / "led-blinker.gbr"
DRAWING = SAMPLES / "square-and-circle.nc"
CONFIG = MachineConfig()


def planned(path):
    program = read_file(path)
    offset = proposed_offset(program)
    job = plan_program(program, CONFIG, offset)
    return program, offset, job, simulate(job.commands, CONFIG)


def preview(path, out, **options):
    program, offset, job, trace = planned(path)
    info = render_preview(program, trace, CONFIG, offset, out, **options)
    return info, np.asarray(Image.open(out).convert("RGB")), job, trace


def pen_down_points(trace: Trace, count: int = 25) -> np.ndarray:
    """Evenly spread work positions (mm) where the trace has the pen down (drawing
    or flashing), skipping the head's resting point before the first lift."""
    pos = trace.positions()
    down = pos[:, 2] <= CONFIG.pen_down_z_steps
    drawing = np.flatnonzero(down & (np.arange(len(pos)) > np.argmax(~down)))
    pick = drawing[np.linspace(0, len(drawing) - 1, count).astype(int)]
    return pos[pick, :2] / CONFIG.steps_per_mm


def has_colour(image: np.ndarray, col: int, row: int, colour, reach: int) -> bool:
    patch = image[max(0, row - reach):row + reach + 1, max(0, col - reach):col + reach + 1]
    return bool(np.all(patch == np.asarray(colour, dtype=np.uint8), axis=-1).any())


def count_colour(image: np.ndarray, colour) -> int:
    return int(np.all(image == np.asarray(colour, dtype=np.uint8), axis=-1).sum())


def expected_strokes(job) -> int:
    """Pen lowerings in the command list: a PenDown while up, or a Flash."""
    down, strokes = False, 0
    for command in job.commands:
        if isinstance(command, PenDown) and not down:
            down, strokes = True, strokes + 1
        elif isinstance(command, Flash):
            down, strokes = False, strokes + 1
        elif isinstance(command, (PenUp, Rapid)):
            down = False
    return strokes


def program_length_mm(program) -> float:
    """Length of the program's lines and arcs, from the op table (not the trace)."""
    total, at = 0.0, (0, 0)
    for row in program.table.tolist():
        kind = row[KIND]
        end = (row[X], row[Y])
        if kind == OpKind.LINE:
            total += math.dist(at, end)
        elif kind in (OpKind.ARC_CW, OpKind.ARC_CCW):
            cx, cy = at[0] + row[I], at[1] + row[J]
            a0 = math.atan2(at[1] - cy, at[0] - cx)
            a1 = math.atan2(end[1] - cy, end[0] - cx)
            sweep = ((a0 - a1) if kind == OpKind.ARC_CW else (a1 - a0)) % (2 * math.pi)
            total += math.hypot(row[I], row[J]) * (sweep or 2 * math.pi)
        if kind in (OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW, OpKind.FLASH):
            at = end
    return total / 1e6


def check_strokes(info, image, trace, artwork: bool = True):
    """Stroke colour where the trace drew, and artwork close by."""
    for x_mm, y_mm in pen_down_points(trace):
        col, row = info.pixel(x_mm, y_mm)
        assert has_colour(image, col, row, STROKE, 2), (x_mm, y_mm, col, row)
        if artwork:  # the pen follows the artwork: green within 0.5 mm
            assert has_colour(image, col, row, ART, 10), (x_mm, y_mm)


def test_sample_board_over_pygerber_artwork(tmp_path):
    info, image, job, trace = preview(BOARD, tmp_path / "board.png")
    assert info.renderer == "pygerber" and info.notes == []
    assert image.shape == (info.height_px, info.width_px, 3)
    # 20 px/mm over the artwork (5.8..46.4 x 4.8..36.2 mm in the file, offset 5, 4 mm)
    # and the head path from the origin, plus 2 mm either side.
    assert info.px_per_mm == 20
    assert info.width_px == pytest.approx((41.4 + 2 + 2) * 20, abs=2)
    assert info.height_px == pytest.approx((32.2 + 2 + 2) * 20, abs=2)
    check_strokes(info, image, trace)
    assert count_colour(image, ART) > 0.05 * image.shape[0] * image.shape[1]
    assert info.strokes == expected_strokes(job)
    assert info.drawn_mm == pytest.approx(program_length_mm(read_file(BOARD)), rel=0.01)
    assert info.stroke_box_mm == pytest.approx((1.0, 1.0, 41.0, 32.0), abs=0.01)
    # Pen-up pixels far from any drawing stay background: the machine origin's
    # corner of the view has no artwork and no strokes.
    assert not has_colour(image, *info.pixel(0.0, 30.0), STROKE, 5)


def test_fallback_when_pygerber_is_not_allowed(tmp_path):
    info, image, job, trace = preview(BOARD, tmp_path / "board.png", pygerber_limit=0)
    assert info.renderer == "galileo"
    assert "limit" in info.notes[0]
    check_strokes(info, image, trace)
    assert count_colour(image, ART) > 0.05 * image.shape[0] * image.shape[1]
    # A 1.6 mm round pad at (14.54, 10) in the file: 0.4 mm above its centre is
    # art, 1 mm above is background.
    col, row = info.pixel(14.54 - 5, 10 - 4)
    assert tuple(image[row - 8, col]) == ART
    assert tuple(image[row - 20, col]) == (255, 255, 255)


def test_fallback_when_pygerber_cannot_read(tmp_path):
    # pygerber 2.4 stops at a '%' inside a G04 comment (EAGLE X2 exports do that).
    text = BOARD.read_text().replace("%TF.GenerationSoftware",
                                     "G04 #@! %TF.Part,Single*\n%TF.GenerationSoftware", 1)
    source = tmp_path / "eagle-style.gbr"
    source.write_text(text)
    info, image, job, trace = preview(source, tmp_path / "board.png")
    assert info.renderer == "galileo"
    assert "pygerber could not read" in info.notes[0]
    check_strokes(info, image, trace)
    assert count_colour(image, ART) > 0


def test_fallback_when_pygerber_reads_it_differently(tmp_path):
    # The Program is read from the mm file; pygerber then sees it in inches,
    # 25.4 times larger: its picture would not line up with the strokes.
    source = tmp_path / "board.gbr"
    source.write_text(BOARD.read_text())
    program = read_file(source)
    offset = proposed_offset(program)
    trace = simulate(plan_program(program, CONFIG, offset).commands, CONFIG)
    source.write_text(BOARD.read_text().replace("%MOMM*%", "%MOIN*%"))
    info = render_preview(program, trace, CONFIG, offset, tmp_path / "board.png")
    assert info.renderer == "galileo"
    assert "differs from ours" in info.notes[0]
    assert info.width_px < 1000                   # the view follows our artwork


def test_gcode_drawing(tmp_path):
    info, image, job, trace = preview(DRAWING, tmp_path / "drawing.png")
    assert info.renderer == "galileo"
    assert info.strokes == 2                      # the square, then the circle
    assert info.drawn_mm == pytest.approx(80 + 10 * math.pi, rel=0.002)
    assert info.stroke_box_mm == pytest.approx((1.0, 1.0, 21.0, 21.0), abs=0.01)
    assert (info.width_px, info.height_px) == (500, 500)  # 0..21 mm + 2 mm margins
    check_strokes(info, image, trace)
    # The circle's centre (10, 10) + 1 mm margin is inside, not drawn.
    assert tuple(image[info.pixel(11.0, 11.0)[::-1]]) == (255, 255, 255)


def test_without_artwork_and_size_cap(tmp_path):
    info, image, job, trace = preview(BOARD, tmp_path / "small.png", artwork=False, max_px=300)
    assert info.renderer == "none"
    assert max(info.width_px, info.height_px) <= 300
    assert info.px_per_mm == 6                    # 45.4 mm wide view -> 6 whole px/mm
    assert count_colour(image, ART) == 0
    assert count_colour(image, STROKE) > 0


def test_empty_trace(tmp_path):
    program = read_file(BOARD)
    empty = Trace(np.zeros(0, np.int64), np.zeros(0, np.int8), np.zeros(0, np.int8), (0, 0, 0), 0)
    info = render_preview(program, empty, CONFIG, proposed_offset(program), tmp_path / "e.png",
                          pygerber_limit=0)
    assert info.strokes == 0 and info.drawn_mm == 0 and info.stroke_box_mm is None
    assert Image.open(tmp_path / "e.png").size == (info.width_px, info.height_px)


CORPUS_FILES = [
    ("kicad/arduino-kicad6/F_Cu.gbr", "pygerber"),
    ("eagle/gyw-electro-x2/copper_top.gbr", "galileo"),   # pygerber cannot parse it
]


@pytest.mark.parametrize("path, renderer", CORPUS_FILES)
def test_corpus_files(tmp_path, path, renderer):
    source = CORPUS / path
    if not source.exists():
        pytest.skip(f"corpus not available at {CORPUS}")
    info, image, job, trace = preview(source, tmp_path / "corpus.png")
    assert info.renderer == renderer
    assert info.strokes == expected_strokes(job) > 0
    check_strokes(info, image, trace)
