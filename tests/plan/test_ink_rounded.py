"""Rounded corners of the rings inside E0 (fill._corners_rounded): the pen turns along
a small circle where the ring outside it inks what the sharp corner did, so the
board is inked the same and plots faster."""

from __future__ import annotations

import math

import numpy as np
import pytest
from inked import bare_within, box, plan_and_ink

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, LineTo, PenDown
from galileo_cnc.machine.timing import job_timing
from galileo_cnc.plan.ink import clip, fill

CONFIG = MachineConfig()
PEN = 400_000                      # the default profile's pen
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
#: a 2.5 mm square pad, a square turned by 30 degrees, an L of copper and a triangle
BOARD = HEADER + (
    "%ADD10R,2.5X2.5*%\nD10*\nX5000000Y4500000D03*\n"
    "G36*\nX11250000Y3000000D02*\nX13415064Y4250000D01*\nX12165064Y6415064D01*\n"
    "X10000000Y5165064D01*\nX11250000Y3000000D01*\nG37*\n"
    "G36*\nX15000000Y3000000D02*\nX19000000Y3000000D01*\nX19000000Y4300000D01*\n"
    "X16600000Y4300000D01*\nX16600000Y6000000D01*\nX15000000Y6000000D01*\n"
    "X15000000Y3000000D01*\nG37*\n"
    "G36*\nX21000000Y3000000D02*\nX25000000Y3000000D01*\nX23000000Y6464102D01*\n"
    "X21000000Y3000000D01*\nG37*\n"
    "M02*\n")


def _sharp_turns(commands) -> int:
    """Pen-down vertices between lines that turn by 60 degrees or more."""
    turns, previous, at, down = 0, None, (0, 0), False
    for command in commands:
        if isinstance(command, PenDown):
            down, previous = True, None
            continue
        if not isinstance(command, (LineTo, ArcTo)) or not down:
            down = down and not hasattr(command, "x_steps")
            previous = None
            continue
        step = (command.x_steps - at[0], command.y_steps - at[1])
        at = (command.x_steps, command.y_steps)
        if isinstance(command, ArcTo) or step == (0, 0):
            previous = None
            continue
        if previous is not None:
            cos = (previous[0] * step[0] + previous[1] * step[1]) / (
                math.hypot(*previous) * math.hypot(*step))
            turns += cos < 0.5
        previous = step
    return turns


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """The board planned, stepped and timed with rounded corners and with sharp ones."""
    path = tmp_path_factory.mktemp("rounded") / "board.gbr"
    path.write_text(BOARD)
    out = {}
    for name, least in (("rounded", fill.ROUNDED_LEAST_NM), ("sharp", 10**12)):
        saved, fill.ROUNDED_LEAST_NM = fill.ROUNDED_LEAST_NM, least
        try:
            planned, ink, copper = plan_and_ink(path, PEN, CONFIG)
        finally:
            fill.ROUNDED_LEAST_NM = saved
        commands = planned.job.commands
        out[name] = {"ink": ink, "copper": copper, "turns": _sharp_turns(commands),
                     "seconds": job_timing(commands, CONFIG).total_s,
                     "lifts": sum(isinstance(c, PenDown) for c in commands)}
    return out


