"""Isolation passes from the exact copper: every pass keeps half the cut off the copper
(checked by shapely, a library the passes never used), the passes step out by the cut
less the overlap, islands the tool cannot pass between are listed where their gap is
narrowest, and a job with such shorts is refused unless they are accepted."""

import numpy as np
import pytest
import shapely

from corpus import corpus_file
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.plan.ink.edges import EdgeIndex
from galileo_cnc.plan.ink.geometry import dark_geometry
from galileo_cnc.plan.ink.islands import Islands
from galileo_cnc.plan.mill.isolate import (MILL_TOLERANCE_NM, ShortsError, find_shorts,
                                           isolate, pass_radii, refuse_shorts)
from galileo_cnc.plan.mill.proof import prove
from galileo_cnc.readers import read_file

# two round pads joined by a trace, a square pad 0.1 mm right of the second round pad,
# and a lone pad far off
BOARD = """%FSLAX46Y46*%
%MOMM*%
%ADD10C,1.0*%
%ADD11C,0.25*%
%ADD12R,1.0X1.0*%
D10*
X0Y0D03*
X5000000Y0D03*
D11*
X0Y0D02*
X5000000Y0D01*
D12*
X6100000Y0D03*
X20000000Y20000000D03*
M02*
"""
#: the 30 deg V-bit, 0.1 mm deep: 0.1 + 0.2 tan(15 deg) = 0.154 mm wide
VBIT = MillConfig(passes=3, overlap_permille=400)


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    path = tmp_path_factory.mktemp("mill") / "board.gtl"
    path.write_text(BOARD)
    return read_file(str(path))


def _shapely_clearance(rings, copper) -> float:
    """The least distance from the closed rings to the copper, by shapely."""
    lines = shapely.MultiLineString([np.vstack([ring, ring[:1]]) for ring in rings])
    return lines.distance(copper)


def _copper(isolation):
    return shapely.MultiPolygon([shapely.Polygon(outer, holes)
                                 for outer, holes in isolation.islands.parts])


def test_every_pass_keeps_half_the_cut_and_each_next_steps_out_a_cut_less_the_overlap(board):
    isolation = isolate(board, VBIT)
    width, step = VBIT.cut_width_nm, VBIT.step_nm
    assert (width, step) == (153_590, 92_154)
    assert len(isolation.passes) == 3
    copper = _copper(isolation)
    clearances = [_shapely_clearance(rings, copper) for rings in isolation.passes]
    for k, clearance in enumerate(clearances):
        assert clearance >= width / 2 + k * step - 1_000
    # the first pass hugs the copper: no further off than its margin
    assert clearances[0] <= width / 2 + isolation.margin_nm
    assert np.allclose(np.diff(clearances), step, atol=isolation.margin_nm)
    proof = prove(isolation)
    assert proof.holds and proof.entries == 0 and proof.swept_in_copper_nm2 == 0
    assert proof.clearance_nm == pytest.approx(clearances[0], abs=1)


def test_islands_closer_than_the_cut_are_a_short_at_the_middle_of_their_gap(board):
    isolation = isolate(board, VBIT)
    # three islands: the pads and trace, the square pad 0.1 mm off, the lone pad
    assert len(isolation.islands.parts) == 3
    (short,) = isolation.shorts
    # the round pad's edge at x = 5.5 mm, the square's at 5.6: 0.1 mm apart at x = 5.55
    assert short.gap_nm == pytest.approx(100_000, abs=2)
    assert short.at_nm == (5_550_000, 0)
    assert "0.1 mm apart at X5.550 Y0.000 mm (work)" in short.describe()
    # an end mill 0.09 mm wide passes between them
    assert isolate(board, MillConfig(tool="endmill", diameter_nm=90_000)).shorts == []


def test_a_job_with_shorts_is_refused_unless_they_are_accepted(board):
    isolation = isolate(board, VBIT)
    with pytest.raises(ShortsError) as refused:
        refuse_shorts(isolation)
    text = str(refused.value)
    assert "1 place(s) where two copper islands are closer than the 0.154 mm cut" in text
    assert "X5.550 Y0.000 mm (work)" in text and "--accept-shorts" in text
    refuse_shorts(isolation, accept_shorts=True)
    refuse_shorts(isolate(board, MillConfig(tool="endmill", diameter_nm=90_000)))


