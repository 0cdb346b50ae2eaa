"""Centre lines beside a fill's ink (plan/ink/beside.py): a pour that KiCad 4 outlines
with strokes of the zone's least width, planned in ink mode, stepped by the reference
machine and the pen-down steps swept by the pen (tests/inked.py) compared with the
copper; the cut put back, and the clipping path by path."""

from __future__ import annotations

import numpy as np
from inked import bare_within, box, joined_islands, plan_and_ink

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.errors import SourcePos
from galileo_cnc.job import PenDown
from galileo_cnc.plan.ink import beside, clip, inking
from galileo_cnc.plan.ink.fill import fill_region
from galileo_cnc.plan.ink.islands import Islands
from galileo_cnc.plan.ink.narrow import NarrowFeature
from galileo_cnc.program.ops import COLUMNS

MM = 1_000_000
PEN = 300_000
TOLERANCE = 1_000
HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n%ADD10C,0.254*%\n"
CONFIG = MachineConfig()


def _square(x0: float, y0: float, x1: float, y1: float) -> list[str]:
    return [f"X{round(x * MM)}Y{round(y * MM)}" for x, y in
            ((x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0))]


def _region(outer: list[str], *holes: list[str]) -> str:
    """A G36 region of one contour, the outer ring with each hole cut in (the hole
    traced the other way round, to its first point and back), then each ring
    stroked with the 0.254 mm aperture along its edge: KiCad 4's zone."""
    contour = list(outer)
    for hole in holes:
        contour += [*hole[::-1], outer[-1]]
    body = "G36*\n" + contour[0] + "D02*\n" + "".join(p + "D01*\n" for p in contour[1:])
    body += "G37*\nD10*\n"
    rings = [outer, *holes]
    for ring in rings:
        body += ring[0] + "D02*\n" + "".join(p + "D01*\n" for p in ring[1:])
    return body


def plot(tmp_path, body: str):
    """(planned job, ink from the steps, copper) of a Gerber body."""
    path = tmp_path / "pour.gbr"
    path.write_text(HEADER + body + "M02*\n")
    return plan_and_ink(path, PEN, CONFIG)


def lifts(planned) -> int:
    return sum(isinstance(command, PenDown) for command in planned.job.commands)


def test_a_pours_outline_strokes_are_not_drawn_beside_its_fill(tmp_path):
    # the region 0.127 mm inside the copper's edge, its outline stroked 0.254 mm wide:
    # a centre line along that outline would spill (0.3 - 0.254) / 2 = 23 um beyond
    # the copper on all 24 mm of edge (0.55 mm²), into the clearance
    planned, ink, copper = plot(tmp_path, _region(_square(0.127, 0.127, 5.873, 5.873)))
    assert not [f for f in planned.ink.narrow if f.pieces and not f.spur]
    assert clip.area_nm2(clip.difference(ink, copper)) < 0.01 * MM * MM
    # the fill's ring reaches the edge: bare only the corners' round pen leaves and the
    # edge margin's band
    bare = clip.area_nm2(clip.difference(copper, ink))
    assert bare < 4 * 0.0002 * MM * MM + 24 * MM * 5_000
    assert not [w for w in planned.ink.warnings if "too narrow to fill" in str(w)]


