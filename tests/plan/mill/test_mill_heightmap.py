"""The height map, pure: the probe grid over a job, exact bilinear heights (the probed
value at every node, the plane between), cuts split so GRBL's straight Z between two
piece ends stays within LINEAR_Z_BOUND_NM of the surface, every Z of a program moved by
the map line by line, and the map kept beside the job's journal for a resume."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from fractions import Fraction

import pytest

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.plan.mill.heightmap import (
    LINEAR_Z_BOUND_NM, HeightCorrector, HeightMap, HeightMapError, axis_nodes, corrected_lines,
    cutting_box, grid_over, job_grid, parse_prb, probe_lines, split_parameters,
)
from galileo_cnc.stream.journal import Journal, JournalEntry, JournalError

MM = 1_000_000
#: a twisted map: 0.2 mm of warp, corners of each cell not in a plane
WARPED = HeightMap((0, 5 * MM, 10 * MM), (0, 4 * MM),
                   ((200_000, -150_000, 50_000), (-200_000, 120_000, 0)))


def words(line: str) -> dict[str, int]:
    """The axis words of a corrected line, in nm."""
    out = {}
    for word in line.split()[1:]:
        if word[0] in "XYZ":
            whole, _, fraction = word[1:].lstrip("-").partition(".")
            value = int(whole) * MM + int((fraction + "000000")[:6])
            out[word[0]] = -value if word[1] == "-" else value
    return out


def test_the_map_is_exact_at_its_nodes_and_bilinear_between():
    for row, y in zip(WARPED.z_nm, WARPED.ys_nm):
        for z, x in zip(row, WARPED.xs_nm):
            assert WARPED.exact(x, y) == z and WARPED.at(x, y) == z
    # a cell's middle is the mean of its corners; along an edge the height is linear
    assert WARPED.exact(2_500_000, 2_000_000) == Fraction(200_000 - 150_000 - 200_000 + 120_000, 4)
    assert WARPED.exact(1_000_000, 0) == Fraction(4 * 200_000 + 1 * -150_000, 5)
    assert WARPED.at(7_500_001, 4_000_000) == 60_000      # (120000 + 0) / 2, less 1 nm's worth
    # outside the grid: the edge's height
    assert WARPED.at(-3 * MM, 0) == 200_000 and WARPED.at(12 * MM, 9 * MM) == 0


def test_a_diagonal_cut_is_split_so_every_chord_keeps_the_bound():
    start, end = (100_000, 3_900_000), (9_800_000, 300_000)
    ts = [Fraction(0), *split_parameters(WARPED, start, end), Fraction(1)]
    # it crosses X = 5 mm (the grid line) exactly there
    crossing = Fraction(5 * MM - start[0], end[0] - start[0])
    assert crossing in ts
    worst = 0
    for a, b in zip(ts, ts[1:]):
        za, zb = (WARPED.exact(*point(start, end, t)) for t in (a, b))
        for k in range(1, 8):
            t = a + (b - a) * Fraction(k, 8)
            chord = za + (zb - za) * Fraction(k, 8)
            worst = max(worst, abs(chord - WARPED.exact(*point(start, end, t))))
    assert worst <= LINEAR_Z_BOUND_NM
    # the split is needed: the grid crossing alone leaves chords far off the surface
    ends = [WARPED.exact(*point(start, end, t)) for t in (Fraction(0), crossing)]
    unsplit = abs(sum(ends) / 2 - WARPED.exact(*point(start, end, crossing / 2)))
    assert unsplit > 20 * LINEAR_Z_BOUND_NM


def point(start, end, t: Fraction) -> tuple[Fraction, Fraction]:
    """The exact point at t along start -> end (exact() takes Fractions as well)."""
    return (start[0] + (end[0] - start[0]) * t, start[1] + (end[1] - start[1]) * t)


def test_an_axis_parallel_cut_is_split_only_at_the_grid_lines():
    # along X the bilinear surface is linear in each cell: no piece but the crossings
    assert split_parameters(WARPED, (0, 1_000_000), (10 * MM, 1_000_000)) == [Fraction(1, 2)]
    assert split_parameters(WARPED, (1_000_000, 0), (1_000_000, 4 * MM)) == []


def test_bilinear_error_of_the_test_warp_is_within_its_stated_bound():
    """tests/grbl/test_height_map_grbl.py's warp and grid: 0.2 mm sin sin over 40 mm
    periods, 1.538 x 1.333 mm cells; the bound A k^2 s^2 / 4 (s the larger side) is 2.9 um.
    Over a whole period in Y too, crests and troughs both ways."""
    amp, k = 200_000, 2 * math.pi / (40 * MM)
    xs, ys = axis_nodes(10 * MM, 30 * MM, 1_600_000), axis_nodes(-12 * MM, -8 * MM, 1_600_000)
    ys = tuple(y + shift for shift in range(0, 40 * MM, 4 * MM) for y in ys[:-1]) + (28 * MM,)
    height_map = HeightMap(xs, ys, tuple(tuple(round(amp * math.sin(k * x) * math.sin(k * y))
                                               for x in xs) for y in ys))
    bound = amp * k * k * (xs[1] - xs[0]) ** 2 / 4
    assert 2_900 < bound < 3_000
    worst = max(abs(height_map.exact(x, y) - amp * math.sin(k * x) * math.sin(k * y))
                for x in range(10 * MM, 30 * MM + 1, 97_000) for y in range(-12 * MM, 28 * MM, 331_000))
    assert 1_000 < worst <= bound + 1


ISOLATION = """(galileo-cnc mill: isolation of board.gbr)
G21 G90 G17 G94
G0 Z2
M3 S10000
G0 X1 Y1
G1 Z-0.1 F60
G1 X9 Y3 F120
X9 Y1
X1 Y1
G0 Z2
M5
M2
""".splitlines()


def test_every_z_of_a_program_is_moved_by_the_map_and_cuts_are_split():
    out = list(corrected_lines(ISOLATION, WARPED))
    assert out[:5] == ISOLATION[:5]                     # comment, modes, up, spindle, travel
    # at X1 Y1 the map is (200000*4*3 - 150000*1*3 - 200000*4*1 + 120000*1*1) / 20
    assert WARPED.at(MM, MM) == 63_500
    assert out[5] == "G1 Z-0.0365 F60"
    cuts = out[6:out.index("G0 Z2.0635")]     # the rise: where the last cut ended, by the map
    # the cut's first piece keeps the feed; every piece a G1 with its own Z, on the surface
    assert cuts[0].endswith(" F120") and all(line.startswith("G1 X") for line in cuts)
    for line in cuts:
        at = words(line)
        assert at["Z"] == -100_000 + WARPED.at(at["X"], at["Y"])
    ends = [(words(line)["X"], words(line)["Y"]) for line in cuts]
    assert {(9 * MM, 3 * MM), (9 * MM, MM), (MM, MM)} <= set(ends) and ends[-1] == (MM, MM)
    assert (5 * MM, MM) in ends                         # X9 Y1 -> X1 Y1 crosses X = 5
    assert out[-2:] == ["M5", "M2"]


def test_the_correction_runs_line_by_line():
    """A generator over the program: its first lines come before the rest is read."""
    read = []

    def program():
        for line in ISOLATION:
            read.append(line)
            yield line

    lines = corrected_lines(program(), WARPED)
    assert [next(lines) for _ in range(6)][-1] == "G1 Z-0.0365 F60"
    assert len(read) == 6


def test_an_arc_gets_its_end_z_and_a_re_zero_re_bases_the_map():
    corrector = HeightCorrector(WARPED)
    lines = ["G0 X2 Y2", "G1 Z-0.5 F60", "G2 X4 Y2 I1 J0", "G0 Z2", "G38.2 Z-10 F60",
             "G92 Z0", "G0 Z2", "G1 Z-0.1"]
    out = [corrector.line(text) for text in lines]
    arc = words(out[2][0])
    assert out[2][0].startswith("G2 X4 Y2 Z") and out[2][0].endswith("I1 J0")
    assert arc["Z"] == -500_000 + WARPED.at(4 * MM, 2 * MM)
    assert out[4] == ["G38.2 Z-10 F60"] and out[5] == ["G92 Z0"]     # as they are
    # Z = 0 is now the surface at X4 Y2: the map's height there is 0
    assert corrector.height_map.at(4 * MM, 2 * MM) == 0
    assert out[6] == ["G0 Z2"] and out[7] == ["G1 Z-0.1"]
    # G92.1 clears the offset: the probed map again
    assert corrector.line("G92.1") == ["G92.1"] and corrector.height_map == WARPED


@pytest.mark.parametrize("lines, message", [
    (["G0 X12 Y1", "G1 Z-0.1"], "2: cuts at X 12.000 Y 1.000 mm (work), outside the "
                                "height map (X 0.000..10.000 Y 0.000..4.000 mm)"),
    (["G91", "G1 X1"], "1: relative moves (G91)"),
    (["G20"], "1: inches (G20)"),
    (["G0 X1 Y1", "G10 L20 P1 X0 Y0"], "2: a work offset moved in X or Y"),
    (["G0 Z1", "G1 Z-0.1 F60"], "2: a cut where X and Y are unknown"),
])
def test_what_the_map_cannot_correct_is_refused_naming_the_line(lines, message):
    with pytest.raises(HeightMapError) as refused:
        list(corrected_lines(lines, WARPED, "board.nc"))
    assert f"board.nc:{message}" in str(refused.value)


def test_the_grid_spans_where_the_job_cuts_in_rows_that_turn():
    mill = MillConfig(height_map_spacing_nm=3 * MM, probe_clearance_nm=MM,
                      probe_depth_nm=500_000, probe_feed_um_min=50_000)
    box = cutting_box(ISOLATION)
    assert box == (MM, MM, 9 * MM, 3 * MM)              # the travel above the board is not
    grid = grid_over(box, mill)
    assert job_grid(ISOLATION, mill) == grid
    with pytest.raises(HeightMapError, match="board.nc: the job cuts nowhere below Z = 0"):
        job_grid(["G0 X1 Y1", "G1 Z0.5"], mill, "board.nc")
    assert grid.xs_nm == (MM, 3_666_666, 6_333_333, 9 * MM) and grid.ys_nm == (MM, 3 * MM)
    assert grid.points()[:5] == [(MM, MM), (3_666_666, MM), (6_333_333, MM), (9 * MM, MM),
                                 (9 * MM, 3 * MM)]
    assert probe_lines(grid)[1] == ["G0 Z1", "G0 X3.666666 Y1", "G38.2 Z-0.5 F50", "G0 Z1"]
    assert "4 x 2 points over X 1.000..9.000 Y 1.000..3.000 mm (work), at most 2.667 mm " \
           "apart" in grid.describe()
    assert axis_nodes(5, 5, 3) == (5,)
    with pytest.raises(HeightMapError, match="raise height_map_spacing_mm"):
        axis_nodes(0, 300 * MM, MM)


def test_grbl_probe_reports_are_read_exactly():
    assert parse_prb("[PRB:10.000,-2.500,-0.805:1]") == ((10 * MM, -2_500_000, -805_000), True)
    assert parse_prb("[PRB:0.000,0.000,0.000:0]") == ((0, 0, 0), False)
    assert parse_prb("[GC:G0 G54]") is None


def test_the_map_is_kept_beside_the_journal_and_resume_reads_it_back(tmp_path):
    journal = Journal(tmp_path / "journal-grbl.json")
    entry = JournalEntry(source="board", digest="", offset_nm=(0, 0), profile="", group=False,
                         total=10, confirmed=-1, first_index=0, first_seq=0)
    journal.begin(entry, height_map=WARPED)
    assert journal.height_map_path == tmp_path / "journal-grbl.heightmap.json"
    stored = Journal(tmp_path / "journal-grbl.json").load()
    assert len(stored.height_map) == 64 and journal.height_map(stored) == WARPED
    # a resume begins the old entry again: its map stays
    journal.begin(stored)
    assert journal.height_map(journal.load()) == WARPED
    # a changed or missing map is refused, never replaced by a new probing
    path = journal.height_map_path
    path.write_text(json.dumps(replace(WARPED, z_nm=((0, 0, 0), (0, 0, 0))).to_json()))
    with pytest.raises(JournalError, match="not the one the journal names"):
        journal.height_map(stored)
    path.unlink()
    with pytest.raises(JournalError, match="which is missing: it cannot resume by another map"):
        journal.height_map(stored)
    # a job without a map: none, and no stale file left
    path.write_text("{}")
    journal.begin(replace(entry, height_map=None))
    assert journal.height_map(journal.load()) is None and not path.exists()
    with pytest.raises(HeightMapError, match="nodes must rise"):
        HeightMap.from_json({"xs_nm": [2, 1], "ys_nm": [0], "z_nm": [[0, 0]]})