def test_rounded_corners_ink_the_copper_as_sharp_ones_and_plot_faster(both):
    """From the steps: no more copper deeper than the pen's radius is left bare than
    with sharp corners (the corners a round pen cannot reach, down to 60 degrees, and
    the stepping along the edges lie nearer the edge; the inner rings' corners lie
    deeper); the ink spills no more; fewer sharp turns, less time."""
    rounded, sharp = both["rounded"], both["sharp"]
    copper = rounded["copper"]
    deep = clip.offset(copper, -PEN // 2, 1_000)
    bare = {name: bare_within(copper, run["ink"], deep) for name, run in both.items()}
    assert bare["sharp"] <= 500e6        # a speck in the triangle's middle: 218 um²
    assert bare["rounded"] <= bare["sharp"] + 20e6
    # ink past the edge: the steps' rounding only, as with sharp corners
    edge = sum(np.hypot(*(np.roll(ring, -1, axis=0) - ring).T).sum()
               for ring in clip.rings_as_arrays(copper))
    for run in (rounded, sharp):
        assert clip.area_nm2(clip.difference(run["ink"], copper)) <= edge * CONFIG.nm_per_step / 2
    assert rounded["lifts"] == sharp["lifts"] == 4
    assert rounded["turns"] < sharp["turns"] - 20
    assert rounded["seconds"] < sharp["seconds"] * 0.98


def _square_ring(half: int) -> list:
    return box(-half, -half, half, half)


def test_a_right_angle_is_rounded_as_far_as_the_ring_outside_covers():
    """At the default pen (r 0.2 mm, spacing 0.32 mm) a right angle of E(k) turns on a
    circle of rho = (r - GAP - g sqrt 2) / (sqrt 2 - 1), g = spacing - r: the cap cut
    off each corner is (1 - pi/4) rho²."""
    radius, spacing = PEN // 2, int(PEN * (1 - fill.DEFAULT_OVERLAP))
    inner = _square_ring(1_000_000)
    outer = clip.offset_mitred(inner, spacing)          # E(k-1), its corners sharp
    rounded = fill._corners_rounded(inner, outer, radius, spacing, 16_000)
    g = spacing - radius
    rho = (radius - fill.GAP_NM - g * math.sqrt(2)) / (math.sqrt(2) - 1)
    assert fill.ROUNDED_LEAST_NM < rho < fill.ROUNDED_MOST_NM
    cut = clip.area_nm2(inner) - clip.area_nm2(rounded)
    # the chords lie inside the circle: a little more than the circle's caps
    assert 1.0 <= cut / (4 * (1 - math.pi / 4) * rho ** 2) <= 1.15
    # the ring the pen draws turns by at most the chord's turn at each vertex
    ring = clip.rings_as_arrays(rounded)[0].astype(np.float64)
    edges = np.roll(ring, -1, axis=0) - ring
    turn = np.degrees(np.abs(np.arctan2(
        edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0],
        np.einsum("ij,ij->i", edges, np.roll(edges, -1, axis=0)))))
    assert turn.max() <= math.degrees(fill.ROUNDED_CHORD_TURN) + 0.5


def test_corners_the_ring_outside_does_not_cover_stay_sharp():
    radius, spacing = PEN // 2, int(PEN * (1 - fill.DEFAULT_OVERLAP))
    # a corner sharper than about 88 degrees: the ink outside would not reach a circle
    wedge = [[[0, 0], [3_000_000, 0], [int(3_000_000 * math.cos(math.radians(80))),
                                      int(3_000_000 * math.sin(math.radians(80)))]]]
    outer = clip.offset_mitred(wedge, spacing)
    assert fill._corners_rounded(wedge, outer, radius, spacing, 16_000) == wedge
    # a corner where two parts of E(k-1)'s outline met as it shrank (here E(k-1) has
    # round corners): no corner of E(k-1) lies out along its bisector
    inner = _square_ring(1_000_000)
    round_outer = clip.offset(inner, spacing, 1_000)
    assert fill._corners_rounded(inner, round_outer, radius, spacing, 16_000) == inner


def test_an_outline_near_a_corner_leaves_a_valid_set_the_next_offset_can_grow():
    """A hole whose edge passes through a corner's cap: the caps are cut out with
    Clipper, the result lies inside the area, and growing it (as the gap test does)
    gives the whole area back, not nothing (a ring of no area holding the set's
    lowest vertex would turn the offset round)."""
    radius, spacing = PEN // 2, int(PEN * (1 - fill.DEFAULT_OVERLAP))
    area = clip.difference(_square_ring(1_000_000),
                           box(960_000, -900_000, 990_000, 990_000))
    outer = clip.offset_mitred(_square_ring(1_000_000), spacing)
    rounded = fill._corners_rounded(area, outer, radius, spacing, 16_000)
    assert clip.area_nm2(clip.difference(rounded, area)) == 0
    assert 0 < clip.area_nm2(area) - clip.area_nm2(rounded) < 4 * 0.22 * 70_000 ** 2
    grown = clip.offset(rounded, radius, 1_000, cleaned=True)
    assert clip.area_nm2(grown) > clip.area_nm2(area)