def test_thermal_spokes_across_a_pours_clearance_are_drawn_as_spurs(tmp_path, monkeypatch):
    # a 2 mm pad in a hole of the pour 0.5 mm wider all round, held by four 0.254 mm
    # spokes from its centre to the pour's outline: one island
    pad = "%ADD11R,2X2*%\nD11*\nX4000000Y4000000D03*\n"
    spokes = "D10*\n" + "".join(f"X4000000Y4000000D02*\nX{x}Y{y}D01*\n" for x, y in (
        (5_563_000, 4_000_000), (2_437_000, 4_000_000), (4_000_000, 5_563_000),
        (4_000_000, 2_437_000)))
    pour = _region(_square(0.127, 0.127, 7.873, 7.873), _square(2.373, 2.373, 5.627, 5.627))
    planned, ink, copper = plot(tmp_path, pour + pad + spokes)
    assert len(clip.components(copper)) == 1
    # the spokes cross the clearance inked: each 0.254 mm neck 0.5 mm long
    for neck in ((5.0, 3.9, 5.5, 4.1), (2.5, 3.9, 3.0, 4.1), (3.9, 5.0, 4.1, 5.5),
                 (3.9, 2.5, 4.1, 3.0)):
        assert bare_within(copper, ink, box(*(round(v * MM) for v in neck))) < \
            0.005 * MM * MM
    # the pour's outline is not drawn: what spills is the spokes' own overdraw only
    # (23 um each side along the 4 x 0.5 mm of clearance, and where they meet the edges)
    assert clip.area_nm2(clip.difference(ink, copper)) < 0.1 * MM * MM
    spurs = [f for f in planned.ink.narrow if f.spur]
    assert spurs
    # spliced into the walks, the spokes cost no pen lift of their own
    monkeypatch.setattr(inking, "into_walks", lambda *args: None)
    alone, _ink, _copper = plot(tmp_path, pour + pad + spokes)
    assert lifts(planned) < lifts(alone)
    assert joined_islands(ink, copper, 30_000) == []


def test_a_cut_shorter_than_two_pens_between_kept_pieces_is_put_back():
    source = np.array([[0, 0], [1_000_000, 0], [1_000_000, 2_000_000]], dtype=np.int64)
    near = [np.array([[0, 0], [400_000, 0]]), np.array([[1_000_000, 2_000_000],
                                                        [1_000_000, 300_000]])]
    # 0.6 + 0.3 mm cut out round the corner: more than two pens, kept apart
    assert len(beside._bridged(source, near, 2 * PEN)) == 2
    (joined,) = beside._bridged(source, [near[0], np.array([[1_000_000, 1_500_000],
                                                            [1_000_000, 100_000]])], 3 * PEN)
    assert joined.tolist() == [[0, 0], [400_000, 0], [1_000_000, 0], [1_000_000, 100_000],
                               [1_000_000, 1_500_000]]
    # a cut just inside each end of the line is no cut between two pieces
    assert beside._bridged(source, [np.array([[0, 0], [1_000_000, 0],
                                              [1_000_000, 1_900_000]])], 2 * PEN)[0] \
        .tolist()[-1] == [1_000_000, 1_900_000]
    # pieces that make the line whole again give back the line itself
    halves = [np.array([[0, 0], [1_000_000, 0], [1_000_000, 500_000]]),
              np.array([[1_000_000, 600_000], [1_000_000, 2_000_000]])]
    (whole,) = beside._bridged(source, halves, 2 * PEN)
    assert whole is source


def test_open_difference_by_path_gives_each_paths_pieces():
    square = [[[0, 0], [1_000_000, 0], [1_000_000, 1_000_000], [0, 1_000_000]]]
    paths = [np.array([[-500_000, 500_000], [1_500_000, 500_000]]),          # flat, cut in two
             np.array([[500_000, -500_000], [500_000, 200_000]]),            # cut at one end
             np.array([[2_000_000, 0], [2_000_000, 1_000_000]]),             # outside: whole
             np.array([[300_000, 300_000], [600_000, 600_000]]),             # inside: nothing
             np.array([[3_000_000, 3_000_000]]),                             # a dot outside
             # round the square and back across its own start (Clipper 6 joins such
             # a path's pieces out of order: cut again exactly)
             np.array([[-200_000, -200_000], [1_200_000, -200_000], [1_200_000, 1_200_000],
                       [500_000, 500_000], [-200_000, -300_000]])]
    by_path = clip.open_difference_by_path(paths, square)
    assert sorted(p.tolist() for p in by_path[0]) == [[[-500_000, 500_000], [0, 500_000]],
                                                      [[1_000_000, 500_000],
                                                       [1_500_000, 500_000]]]
    assert [p.tolist() for p in by_path[1]] in ([[[500_000, -500_000], [500_000, 0]]],
                                                [[[500_000, 0], [500_000, -500_000]]])
    assert [p.tolist() for p in by_path[2]] in ([paths[2].tolist()], [paths[2][::-1].tolist()])
    assert by_path[3] == []
    assert [p.tolist() for p in by_path[4]] == [[[3_000_000, 3_000_000]]]
    # each path's pieces are what open_difference makes of it alone
    for path, pieces in zip(paths, by_path):
        alone = clip.open_difference([path], square)
        assert len(pieces) == len(alone)
        assert abs(_length(pieces) - _length(alone)) < 4