def test_the_proof_fails_a_pass_that_enters_the_copper(board):
    isolation = isolate(board, MillConfig())
    # the first pass moved 5 um in: a cut the proof must see
    from galileo_cnc.plan.ink import clip

    closer = isolation.radii_nm[0] - isolation.margin_nm - 5_000
    isolation.passes = [clip.rings_as_arrays(clip.offset(isolation.copper, closer, 500))]
    proof = prove(isolation)
    assert not proof.holds and proof.clearance_nm < isolation.cut_width_nm / 2
    assert proof.swept_in_copper_nm2 > 0
    assert "A PASS ENTERS THE COPPER" in proof.describe()


def test_a_real_copper_layer_is_isolated_without_touching_its_copper():
    program = read_file(str(corpus_file("altium/usbvil/pic18f14k50.gtl")))
    isolation = isolate(program, MillConfig(passes=2))
    copper = _copper(isolation)
    assert len(isolation.islands.parts) == 38 and isolation.shorts == []
    assert _shapely_clearance(isolation.rings, copper) >= MillConfig().cut_width_nm / 2 - 1_000
    assert prove(isolation).holds
    # a 0.3 mm end mill cannot pass between the chip's pads: every pair of islands
    # under two first-pass radii apart (by shapely) is a short, at its gap
    wide = isolate(program, MillConfig(tool="endmill", diameter_nm=300_000))
    polygons = [shapely.Polygon(outer, holes) for outer, holes in wide.islands.parts]
    gaps = {(a, b): polygons[a].distance(polygons[b])
            for a in range(len(polygons)) for b in range(a + 1, len(polygons))}
    close = {pair: gap for pair, gap in gaps.items() if gap < 2 * wide.radii_nm[0]}
    assert len(close) == 31
    assert {short.islands: short.gap_nm for short in wide.shorts} == pytest.approx(close, abs=2)
    for short in wide.shorts:                # the midpoint lies between the two islands
        middle = shapely.Point(short.at_nm)
        a, b = (polygons[k] for k in short.islands)
        assert middle.distance(a) == pytest.approx(short.gap_nm / 2, abs=2)
        assert middle.distance(b) == pytest.approx(short.gap_nm / 2, abs=2)


def _cuts(text: str, depth_nm: int) -> list[np.ndarray]:
    """The XY paths the G-code cuts at `depth_nm` below the copper's top, each a closed
    ring of points (nm), read line by line as GRBL would (modal G0/G1, absolute mm)."""
    x = y = z = 0.0
    cuts, path = [], []
    for line in text.splitlines():
        words = dict((w[0], w[1:]) for w in line.split() if not line.startswith("("))
        x, y = float(words.get("X", x)), float(words.get("Y", y))
        z = float(words.get("Z", z))
        cutting = abs(z * 1e6 + depth_nm) < 1
        if cutting and ("X" in words or "Y" in words or not path):
            path.append((round(x * 1e6), round(y * 1e6)))
        elif not cutting and path:
            cuts.append(np.array(path))
            path = []
    return cuts


def test_the_g_code_cuts_the_proven_passes_at_depth_and_refuses_unaccepted_shorts(board):
    from galileo_cnc.plan.mill.gcode import mill_gcode

    with pytest.raises(ShortsError):
        mill_gcode(board, VBIT)
    accepted = mill_gcode(board, VBIT, accept_shorts=True)
    assert "(short accepted: islands 0 and 1: 0.1 mm apart at X5.550 Y0.000 mm [work])" \
        in accepted.splitlines()
    mill = MillConfig(tool="endmill", diameter_nm=90_000, cut_depth_nm=50_000,
                      safe_height_nm=1_500_000, spindle_rpm=9_000, feed_um_min=200_000,
                      plunge_feed_um_min=40_000, passes=2)
    text = mill_gcode(board, mill)
    lines = text.splitlines()
    assert "G21 G90 G17 G94" in lines and "M3 S9000" in lines and lines[-2:] == ["M5", "M2"]
    plunges = [line for line in lines if line.startswith("G1 Z")]
    assert plunges and set(plunges) == {"G1 Z-0.05 F40"}
    assert lines.count("G0 Z1.5") == len(plunges) + 1
    cuts = _cuts(text, 50_000)
    isolation = isolate(board, mill)
    assert len(cuts) == len(isolation.rings) == len(plunges)
    assert all((cut[0] == cut[-1]).all() for cut in cuts)           # each ring closed
    copper = _copper(isolation)
    assert _shapely_clearance([cut[:-1] for cut in cuts], copper) >= 45_000 - 1_000


def _square(x0: int, y0: int, side: int = 1_000_000) -> list:
    return [[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]]


