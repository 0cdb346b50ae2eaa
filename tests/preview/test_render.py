"""Preview images (galileo_cnc/preview/render.py): strokes from the trace over the artwork."""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageDraw

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.job import Flash, PenDown, PenUp, Rapid
from galileo_cnc.machine import simulate
from galileo_cnc.machine.planner import JobSteps
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind
from galileo_cnc.readers import read_file
from galileo_cnc.preview import render
from galileo_cnc.preview.artwork import ART, PixelFrame
from galileo_cnc.preview.render import STROKE, TRAVEL, render_preview

from corpus import corpus_file

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
    source = corpus_file(path)
    info, image, job, trace = preview(source, tmp_path / "corpus.png")
    assert info.renderer == renderer
    assert info.strokes == expected_strokes(job) > 0
    check_strokes(info, image, trace)


# ---- the trace is read in chunks: same picture and numbers as reading it whole ----

def whole_trace_reference(trace: Trace, config, info, start=(0, 0, 0), pen_px: int = 3,
                          travel: bool = True):
    """Strokes and travel drawn from the whole trace at once, as render.py drew them
    before it read the trace in chunks, on a blank canvas of `info`'s view: the
    image, and (strokes, drawn mm, travel mm, stroke box)."""
    pos = trace.positions(start)
    last_of_tick = np.ones(len(trace), dtype=bool)
    last_of_tick[:-1] = trace.tick[1:] != trace.tick[:-1]
    points = np.vstack([np.asarray(start, dtype=np.int64), pos[last_of_tick]])
    down = points[:, 2] <= config.pen_down_z_steps
    moves = np.zeros(len(points), dtype=bool)
    moves[1:] = np.any(points[1:, :2] != points[:-1, :2], axis=1)
    moved_before = np.cumsum(moves)

    def runs(mask):
        edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
        return np.stack([np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1], axis=1)

    def moved(r):
        return moved_before[r[:, 1]] - moved_before[r[:, 0]] > 0

    pen_down = runs(down)
    strokes = pen_down[moved(pen_down) | (pen_down[:, 0] > 0)]
    pen_up = runs(~down)
    travels = pen_up[moved(pen_up)]
    travels[:, 0] = np.maximum(travels[:, 0] - 1, 0)
    xy = points[:, :2] / config.steps_per_mm

    def length(rs):
        total = 0.0
        for a, b in rs.tolist():
            index = np.arange(a, b + 1)
            pts = xy[index[((index - a) % 16 == 0) | (index == b)]]
            total += float(np.hypot(*np.diff(pts, axis=0).T).sum())
        return total

    box = None
    if len(strokes):
        pts = np.concatenate([xy[a:b + 1] for a, b in strokes.tolist()])
        box = (*pts.min(axis=0).tolist(), *pts.max(axis=0).tolist())

    image = Image.new("RGB", (info.width_px, info.height_px), (255, 255, 255))
    draw = ImageDraw.Draw(image)
    col, row = PixelFrame(info.view_mm, info.px_per_mm).xy(xy[:, 0], xy[:, 1])
    pix = np.stack([np.rint(col), np.rint(row)], axis=1)

    def draw_runs(rs, colour, width):
        for a, b in rs.tolist():
            pts = pix[a:b + 1]
            keep = np.ones(len(pts), dtype=bool)     # the points that change pixel
            keep[1:-1] = np.any(pts[1:-1] != pts[:-2], axis=1)
            pts = pts[keep]
            if np.any(pts != pts[0]):
                draw.line(pts.ravel().tolist(), fill=colour, width=width, joint="curve")
            else:
                x, y = pts[0].tolist()
                dot = max(2.0, width)
                draw.ellipse((x - dot, y - dot, x + dot, y + dot), fill=colour)

    if travel:
        draw_runs(travels, TRAVEL, 1)
    draw_runs(strokes, STROKE, pen_px)
    return np.asarray(image), (len(strokes), length(strokes), length(travels), box)


def random_trace(seed: int, events: int) -> Trace:
    """Steps in straight runs with turns, X and Y steps often sharing a tick, and Z
    wandering round the pen-down height (lifts and lowerings mid-move too)."""
    rng = np.random.default_rng(seed)
    ticks, axes, dirs = [], [], []
    tick, heading = 0, rng.integers(-1, 2, size=2)
    for _ in range(events):
        tick += int(rng.integers(1, 5))
        if rng.random() < 0.05:
            heading = rng.integers(-1, 2, size=2)
        for axis in (0, 1):
            if heading[axis] and rng.random() < 0.8:
                ticks.append(tick), axes.append(axis), dirs.append(int(heading[axis]))
        if rng.random() < 0.08:
            ticks.append(tick), axes.append(2), dirs.append(int(rng.choice([-1, 1])))
    return Trace(np.array(ticks, np.int64), np.array(axes, np.int8), np.array(dirs, np.int8),
                 (0, 0, 0), tick)