def _length(lines: list[np.ndarray]) -> float:
    return sum(float(np.hypot(*np.diff(line, axis=0).T).sum()) for line in lines)


def test_a_trace_of_the_pens_width_stays_one_line_round_its_bends(tmp_path):
    # 0.3 mm segments, each narrow: at a bend the two capsules make room for the pen,
    # and the fill's ink there would cut both segments' ends; one cut round the joint,
    # shorter than two pens, is put back, so the trace is still drawn as one line
    body = ("%ADD11C,0.3*%\nD11*\nX0Y0D02*\nX5000000Y0D01*\nX5000000Y5000000D01*\n"
            "X10000000Y5000000D01*\n")
    planned, _ink, _copper = plot(tmp_path, body)
    assert lifts(planned) == 1
    assert [(f.cut, f.spur) for f in planned.ink.narrow] == [(False, False)] * 3


RING = ("%ADD12C,0.2*%\nG36*\nX5000000Y7100000D02*\nG03X5000000Y2900000I0J-2100000D01*\n"
        "G01X5000000Y7100000D01*\nG37*\nD12*\nX7000000Y5000000D02*\nG75*\n")


def test_a_full_circle_beside_a_fill_is_cut_along_itself_both_ways_round(tmp_path):
    # a half disc and a 0.2 mm circle (G75, its end at its start) round it: the circle
    # runs beside the fill on the left and alone on the right; what is left of it must
    # follow the circle round its closing point, never cut across it
    for turn in ("G02", "G03"):
        pad = "%ADD13R,0.4X0.4*%\nD13*\nX5900000Y6000000D03*\n"    # another island inside
        body = RING + f"{turn}X7000000Y5000000I-2000000J0D01*\n" + pad
        planned, ink, copper = plot(tmp_path, body)
        assert joined_islands(ink, copper, 30_000) == []
        # the ink beyond the copper is the circle's own overdraw, along the circle
        circle = np.array([[5 * MM + 2 * MM * np.cos(a), 5 * MM + 2 * MM * np.sin(a)]
                           for a in np.linspace(0, 2 * np.pi, 721)]).round().astype(np.int64)
        along = clip.stroke([circle], PEN // 2 + 5_000, 1_000)
        assert clip.area_nm2(clip.difference(clip.difference(ink, copper), along)) < \
            0.001 * MM * MM
        # the circle's right half, away from the half disc, inked whole
        right = box(5_200_000, 2_000_000, 8_000_000, 8_000_000)
        ring = clip.intersection(clip.stroke([circle], 150_000, 1_000), right)
        assert bare_within(copper, ink, ring) < 0.002 * MM * MM


def test_a_traces_end_cap_beside_a_pad_is_still_drawn(tmp_path):
    # a 0.25 mm trace along a 2 mm pad's lower edge, ending just past its corner: the
    # piece left there is short and its centre lies in the pad's ink, but it holds the
    # trace's free end, whose cap the pad's fill does not ink
    body = ("%ADD20R,2X2*%\nD20*\nX5000000Y5000000D03*\n%ADD30C,0.25*%\nD30*\n"
            "X5000000Y4084000D02*\nX3980000Y4084000D01*\n")
    planned, ink, copper = plot(tmp_path, body)
    cap = box(3_800_000, 3_900_000, 4_050_000, 4_250_000)
    assert bare_within(copper, ink, cap) < 0.002 * MM * MM


def test_a_draw_of_no_length_is_left_as_it_was(tmp_path):
    # Eagle writes round pads as draws from a point to itself: Clipper hands such a
    # line back as its one point, which is no cut (else it became a dot of its own)
    body = ("%ADD11R,2X2*%\nD11*\nX5000000Y5000000D03*\n%ADD30C,0.25*%\nD30*\n"
            "X2000000Y2000000D02*\nX2000000Y2000000D01*\nX2000000Y4000000D01*\n")
    planned, _ink, _copper = plot(tmp_path, body)
    assert not any(type(command).__name__ == "Flash" for command in planned.job.commands)
    assert [f.cut for f in planned.ink.narrow] == [False, False]


def test_a_line_that_ends_on_a_walk_is_spliced_into_it():
    # a line cut where it enters a fill's centre area ends on the fill's outer walk,
    # which runs along that area's edge: its way from the walk has no length, and the
    # spur starts with that point twice. Repeats count for nothing when into_walks asks
    # whether the way kept apart (5afa1ad had made them count: such lines were left
    # as strokes of their own, 114 more pen lifts on KiCad's atmega328 F.Cu). Here a
    # 2 mm pad and a 0.254 mm trace through it, one island: the outer walk bulges into
    # the trace's feet, its highest and lowest vertices on the trace's centre line
    # (within a few um), and lines from there along the trace end on the walk
    pad = [[3 * MM, 3 * MM], [5 * MM, 3 * MM], [5 * MM, 5 * MM], [3 * MM, 5 * MM]]
    trace = [[3_373_000, 1 * MM], [3_627_000, 1 * MM], [3_627_000, 7 * MM],
             [3_373_000, 7 * MM]]
    copper = clip.union([pad, trace])
    islands = Islands.of(copper)

    def walks():
        return fill_region(copper, PEN, TOLERANCE, islands=islands.parts,
                           edge_margin_nm=inking.DEFAULT_EDGE_MARGIN_NM)

    def feature(*pieces) -> NarrowFeature:
        return NarrowFeature(op_index=-1, pos=SourcePos("pad", 0, 0), width_nm=254_000,
                             pen_nm=PEN, row=[0] * len(COLUMNS), start_nm=pieces[0][0],
                             pieces=[np.array(piece) for piece in pieces], cut=True)

    def into_walks(line, narrow) -> list:
        fill = walks()
        beside.into_walks([line], narrow, fill, islands, PEN, TOLERANCE, lambda lines: lines)
        return np.concatenate(fill.paths).tolist()

    points = np.concatenate(walks().paths)
    (x, y), (x_low, y_low) = (points[np.argmax(points[:, 1])].tolist(),
                              points[np.argmin(points[:, 1])].tolist())
    assert abs(x - 3_500_000) < 20_000 and abs(x_low - 3_500_000) < 20_000
    top, bottom = [x, 6_800_000], [x_low, 1_200_000]
    unchanged = points.tolist()
    # where it meets two more lines, path order runs on through the junction: no spur
    line = feature([(x, y), top])
    others = [feature([top, [x, 6_950_000]]), feature([top, [x + 50_000, 6_900_000]])]
    assert into_walks(line, [line, *others]) == unchanged and not line.spur
    assert line.pieces[0].tolist() == [[x, y], top]
    # a line of two pieces, one far from any walk: neither is spliced
    line = feature([(x, y), top], [[x_low, 1_200_000], [x_low, 1_100_000]])
    assert into_walks(line, [line]) == unchanged and not line.spur
    # drawn out and back from the walk, the walk otherwise as it was
    line = feature([(x, y), top])
    spliced = into_walks(line, [line])
    assert line.spur and len(spliced) == len(unchanged) + 2 and top in spliced
    # each piece of a line from its own place on the walk
    line = feature([(x, y), top], [bottom, (x_low, y_low)])
    spliced = into_walks(line, [line])
    assert line.spur and len(spliced) == len(unchanged) + 4
    assert top in spliced and bottom in spliced
    assert [piece[-1].tolist() for piece in line.pieces] == [top, bottom]
