"""The height map on stock GRBL 1.1h in simavr, over a board warped by +-0.2 mm: the
harness's probe pin (--probe) touches a surface waved as 0.2 mm sin(2 pi x / 40 mm)
sin(2 pi y / 40 mm) (machine x, y), the grid over the job is probed with G38.2
(grbl/probe.py), isolation-style passes are streamed corrected by the map
(plan/mill/heightmap.py), and from the Z steps in the pin trace the depth below the
real surface stays within 0.01 mm of the set depth at every step of every cutting pass.

The board, a 20 x 4 mm strip (work X 0..20, Y 0..4 at machine X 10..30, Y -12..-8),
runs along the wave from a trough (-0.2 mm) to a crest (+0.2 mm) over the ridge at
machine Y -10, which it straddles, so the surface also bends and twists across it. A
strip, not a square: GRBL in simavr runs at a real board's pace, and the probes are
most of the test's time (4 rows, not 8). Z has 800 steps/mm (a 3018's lead screw:
1.25 um a step), X and Y the test machine's 160. The error budget, worst case: the
bilinear map against the sine (1.538 mm grid: A k^2 s^2 / 4 = 2.9 um), the probe's
contact at the first step at or below the surface (up to a step, 1.25 um) and [PRB:]'s
three decimals (0.5 um), GRBL rounding a commanded Z to the step (0.6 um) and
Bresenham's Z between two of them (under a step), the chord bound LINEAR_Z_BOUND_NM
(1 um): 7.5 um in all.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.grbl.gcode import GcodeLine
from galileo_cnc.grbl.numbers import F32, lround_f32, read_float
from galileo_cnc.grbl.probe import ProbeError, probe_height_map
from galileo_cnc.grbl.stream import stream
from galileo_cnc.plan.mill.heightmap import HeightCorrector, ProbeGrid, job_grid
from galileo_cnc.simavr.grbl_firmware import ProbeSurface
from galileo_cnc.stream.journal import Journal, JournalEntry

from grbl_support import SETTINGS, grbl_machine, positions_and_ticks, settled_trace

MM = 1_000_000            # nm
XY_STEPS_PER_MM, Z_STEPS_PER_MM = 160, 800
#: the test machine with a 3018's Z: 800 steps/mm, at most 2000 mm/min (27 kHz); the
#: steppers kept on ($1=255, as mills run: Z holds), which also spares the 25 ms GRBL
#: waits each time its steppers go idle (st_go_idle), twice a probe; accelerating at
#: 40000 mm/s^2, as the depth below the surface holds at any acceleration (the probes'
#: short moves are mostly speeding up and slowing down)
WARPED = {**SETTINGS, 1: "255", 102: str(Z_STEPS_PER_MM), 112: "2000",
          120: "40000", 121: "40000", 122: "40000"}
#: work (0, 0, 0) at machine (10, -12, -1) mm: set by `G10 L20 P1 X-10 Y12 Z1` at power-up
WORK_ZERO_MM = (10, -12, -1)
#: the board's top: 1 mm below power-up, waved by 0.2 mm over 40 mm periods (machine steps)
SURFACE = ProbeSurface(z0=-1 * Z_STEPS_PER_MM, amp=0.2 * Z_STEPS_PER_MM,
                       px=40 * XY_STEPS_PER_MM, py=40 * XY_STEPS_PER_MM)
DEPTH_MM = 0.1
TOLERANCE_MM = 0.01
#: 1.6 mm spacing: 13 cells of 1.538 mm over 20 mm, 3 of 1.333 mm over 4: 14 x 4 probes
MILL = MillConfig.from_table({"height_map": True, "height_map_spacing_mm": 1.6,
                              "probe_clearance_mm": 0.25, "probe_depth_mm": 0.25,
                              "probe_feed_mm_min": 2000, "cut_depth_mm": DEPTH_MM})


def passes() -> list[tuple[str, bool]]:
    """Isolation-style G-code (plan/mill/gcode.py's form, modal continuation lines
    included) over the 20 x 4 mm strip: a ring along its edges, trough to crest, a
    line along the ridge, both diagonals and a steep line (where the bilinear surface
    is quadratic along the cut). Each line with whether it cuts."""
    rings = [[(0, 0), (20, 0), (20, 4), (0, 4), (0, 0)],
             [(0, 2), (20, 2)], [(0, 0), (20, 4)], [(0, 4), (20, 0)], [(3, 0), (9, 4)]]
    lines = [("G21 G90 G17 G94", False), ("G0 Z0.5", False), ("M3 S10000", False)]
    for ring in rings:
        lines += [(f"G0 X{ring[0][0]} Y{ring[0][1]}", False), (f"G1 Z{-DEPTH_MM} F1500", False),
                  (f"G1 X{ring[1][0]} Y{ring[1][1]} F8000", True)]
        lines += [(f"X{x} Y{y}", True) for x, y in ring[2:]]
        lines.append(("G0 Z0.5", False))
    return lines + [("M5", False), ("M2", False)]


def machine_steps(text: str, axis: int) -> int:
    """GRBL's target step for a work coordinate: (value + offset) * steps/mm in floats."""
    spm = F32(XY_STEPS_PER_MM if axis < 2 else Z_STEPS_PER_MM)
    return lround_f32(F32(F32(read_float(text) + F32(WORK_ZERO_MM[axis])) * spm))