def assert_same_as_whole_trace(info, image, trace, start=(0, 0, 0), pen_px=3, travel=True):
    reference, (strokes, drawn, travel_mm, box) = whole_trace_reference(
        trace, CONFIG, info, start, pen_px, travel)
    assert info.strokes == strokes
    assert info.drawn_mm == pytest.approx(drawn, rel=1e-12, abs=1e-9)
    assert info.travel_mm == pytest.approx(travel_mm, rel=1e-12, abs=1e-9)
    assert info.stroke_box_mm == (None if box is None else pytest.approx(box, abs=1e-12))
    different = np.any(image != reference, axis=-1)
    assert not different.any(), \
        f"{different.sum()} pixels differ, the first at (row, col) {np.argwhere(different)[0]}"


@pytest.mark.parametrize("chunk", [101, 4096])
def test_chunked_board_draws_the_whole_trace_picture(tmp_path, monkeypatch, chunk):
    # Chunks far shorter than the strokes: every stroke and travel line crosses
    # several chunk boundaries, yet each pixel is the one the whole trace gives.
    monkeypatch.setattr(render, "_CHUNK_STEPS", chunk)
    info, image, job, trace = preview(BOARD, tmp_path / "board.png", artwork=False)
    assert_same_as_whole_trace(info, image, trace)


@pytest.mark.parametrize("seed", range(12))
def test_chunked_random_traces_draw_the_whole_trace_picture(tmp_path, monkeypatch, seed):
    rng = np.random.default_rng(1000 + seed)
    trace = random_trace(seed, int(rng.integers(0, 2500)))
    start = (int(rng.integers(-50, 50)), int(rng.integers(-50, 50)), int(rng.integers(-2, 3)))
    # Wide pens (over 4 px) have curved joints, which pieces of a run must keep.
    px_per_mm, pen_mm = [(3, 0.15), (20, 0.15), (45, 0.3)][seed % 3]
    pen_px = max(1, round(pen_mm * px_per_mm))
    program = read_file(DRAWING)
    for chunk in (1, 3, 64, 1 << 17):
        monkeypatch.setattr(render, "_CHUNK_STEPS", chunk)
        out = tmp_path / f"random-{chunk}.png"
        info = render_preview(program, trace, CONFIG, (0, 0), out, start=start, artwork=False,
                              px_per_mm=px_per_mm, pen_width_mm=pen_mm, travel=seed % 4 != 0)
        image = np.asarray(Image.open(out).convert("RGB"))
        assert_same_as_whole_trace(info, image, trace, start, pen_px, travel=seed % 4 != 0)


def test_working_memory_does_not_grow_with_the_trace(tmp_path):
    # 4 M steps of pen-down zigzag (a 40 MB trace). Reading the whole trace at once
    # took ~50 bytes per step (200 MB here); in chunks, numpy's working memory is
    # a few MB whatever the trace's length.
    n = 4_000_000
    k = np.arange(n)
    axis = np.where(k % 4040 < 4000, 0, 1).astype(np.int8)
    step = np.where((axis == 0) & (k // 4040 % 2 == 1), -1, 1).astype(np.int8)
    trace = Trace(k * 3, axis, step, (0, 0, 0), 3 * n)
    program = read_file(DRAWING)
    tracemalloc.start()
    try:
        info = render_preview(program, trace, CONFIG, (0, 0), tmp_path / "long.png",
                              artwork=False)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 24 * 2 ** 20, peak
    assert info.strokes == 1
    assert info.stroke_box_mm == pytest.approx((0.0, 0.0, 25.0, 990 * 40 / 160), abs=1e-9)
    assert info.drawn_mm == pytest.approx(n / 160, rel=0.01)


@pytest.mark.parametrize("chunk", [97, 1 << 17])
def test_a_job_stepped_as_it_is_read_draws_the_trace_picture(tmp_path, monkeypatch, chunk):
    # `galileo-cnc preview` never holds the whole trace: JobSteps steps the job piece
    # by piece while the preview reads it (twice); the picture is the same
    monkeypatch.setattr(render, "_CHUNK_STEPS", chunk)
    program = read_file(BOARD)
    offset = proposed_offset(program)
    job = plan_program(program, CONFIG, offset)
    whole = render_preview(program, simulate(job.commands, CONFIG), CONFIG, offset,
                           tmp_path / "whole.png", artwork=False)
    stepped = render_preview(program, JobSteps(job.commands, CONFIG), CONFIG, offset,
                             tmp_path / "stepped.png", artwork=False)
    assert (whole.strokes, whole.drawn_mm, whole.travel_mm, whole.stroke_box_mm) == \
        (stepped.strokes, stepped.drawn_mm, stepped.travel_mm, stepped.stroke_box_mm)
    assert np.array_equal(np.asarray(Image.open(tmp_path / "whole.png")),
                          np.asarray(Image.open(tmp_path / "stepped.png")))
