"""A board's outline and silkscreen as centre lines (`--outline`, `--silk`, issue 32):
planned on tests/boards.py's board with both sides' silk, stepped by the reference
machine: after the copper with a pen change each, clear of copper by the pen's
radius, the bottom's silk mirrored about the copper's axis, kept in the journal, and
coloured in the preview."""

from __future__ import annotations

import json

import numpy as np
import pyclipper as pc
import pytest

from boards import SILK_DOTS_MM, make_board
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, Flash, LineTo, PenDown, Rapid
from galileo_cnc.machine import simulate
from galileo_cnc.plan.board_plan import BoardChoice, plan_board
from galileo_cnc.plan.ink import clip
from galileo_cnc.plan.ink.geometry import dark_geometry
from galileo_cnc.plan.pipeline import PlanOptions
from galileo_cnc.preview.job_path import JobPath
from galileo_cnc.preview.render import LINE_COLOURS, pen_stretches, render_preview
from galileo_cnc.preview.svg import render_svg
from galileo_cnc.program.ops import NM_PER_MM

CONFIG = MachineConfig()                    # one 0.4 mm pen
PEN_NM = min(CONFIG.pen_widths_nm)
CHOICE = BoardChoice(outline=True, silk=True)
_DRAWING = (PenDown, LineTo, ArcTo, Flash)


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    return make_board(tmp_path_factory.mktemp("silk") / "board", silk=True)


@pytest.fixture(scope="module")
def planned(board):
    """Both sides, ink mode, the outline and the silk drawn."""
    return {side: plan_board(board, CONFIG, choice=BoardChoice(side=side, outline=True,
                                                               silk=True))
            for side in ("top", "bottom")}


def _drawing_indices(job, tools) -> list[int]:
    return [k for k, (command, tool) in enumerate(zip(job.commands, job.aperture))
            if isinstance(command, _DRAWING) and tool in tools]


def test_outline_then_silk_after_all_copper_each_with_a_pen_change(planned):
    for side, plan in planned.items():
        job, roles = plan.job, plan.pen_roles
        assert sorted(roles.values()) == ["outline", "silk"], side
        tool = {role: key for key, role in roles.items()}
        copper = _drawing_indices(job, set(job.aperture) - set(roles))
        outline = _drawing_indices(job, {tool["outline"]})
        silk = _drawing_indices(job, {tool["silk"]})
        assert copper and outline and silk, side
        assert max(copper) < min(outline) and max(outline) < min(silk), side
        # the job stops for the user's pen before each, and names it
        changes = {key: command for command, key in job.pen_changes.items()}
        assert max(copper) < changes[tool["outline"]] <= min(outline), side
        assert max(outline) < changes[tool["silk"]] <= min(silk), side
        assert job.pen_labels[tool["outline"]] == "the outline pen (0.4 mm)"
        assert job.pen_labels[tool["silk"]] == "the silk pen (0.4 mm)"
        assert job.pen_widths_nm[tool["silk"]] == PEN_NM
    # the top silk's half circle (1 mm radius) is one arc, not its chords
    top = planned["top"]
    silk = next(key for key, role in top.pen_roles.items() if role == "silk")
    arcs = [c for c, key in zip(top.job.commands, top.job.aperture)
            if isinstance(c, ArcTo) and key == silk]
    assert len(arcs) == 1 and np.hypot(arcs[0].i_steps, arcs[0].j_steps) == \
        pytest.approx(NM_PER_MM / CONFIG.nm_per_step, abs=1)


def _pen_down_nm(plan, tool: int) -> np.ndarray:
    """Program nm of every pen-down step of the reference machine while `tool`'s pen
    is in the holder."""
    job = plan.job
    trace = simulate(job.commands, CONFIG)
    positions = trace.positions()
    events = np.vstack([[0, 0, 0], positions[np.r_[trace.tick[1:] != trace.tick[:-1], True]]])
    stretches = pen_stretches(job, CONFIG)
    k = stretches.keys.index(tool)
    end = stretches.first_event[k + 1] if k + 1 < len(stretches.keys) else len(events)
    mine = events[stretches.first_event[k]:end]
    down = mine[mine[:, 2] <= CONFIG.pen_down_z_steps][:, :2]
    return down * CONFIG.nm_per_step + np.asarray(plan.offset_nm)