def test_any_gap_is_a_short_but_copper_that_meets_at_a_corner_is_one_island():
    from galileo_cnc.plan.mill.isolate import isolate_copper

    # 3 um apart: under the ink's 5 um touch, still two islands the tool leaves joined
    (short,) = isolate_copper([_square(0, 0), _square(1_003_000, 0)], VBIT).shorts
    # parallel edges: every point between them is as narrow; one on the middle line
    assert short.gap_nm == 3_000 and short.at_nm[0] == 1_001_500
    assert 0 <= short.at_nm[1] <= 1_000_000
    # meeting at a corner: Clipper keeps two pieces, the copper is one
    corner = isolate_copper([_square(0, 0), _square(1_000_000, 1_000_000)], VBIT)
    assert len(corner.islands.parts) == 2 and corner.shorts == []


def test_a_layer_without_copper_is_refused(tmp_path):
    from galileo_cnc.plan.mill.gcode import MillError, mill_gcode

    path = tmp_path / "empty.gtl"
    path.write_text("%FSLAX46Y46*%\n%MOMM*%\nM02*\n")
    with pytest.raises(MillError, match="no copper on this layer: nothing to isolate"):
        mill_gcode(read_file(str(path)), MillConfig())


def test_the_proof_sees_a_pass_inside_a_pour_and_one_across_a_trace():
    from galileo_cnc.plan.mill.isolate import isolate_copper

    pour = isolate_copper([_square(0, 0, 10_000_000)], MillConfig())
    # a ring deep inside the pour: 4 mm from every edge, yet in the copper
    pour.passes = [[np.array(_square(4_000_000, 4_000_000, 2_000_000))]]
    proof = prove(pour)
    assert proof.clearance_nm == 4_000_000 and proof.entries == 4 and not proof.holds
    # a ring whose side crosses a 0.2 mm trace: every vertex 2 mm or more from it
    trace = [[0, 0], [10_000_000, 0], [10_000_000, 200_000], [0, 200_000]]
    across = isolate_copper([trace], MillConfig())
    across.passes = [[np.array(_square(4_000_000, -2_000_000, 4_000_000))]]
    proof = prove(across)
    assert proof.entries == 4 and not proof.holds       # two sides, each over both edges
    assert proof.swept_in_copper_nm2 > 0                # the second witness agrees


def test_a_refusal_lists_the_first_shorts_and_counts_the_rest():
    from galileo_cnc.plan.mill.isolate import SHOWN_SHORTS, isolate_copper

    # a row of squares 0.1 mm apart: one short between each two
    row = [_square(k * 1_100_000, 0) for k in range(SHOWN_SHORTS + 6)]
    isolation = isolate_copper(row, VBIT, source="row.gtl")
    assert len(isolation.shorts) == SHOWN_SHORTS + 5
    with pytest.raises(ShortsError) as refused:
        refuse_shorts(isolation)
    text = str(refused.value)
    assert text.startswith(f"row.gtl: {SHOWN_SHORTS + 5} place(s)")
    assert text.count("mm (work)") == SHOWN_SHORTS and "... and 5 more" in text


def _every_vertex_edge_pair(reach_nm):
    """Every (vertex, edge) pair of different islands, by vertex then edge, but those
    whose vertex lies `reach_nm` or more outside the edge's box (no short)."""
    def pairs(index, owner):
        low = np.minimum(index.a, index.b) - reach_nm
        high = np.maximum(index.a, index.b) + reach_nm
        vertices, edges = [], []
        for first in range(0, len(index.a), 256):
            vertex = np.arange(first, min(first + 256, len(index.a)))[:, None]
            point = index.a[vertex]
            near = (np.all((point > low) & (point < high), axis=-1)
                    & (owner[vertex] != owner[None, :]))
            found_vertex, found_edge = np.nonzero(near)
            vertices.append(vertex[found_vertex, 0])
            edges.append(found_edge)
        return np.concatenate(vertices), np.concatenate(edges)
    return pairs


def test_the_indexed_short_search_finds_what_the_exhaustive_one_does():
    program = read_file(str(corpus_file("altium/usbvil/pic18f14k50.gtl")))
    copper = dark_geometry(program, MILL_TOLERANCE_NM).native
    islands = Islands.of(copper)
    reach = 2 * pass_radii(MillConfig(tool="endmill", diameter_nm=300_000))[0]
    index = EdgeIndex(islands.rings, cell_nm=reach)
    owner = islands.owner[index.ring]
    vertex, edge = index.around_vertices(owner)
    # each pair once, by vertex then edge, of different islands
    keys = vertex * len(index.a) + edge
    assert (np.diff(keys) > 0).all() and (owner[vertex] != owner[edge]).all()
    shorts = find_shorts(islands, reach)
    assert len(shorts) == 31
    assert shorts == find_shorts(islands, reach, pairs=_every_vertex_edge_pair(reach))