def test_height_mapped_passes_keep_their_depth_below_a_warped_board(tmp_path):
    program = passes()
    grid = job_grid([text for text, _ in program], MILL)
    assert (len(grid.xs_nm), len(grid.ys_nm)) == (14, 4)
    with grbl_machine(WARPED, probe=SURFACE) as (board, link):
        link.command_checked("G10 L20 P1 X-10 Y12 Z1")
        height_map = probe_height_map(link, grid)
        after_probing = len(settled_trace(board)[0])
        corrector = HeightCorrector(height_map)
        sent = [(GcodeLine(out, index), cuts) for index, (text, cuts) in enumerate(program)
                for out in corrector.line(text)]
        stream(link, [line for line, _ in sent])
        edges = settled_trace(board)
        # a probe whose reach ends above the board (0.1 mm below Z = 0, over the trough
        # at -0.2 mm) touches nothing: GRBL's ALARM:5, named in mm
        short = ProbeGrid((0,), (2 * MM,), 250_000, 100_000, 2_000_000)
        with pytest.raises(ProbeError) as failed:
            probe_height_map(link, short)
        # unlocked, one that starts below the crest (+0.2 mm) already touches: ALARM:4
        link.command_checked("$X")
        low = ProbeGrid((20 * MM,), (2 * MM,), 100_000, 100_000, 2_000_000)
        with pytest.raises(ProbeError) as touching:
            probe_height_map(link, low)
    assert ("the probe touched nothing at X 0.000 Y 2.000 mm (work) from Z 0.250 down to "
            "Z -0.100 mm (work): the board lies deeper there than probe_depth_mm = 0.100 "
            "reaches") in str(failed.value)
    assert failed.value.alarm and failed.value.code == 5
    assert ("the probe already touched at X 20.000 Y 2.000 mm (work), Z 0.100 mm (work), "
            "before it moved: the board lies higher there than probe_clearance_mm = 0.100"
            ) in str(touching.value)
    assert touching.value.code == 4

    # the map holds the surface at every node to within a step (the probe stops on the
    # first step at or below it) and the half um of [PRB:]'s three decimals
    for y, row in zip(grid.ys_nm, height_map.z_nm):
        for x, z in zip(grid.xs_nm, row):
            true_mm = (SURFACE.height((x / 1e6 + WORK_ZERO_MM[0]) * XY_STEPS_PER_MM,
                                      (y / 1e6 + WORK_ZERO_MM[1]) * XY_STEPS_PER_MM)
                       / Z_STEPS_PER_MM - WORK_ZERO_MM[2])
            assert -1.0 / Z_STEPS_PER_MM - 0.5e-3 <= z / 1e6 - true_mm <= 0.5e-3, (x, y, z)

    pos = positions_and_ticks(edges)[0]
    first = len(positions_and_ticks(tuple(e[:after_probing] for e in edges))[0]) - 1
    row, at = first, tuple(pos[first])
    cut_rows = []
    for line, cuts in sent:
        words = {w[0]: w[1:] for w in line.text.split()[1:]}
        if not line.text.startswith(("G0", "G1")) or not set(words) & set("XYZ"):
            continue
        end = tuple(machine_steps(words[a], k) if a in words else at[k]
                    for k, a in enumerate("XYZ"))
        hits = np.nonzero(np.all(pos[row:] == end, axis=1))[0]
        assert len(hits), f"{line.text} never reached {end}"
        if cuts:
            cut_rows.append(np.arange(row, row + int(hits[0]) + 1))
        row, at = row + int(hits[0]), end
    assert row == len(pos) - 1, "steps after the last line"
    rows = np.concatenate(cut_rows)
    x, y, z = pos[rows].T.astype(float)
    surface = SURFACE.z0 + SURFACE.amp * np.sin(2 * math.pi * x / SURFACE.px) \
        * np.sin(2 * math.pi * y / SURFACE.py)
    depth_mm = (surface - z) / Z_STEPS_PER_MM
    error = np.abs(depth_mm - DEPTH_MM)
    # the passes ran over the whole warp, crest to trough
    assert surface.max() - surface.min() >= 0.39 * Z_STEPS_PER_MM
    assert len(rows) > 10_000
    assert error.max() <= TOLERANCE_MM, (
        f"depth {depth_mm[error.argmax()]:.4f} mm at machine step {pos[rows][error.argmax()]}")
    print(f"\nsimulated {edges[0][-1] / 16e6:.1f} s; {len(rows)} steps of cutting passes: "
          f"depth below the surface {depth_mm.min():.4f}..{depth_mm.max():.4f} mm "
          f"(set {DEPTH_MM}), worst {error.max() * 1000:.2f} um off; "
          f"{len(grid.points())} probes")

    # kept with the job's journal, the map gives a resume the very lines that were sent
    journal = Journal(tmp_path / "journal-grbl.json")
    journal.begin(JournalEntry(source="passes", digest="", offset_nm=(0, 0), profile="",
                               group=False, total=len(sent), confirmed=-1, first_index=0,
                               first_seq=0), height_map=height_map)
    again = HeightCorrector(Journal(journal.path).height_map(journal.load()))
    assert [out for text, _ in program for out in again.line(text)] == \
        [line.text for line, _ in sent]