def test_no_outline_or_silk_step_within_the_pens_radius_of_copper(board, planned):
    # ink mode, both sides; centre mode's bottom (its copper as the file draws it)
    centre = plan_board(board, CONFIG, choice=BoardChoice(side="bottom", outline=True,
                                                         silk=True),
                        options=PlanOptions(mode="centre"))
    for side, plan in [*planned.items(), ("bottom, centre mode", centre)]:
        copper = plan.ink.copper if plan.ink is not None else dark_geometry(plan.program)
        # the copper as plotted on the side, grown by the pen's radius less a step
        near = clip.offset(copper.native, PEN_NM // 2 - CONFIG.nm_per_step, 1_000)
        for tool, role in plan.pen_roles.items():
            points = _pen_down_nm(plan, tool)
            assert len(points) > 50, (side, role)
            inside = [p for p in points.tolist()
                      if sum(1 if pc.Area(ring) > 0 else -1 for ring in near
                             if pc.PointInPolygon(tuple(p), ring) != 0) > 0]
            assert not inside, (side, role, inside[:3])
    # the silk crosses pads on both sides: cut there, and said so in mm
    for side, plan in planned.items():
        assert any(w.startswith("--silk: ") and " mm of the silk " in w
                   for w in plan.line_warnings), (side, plan.line_warnings)
    assert not any(w.startswith("--outline") for p in planned.values()
                   for w in p.line_warnings)


def _flash_steps(job, tool) -> list[tuple[int, int]]:
    """Where `tool`'s flashes put the pen down (steps)."""
    at, out = (0, 0), []
    for command, key in zip(job.commands, job.aperture):
        if isinstance(command, (Rapid, LineTo)):
            at = (command.x_steps, command.y_steps)
        elif isinstance(command, Flash) and key == tool:
            out.append(at)
    return out


def test_bottom_silk_turned_over_lands_on_its_top_mirror_point(planned):
    top, bottom = planned["top"], planned["bottom"]
    assert top.offset_nm == bottom.offset_nm           # one offset for both sides
    silk = {name: next(k for k, role in p.pen_roles.items() if role == "silk")
            for name, p in planned.items()}
    step = CONFIG.nm_per_step
    ox, oy = bottom.offset_nm
    # the bottom's dot, plotted mirrored: turned over about the axis on the machine it
    # is where the top's copper has that board point
    [(xb, yb)] = _flash_steps(bottom.job, silk["bottom"])
    axis_steps = (bottom.axis.twice_nm // 2 - ox) / step
    x_mm, y_mm = SILK_DOTS_MM["bottom"]
    assert 2 * axis_steps - xb == pytest.approx((x_mm * NM_PER_MM - ox) / step, abs=1)
    assert yb == pytest.approx((y_mm * NM_PER_MM - oy) / step, abs=1)
    # the top's own dot is at its board point (the one on a pad is left out)
    x_mm, y_mm = SILK_DOTS_MM["top"]
    assert _flash_steps(top.job, silk["top"]) == [
        (round((x_mm * NM_PER_MM - ox) / step), round((y_mm * NM_PER_MM - oy) / step))]


def test_the_journal_keeps_outline_and_silk_and_a_replan_is_the_same(board, planned):
    plan = planned["bottom"]
    kept = json.loads(json.dumps(plan.job.board))
    assert kept["outline"] is True and kept["silk"] is True
    choice = BoardChoice.from_dict(kept)
    assert choice == BoardChoice(side="bottom", outline=True, silk=True)
    # a journal written before the two options: neither drawn
    old = {key: value for key, value in kept.items() if key not in ("outline", "silk")}
    assert BoardChoice.from_dict(old) == BoardChoice(side="bottom")
    again = plan_board(board, CONFIG, choice=choice)
    assert again.job.commands == plan.job.commands
    assert again.job.pen_labels == plan.job.pen_labels


def test_preview_paints_outline_and_silk_in_their_own_colours(planned, tmp_path):
    plan = planned["top"]
    image_path = tmp_path / "top.png"
    info = render_preview(plan.program, JobPath(plan.job.commands, CONFIG), CONFIG,
                          plan.offset_nm, image_path, job=plan.job, copper=plan.copper,
                          marks=plan.marks, pen_roles=plan.pen_roles, artwork=False)
    from PIL import Image
    image = np.asarray(Image.open(image_path).convert("RGB"))
    ox, oy = plan.offset_nm
    for role, (x_mm, y_mm) in (("silk", SILK_DOTS_MM["top"]), ("outline", (6.0, 0.0))):
        col, row = info.pixel(x_mm - ox / NM_PER_MM, y_mm - oy / NM_PER_MM)
        assert tuple(image[row, col]) == LINE_COLOURS[role], role
    # drawn off the copper on purpose: not counted as ink outside it
    plain = render_preview(plan.program, JobPath(plan.job.commands, CONFIG), CONFIG,
                           plan.offset_nm, tmp_path / "plain.png", job=plan.job,
                           copper=plan.copper, marks=plan.marks, artwork=False)
    assert plain.outside_mm2 > info.outside_mm2 + 1.0


def test_svg_preview_draws_outline_and_silk_apart_with_their_legend(planned, tmp_path):
    plan = planned["bottom"]
    path = tmp_path / "bottom.svg"
    render_svg(plan.program, plan.job, CONFIG, plan.offset_nm, path, copper=plan.copper,
               pen_roles=plan.pen_roles)
    drawing = path.read_text()
    for role, colour in LINE_COLOURS.items():
        assert f'<g id="{role}" fill="none"' in drawing and f">{role}</text>" in drawing
        assert "#{:02x}{:02x}{:02x}".format(*colour) in drawing
    # the bottom's silk dot, mirrored: a disc of the pen in the silk group
    silk = drawing[drawing.index('<g id="silk"'):]
    silk = silk[:silk.index("</g>")]
    x_mm, y_mm = SILK_DOTS_MM["bottom"]
    x_mm = plan.axis.twice_nm / NM_PER_MM - x_mm
    ox, oy = (v / NM_PER_MM for v in plan.offset_nm)
    assert f'<circle cx="{x_mm - ox:.4f}" cy="{y_mm - oy:.4f}" r="0.2000"' in silk


def test_clear_of_cuts_lines_across_copper_and_keeps_one_below_it_whole():
    # a 10 mm square of keep-out: a line across it loses its 10 mm inside, a line below
    # it is kept whole (Clipper alone loses a horizontal open path below every
    # polygon: flashpads' outline is four lines, its bottom one below all copper)
    from galileo_cnc.plan.board_lines import clear_of

    mm = NM_PER_MM
    square = [[[0, 0], [10 * mm, 0], [10 * mm, 10 * mm], [0, 10 * mm]]]
    strokes = [np.array([[-5 * mm, -2 * mm], [15 * mm, -2 * mm]]),
               np.array([[-5 * mm, 5 * mm], [15 * mm, 5 * mm]]),
               np.array([[5 * mm, 5 * mm]]), np.array([[20 * mm, 5 * mm]])]
    lines = clear_of("silk", strokes, square)
    assert lines.dropped_nm == 10 * mm and lines.dropped_dots == 1
    kept = sorted(sorted(map(tuple, s.tolist())) for s in lines.strokes)
    assert kept == [[(-5 * mm, -2 * mm), (15 * mm, -2 * mm)], [(-5 * mm, 5 * mm), (0, 5 * mm)],
                    [(10 * mm, 5 * mm), (15 * mm, 5 * mm)], [(20 * mm, 5 * mm)]]
    assert lines.warning(400_000, 50_000) == (
        "--silk: 10.00 mm of the silk and 1 dot left out within 0.250 mm of copper or a "
        "drill mark (its ink there would join copper islands)")


def test_clear_of_keeps_a_dot_in_a_hole_of_the_keep_out():
    # a 10 mm square with a 2 mm hole (clockwise): a dot in the hole is off the copper
    from galileo_cnc.plan.board_lines import clear_of

    mm = NM_PER_MM
    ring = [[[0, 0], [10 * mm, 0], [10 * mm, 10 * mm], [0, 10 * mm]],
            [[4 * mm, 4 * mm], [4 * mm, 6 * mm], [6 * mm, 6 * mm], [6 * mm, 4 * mm]]]
    dots = [np.array([[5 * mm, 5 * mm]]), np.array([[2 * mm, 2 * mm]]),
            np.array([[4 * mm - 1, 5 * mm]])]
    lines = clear_of("silk", dots, ring)
    assert [s.tolist() for s in lines.strokes] == [[[5 * mm, 5 * mm]]]
    assert lines.dropped_dots == 2 and lines.dropped_nm == 0


def test_a_side_without_silk_says_so_and_a_board_without_an_outline_refuses_it(tmp_path):
    from galileo_cnc.readers.board import BoardError

    board = make_board(tmp_path / "board", silk=True)
    (board / "board-B_SilkS.gbr").unlink()
    bottom = plan_board(board, CONFIG, choice=BoardChoice(side="bottom", silk=True))
    assert bottom.line_warnings == ("--silk: no file is bottom-silk: no silk on the bottom "
                                    "side",)
    assert not bottom.pen_roles
    (board / "board-Edge_Cuts.gbr").unlink()
    with pytest.raises(BoardError, match="--outline: no file is outline"):
        plan_board(board, CONFIG, choice=BoardChoice(outline=True))


def test_a_server_planning_zip_boards_keeps_few_unpacked(tmp_path, monkeypatch):
    """A zip board stays unpacked after its plan (messages name its files), but only the
    last few: `serve` plans many, each a folder in /tmp. A plan that fails keeps none."""
    import shutil
    import tempfile

    from galileo_cnc.errors import GalileoError
    from galileo_cnc.plan import board_plan

    board_zip = shutil.make_archive(str(tmp_path / "board"), "zip",
                                    make_board(tmp_path / "board"))
    unpacked = tmp_path / "tmp"
    unpacked.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(unpacked))
    monkeypatch.setattr(board_plan, "_UNPACKED", [])      # this test's boards only
    roots = []
    for _ in range(board_plan.KEPT_UNPACKED + 2):
        plan_board(board_zip, MachineConfig())
        roots.append(board_plan._UNPACKED[-1].root)
    assert [root.exists() for root in roots] == [False] * 2 + [True] * board_plan.KEPT_UNPACKED
    assert len(list(unpacked.iterdir())) == board_plan.KEPT_UNPACKED
    kept = list(board_plan._UNPACKED)
    with pytest.raises(GalileoError, match="wide"):       # 12 mm on 5 mm of travel
        plan_board(board_zip, MachineConfig(x_travel_mm=5.0))
    assert board_plan._UNPACKED == kept and all(board.root.exists() for board in kept)
    assert len(list(unpacked.iterdir())) == board_plan.KEPT_UNPACKED
    for board in kept:
        board.close()
