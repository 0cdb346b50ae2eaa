"""Our Gerber reader against two readers nobody here wrote: gerbonara and pygerber.

For every readable corpus file (MANIFEST kind real/synthetic/derived) and each peer:
flash, draw and arc counts per D-code, region counts and the bounding box of centre
lines, arc extremes and flash points (within 1 um) must match our reading.

Where a peer is wrong or cannot read a file, the tables below name the file and the
reason, and the test asserts that exact behaviour instead of skipping: a peer that
starts reading a file, or gets it wrong differently, fails the test until someone
reviews the entry. Where OUR reader is wrong, nothing is listed: the test fails.

Each file is read once per reader per session (functools.cache). pygerber is slow
(about 30 kB/s; some 13 CPU-minutes for the whole corpus); set
GALILEO_PYGERBER_MAX_BYTES (below) bounds the files it is compared on.
"""

from __future__ import annotations

import functools
import logging
import os
import re
from dataclasses import dataclass

import pytest

from corpus import FULL, GERBER_CURATED
from peers import (BBOX_TOLERANCE_NM, PEERS, bbox_close, corpus_dir, corpus_files,
                   differences, ours_summary)

FILES = corpus_files()
PATHS = [f.path for f in FILES]
SOURCES = {f.path: f.source for f in FILES}
MM = 1_000_000
INCH = 25_400_000

pytestmark = [
    pytest.mark.skipif(not FILES, reason=f"no corpus at {corpus_dir()}"),
    # pygerber's grammar module uses pyparsing names pyparsing now deprecates
    pytest.mark.filterwarnings("ignore::DeprecationWarning:pygerber"),
]


# --------------------------------------------------------------------------- expectations


@dataclass(frozen=True)
class Fails:
    """The peer cannot read the file: it raises, with a message matching `error`."""

    reason: str
    error: str  # regex searched in "Type: message <- CauseType: message"


@dataclass(frozen=True)
class Differs:
    """The peer reads the file, and differs from us in exactly these ways."""

    reason: str
    lines: tuple[str, ...]  # exactly what peers.differences() reports

    def check(self, ours, peer, rel, name):
        return _same_list(differences(ours, peer), list(self.lines))


@dataclass(frozen=True)
class StepRepeatOnce:
    """The peer draws a %SR block once instead of nx * ny times.

    Everything it drew inside the block we must have drawn nx * ny times, and our
    bounding box is its box stretched by (nx - 1) steps in X and (ny - 1) in Y.
    `outside` lists D-codes used only outside the block (drawn once by both); with
    them the box can only be checked for containment.
    """

    reason: str
    nx: int
    ny: int
    step_x_nm: int
    step_y_nm: int
    outside: frozenset[int] = frozenset()

    def check(self, ours, peer, rel, name):
        n = self.nx * self.ny
        problems = []
        for name in ("flashes_by_aperture", "draws_by_aperture", "arcs_by_aperture"):
            a, b = getattr(ours, name), getattr(peer, name)
            for code in sorted(set(a) | set(b)):
                factor = 1 if code in self.outside else n
                if a.get(code, 0) != b.get(code, 0) * factor:
                    problems.append(f"{name} D{code}: ours {a.get(code, 0)}, "
                                    f"peer {b.get(code, 0)} x {factor}")
        for name in ("region_count", "contour_count", "region_segments"):
            a, b = getattr(ours, name), getattr(peer, name)
            if a is not None and b is not None and a != b * n:
                problems.append(f"{name}: ours {a}, peer {b} x {n}")
        for name in ("bbox_nm", "region_bbox_nm"):
            a, b = getattr(ours, name), getattr(peer, name)
            if b is None:
                continue
            if self.outside:
                if a is None or not (a[0] <= b[0] and a[1] <= b[1] and a[2] >= b[2]
                                     and a[3] >= b[3]):
                    problems.append(f"{name}: ours {a} does not contain peer {b}")
                continue
            want = (b[0], b[1], b[2] + (self.nx - 1) * self.step_x_nm,
                    b[3] + (self.ny - 1) * self.step_y_nm)
            if not bbox_close(a, want, BBOX_TOLERANCE_NM):
                problems.append(f"{name}: ours {a}, peer {b} stretched {want}")
        if not differences(ours, peer):
            problems.append("the peer now agrees with us: remove the entry")
        return problems


@dataclass(frozen=True)
class IncrementalAsAbsolute:
    """The peer reads incremental coordinates as absolute ones.

    Counts still match, the box does not; and the same peer reading the absolute
    original (`original`, the file the derived one was made from) must agree with
    our reading of the incremental file.
    """

    reason: str

    def check(self, ours, peer, rel, name):
        problems = []
        diffs = differences(ours, peer)
        if any(not d.startswith(("bbox_nm", "region_bbox_nm")) for d in diffs):
            problems.append(f"counts differ too: {diffs}")
        if not any(d.startswith("bbox_nm") for d in diffs):
            problems.append("the bounding boxes agree: the peer reads incremental now?")
        original = _original_of(rel)
        return problems + [f"vs peer reading {original}: {d}" for d in
                           differences(ours, _peer(name, original)[0])]


def _same_list(got: list[str], want: list[str]) -> list[str]:
    if got == want:
        return []
    return ([f"unexpected: {g}" for g in got if g not in want]
            + [f"no longer seen: {w}" for w in want if w not in got])


def _original_of(rel: str) -> str:
    m = re.search(r"\(derived from (\S+)\)", SOURCES[rel])
    assert m, f"{rel}: MANIFEST source names no original"
    return m.group(1)


def _fails(reason: str, error: str, *paths: str) -> dict:
    return {p: Fails(reason, error) for p in paths}


EKF2 = [f"unknown/ekf2/{n}.grb" for n in
        ("d1", "l0", "l1", "l3", "l4", "pow", "pow3", "sieb0", "sieb1", "stp0", "stp1")]
UCAMCO_496 = [f"ucamco-spec/spec-4.9.6/{n}.grb" for n in
              ("source", "source_1", "source_2", "source_no_ld_rot")]
SR_PYGERBER = "synthetic-pygerber/step_and_repeat"
SR_ONCE = "gerbonara 1.5 collects %SR objects into a list it never appends to, so a " \
          "step-and-repeat block is drawn once"
UNCLOSED_SR = "pygerber only emits an %SR block at its closing %SR*%; a block still " \
              "open at M02 is dropped"
AXIS_SELECT = "%ASAYBX* swaps the A/B axes (the file's own comment: the line must " \
              "render along Y); the peer parses %AS but never applies it"

GERBONARA: dict[str, object] = {
    **_fails("outline macro primitive whose last point misses the first by float "
             "rounding; gerbonara demands exact equality", r"Last point must equal first",
             "unknown/pcb-tools-issue-211/main.gtl"),
    **_fails("%ADD..R with one modifier (width only); gerbonara's RectangleAperture "
             "needs two", r"list index out of range", *EKF2),
    **_fails("macro name with spaces (Mentor: 'VB_Custom_Fiducial Mimot Dot 1.0 "
             "Mask_Mirrored'); gerbonara's name pattern drops the %AD, then D11 is "
             "undefined", r"undefined aperture 11", "mentor-xpedition/ekf-ccgr0/stp0.grb"),
    **_fails("coordinate-only word after D02/D03 (deprecated, means 'repeat the last D "
             "code'); gerbonara accepts it only after D01", r"Ambiguous coordinate statement",
             "zuken-visula/jj/l1-3.grb"),
    **_fails("block apertures (%AB) unsupported: the block's D code stays undefined",
             r"undefined aperture", "ucamco-spec/spec-4.11.4/source.grb", *UCAMCO_496,
             f"{SR_PYGERBER}/ab/01_cr_xy_2_2.grb"),
    **_fails("macro primitive 22 (lower-left rectangle, deprecated) unsupported",
             r"Unknown aperture macro primitive code 22",
             "synthetic-gerbv/am-test/am-test.gbx",
             "synthetic-tracespace/macro-primitives/lower-left-rect-primitive.gbr"),
    **_fails("obround aperture used for a D01 draw; gerbonara refuses non-circular "
             "stroke apertures", r"Non-circular aperture used in interpolation",
             "synthetic-gerbv/test-inputs/test-aperture-obround-1.gbx"),
    **_fails("no %MO in the file; gerbonara refuses to assume a unit",
             r"does not contain a unit definition",
             "synthetic-gerbv/amacro-ref/full-ex.grb", "synthetic-gerbv/amacro-ref/limit-ex.grb",
             "ucamco-spec/spec-4.10.4.7/source.grb"),
    **_fails("rectangular hole (two hole sizes) in a C/R/O/P aperture, from older "
             "RS-274X; gerbonara takes one hole diameter", r"__init__\(\) takes",
             "synthetic-gerbv/test-inputs/test-aperture-circle-flash-1.gbx",
             "synthetic-gerbv/test-inputs/test-aperture-rectangle-flash-1.gbx",
             "synthetic-gerbv/test-inputs/test-aperture-obround-flash-1.gbx",
             "synthetic-tracespace/pads/polygon-with-rect-hole.gbr",
             "synthetic-tracespace/pads/rectangle-with-rect-hole.gbr"),
    **_fails("aperture modifiers with a trailing 'X' (%ADD14C,0.1X*%)",
             r"could not convert string to float", "synthetic-gerbv/exposure/example.grb"),
    **_fails("fragment meant for %IF inclusion: no %FS/%MO/%AD at all; gerbonara "
             "refuses the undefined D10 (we assume defaults and warn)",
             r"undefined aperture 10", "synthetic-gerbv/test-inputs/include-file-1.gbx"),

    f"{SR_PYGERBER}/00_cr_x_3.grb": StepRepeatOnce(SR_ONCE, 3, 1, 8 * MM, 0),
    f"{SR_PYGERBER}/01_cr_y_3.grb": StepRepeatOnce(SR_ONCE, 1, 3, 0, 6 * MM),
    f"{SR_PYGERBER}/01_cr_y_6.grb": StepRepeatOnce(SR_ONCE, 1, 6, 0, 6 * MM),
    f"{SR_PYGERBER}/02_cr_xy_6_6.grb": StepRepeatOnce(SR_ONCE, 6, 6, 8 * MM, 6 * MM),
    f"{SR_PYGERBER}/line/01_cr_xy_2_2.grb": StepRepeatOnce(SR_ONCE, 6, 6, 8 * MM, 6 * MM),
    f"{SR_PYGERBER}/line/02_cr_xy_2_2_rot_30.grb":
        StepRepeatOnce(SR_ONCE, 6, 6, 8 * MM, 6 * MM),
    f"{SR_PYGERBER}/rot_30/00_cr_x_6.grb": StepRepeatOnce(SR_ONCE, 6, 1, 8 * MM, 0),
    f"{SR_PYGERBER}/rot_30/01_cr_y_3.grb": StepRepeatOnce(SR_ONCE, 1, 3, 0, 6 * MM),
    f"{SR_PYGERBER}/rot_30/02_cr_xy_3_6.grb": StepRepeatOnce(SR_ONCE, 3, 6, 8 * MM, 6 * MM),
    f"{SR_PYGERBER}/rot_30/02_cr_xy_6_6.grb": StepRepeatOnce(SR_ONCE, 6, 6, 8 * MM, 6 * MM),
    "synthetic-gerbv/test-inputs/test-layer-step-and_repeat-2.gbx":
        StepRepeatOnce(SR_ONCE, 3, 2, INCH, INCH),
    "synthetic-tracespace/step-repeats/one-polarity.gbr":
        StepRepeatOnce(SR_ONCE, 3, 2, INCH, INCH),
    "synthetic-tracespace/step-repeats/multi-polarity.gbr":
        StepRepeatOnce(SR_ONCE, 3, 2, INCH, INCH),
    "synthetic-tracespace/step-repeats/multi-polarity-over-existing.gbr":
        StepRepeatOnce(SR_ONCE, 2, 2, 3 * INCH // 4, 3 * INCH // 4, frozenset({11, 12})),

    "derived-incremental/kicad-carte_test-F_Cu.incremental.gbr": IncrementalAsAbsolute(
        "gerbonara 1.5 parses every coordinate as absolute, whatever %FS says"),
    "derived-incremental/pcb-rnd-power-art.trailing-incremental.gtl": IncrementalAsAbsolute(
        "gerbonara 1.5 parses every coordinate as absolute, whatever %FS says"),

    "geda-pcb/cslk/cslk.gbx": Differs(
        "words like 'G75G03I150J0X3550Y1701D01*' (two G codes, I/J before X/Y) match no "
        "gerbonara statement pattern: 'unknown statement' warning, the arc is dropped",
        ("arcs D16: ours 15, peer 0",
         "bbox_nm: ours (1016000, 50800, 97790000, 61595000), "
         "peer (1270000, 50800, 97104200, 61595000)")),
    "synthetic-gerbv/test-inputs/test-layer-axis-select-1.gbx": Differs(
        AXIS_SELECT,
        ("bbox_nm: ours (0, -25400000, 0, 25400000), peer (-25400000, 0, 25400000, 0)",)),
    "synthetic-gerbv/test-inputs/test-layer-mode-1.gbx": Differs(
        "gerbonara keeps the first %MO and ignores later ones (box 3, in mm, is read "
        "as inches: x up to 125 in), and drops Y-before-X words such as "
        "'Y12000X12700D03*' (the three thermal flashes)",
        ("flashes D12: ours 2, peer 0", "flashes D13: ours 1, peer 0",
         "bbox_nm: ours (0, 0, 125000000, 25400000), peer (0, 0, 3175000000, 635000000)")),
    "synthetic-tracespace/arc-strokes/zero-length.gbr": Differs(
        "G74 arc whose end is its start: gerbonara returns no object at all; it is a "
        "zero-length stroke, which still images the aperture once (ours: a zero-length "
        "LINE)",
        ("draws D10: ours 1, peer 0", "bbox_nm: ours (0, 0, 0, 0), peer None")),
}

ALLEGRO_FS_MO = "'%FSLAX..*MOIN*%': two commands in one extended block (Allegro, " \
                "OrCAD); pygerber's grammar takes one"
PYGERBER_STOP = r"ParseException: Expected .*End of file"
PYGERBER: dict[str, object] = {
    **_fails(ALLEGRO_FS_MO, PYGERBER_STOP + r".*found '%'", *[
        f.path for f in FILES if f.path.startswith(("allegro/tracespace-371/",
                                                    "orcad/led-display-g4-arena/"))
        or (f.path.startswith("allegro/minnowmax-reva1/") and "GAF" not in f.path)]),
    **_fails("deprecated %IC (input code) command, unknown to pygerber's grammar",
             PYGERBER_STOP + r".*found '%'", *[
                 f.path for f in FILES if f.path.startswith((
                     "mentor-xpedition/", "orcad/rs232-cm-orcad-layout/", "p-cad/zxinet/"))]),
    **_fails("aperture numbers with a leading zero (%ADD010...)",
             PYGERBER_STOP + r".*found '%'", *EKF2,
             *[f"pads/osu-mars-rover-2011/{n}.pho" for n in
               ("Bottom", "Layer3", "SMB", "SSB", "SST")]),
    **_fails("Eagle writes X2 attributes inside comments ('G04 #@! %TF.Part,...*'); the "
             "'%' in a G04 comment stops pygerber's grammar", PYGERBER_STOP + r".*'G04'",
             *[f.path for f in FILES if f.path.startswith("eagle/gyw-electro-x2/")]),
    **_fails("deprecated image commands pygerber's grammar lacks (%SF, %MI, %IR, %IO, %IJ, "
             "%RO, %KO, empty %IN)", PYGERBER_STOP + r".*found '%'",
             "allegro/minnowmax-reva1/MinnowMax_lyr1_GAF.art",
             "allegro/minnowmax-reva1/MinnowMax_smc_GAF.art",
             "pcgerber/cd1r2/cd1r2.1_sieb0.off", "zuken-visula/jj/l1-2.grb",
             "zuken-visula/jj/l1-3.grb", "fusion360/pmw3360-breakout/profile.gbr",
             "synthetic-gerbv/test-inputs/test-layer-scale-factor-1.gbx",
             "synthetic-gerbv/test-inputs/test-layer-mirror-image-1.gbx",
             "synthetic-gerbv/test-inputs/test-image-rotation-1.gbx",
             "synthetic-gerbv/test-inputs/test-image-offset-1.gbx",
             "synthetic-gerbv/test-inputs/test-image-justify-2.gbx",
             "synthetic-gerbv/test-inputs/test-layer-rotation-1.gbx",
             "synthetic-gerbv/test-inputs/test-layer-knockout-1.gbx"),
    **_fails("%FS without L or T (zero omission unspecified)", PYGERBER_STOP + r".*found '%'",
             "altium/pygerber-issue-340/altium_example.grb"),
    **_fails("macro primitives 2 (vector line), 6 (moire) or 22, or an outline-only "
             "comment line, unknown to pygerber's grammar", PYGERBER_STOP + r".*found '%'",
             "synthetic-gerbv/am-test/am-test.gbx", "synthetic-gerbv/exposure/example.grb",
             "synthetic-pygerber/macro/codes/code_6.grb",
             "synthetic-tracespace/macro-primitives/vector-primitive.gbr",
             "synthetic-tracespace/macro-primitives/rotated-vector-primitive.gbr",
             "synthetic-tracespace/macro-primitives/moire-primitive.gbr",
             "synthetic-tracespace/macro-primitives/rotated-moire-primitive.gbr",
             "synthetic-tracespace/macros/clear-with-moire.gbr",
             "synthetic-tracespace/macro-primitives/lower-left-rect-primitive.gbr"),
    **_fails("macro names with '-' and '.' (Upverter: %AMRect-W1650000-H1650000-RO1.500*)",
             PYGERBER_STOP + r".*found '%'",
             *[f"upverter/sportiduino/design_export.{ext}" for ext in
               ("gbl", "gbp", "gbs", "gtl", "gts")]),
    **_fails("rectangular hole (two hole sizes) in a C/R/O/P aperture",
             PYGERBER_STOP + r".*found '%'",
             "synthetic-gerbv/test-inputs/test-aperture-circle-flash-1.gbx",
             "synthetic-gerbv/test-inputs/test-aperture-rectangle-flash-1.gbx",
             "synthetic-gerbv/test-inputs/test-aperture-obround-flash-1.gbx",
             "synthetic-tracespace/pads/polygon-with-rect-hole.gbr",
             "synthetic-tracespace/pads/rectangle-with-rect-hole.gbr"),
    **_fails("deprecated G55 (prepare flash) before D03 (Zuken 'G55D03*')",
             PYGERBER_STOP + r".*'G55D03'",
             *[f"zuken-emulated/8seg-driver/{n}.fph" for n in
               ("Conductive-1", "MetalMask-A", "MetalMask-B")]),
    **_fails("words like 'G75G03I150J0X3550Y1701D01*' (two G codes, I/J before X/Y)",
             PYGERBER_STOP + r".*'G75G03", "geda-pcb/cslk/cslk.gbx"),
    **_fails("Y before X in a coordinate word ('Y12000X12700D03*')",
             PYGERBER_STOP + r".*'Y12000X12700D03'",
             "synthetic-gerbv/test-inputs/test-layer-mode-1.gbx"),
    **_fails("no M02 (the grammar requires M02 or M00 at the end)",
             PYGERBER_STOP + r".*found end of text",
             "synthetic-pygerber/expressions/AM/sample-0.gbr",
             "synthetic-pygerber/expressions/AM/sample-1.gbr",
             "synthetic-pygerber/expressions/AM/sample-2.gbr",
             "synthetic-gerbv/test-inputs/include-file-1.gbx"),
    **_fails("no %MO in the file", r"UnitNotSet2Error",
             "synthetic-gerbv/amacro-ref/full-ex.grb", "synthetic-gerbv/amacro-ref/limit-ex.grb",
             "ucamco-spec/spec-4.10.4.7/source.grb"),
    **_fails("incremental notation unsupported", r"IncrementalCoordinatesNotSupported",
             "derived-incremental/kicad-carte_test-F_Cu.incremental.gbr",
             "derived-incremental/pcb-rnd-power-art.trailing-incremental.gtl"),
    **_fails("G74 arc whose end is its start: pygerber finds no valid centre",
             r"NoValidArcCenterFoundError", "synthetic-tracespace/arc-strokes/zero-length.gbr"),

    "synthetic-gerbv/test-inputs/test-layer-axis-select-1.gbx": Differs(
        AXIS_SELECT,
        ("bbox_nm: ours (0, -25400000, 0, 25400000), peer (-25400000, 0, 25400000, 0)",)),
    "synthetic-gerbv/test-inputs/test-layer-step-and_repeat-2.gbx": Differs(UNCLOSED_SR, (
        "region_bbox_nm: ours (10160000, 0, 66040000, 30480000), peer None",
        "region_count: ours 6, peer 0", "region_segments: ours 24, peer 0")),
    "synthetic-tracespace/step-repeats/one-polarity.gbr": Differs(UNCLOSED_SR, (
        "flashes D10: ours 6, peer 0", "bbox_nm: ours (0, 0, 50800000, 25400000), peer None")),
    "synthetic-tracespace/step-repeats/multi-polarity.gbr": Differs(UNCLOSED_SR, (
        "flashes D10: ours 6, peer 0", "flashes D11: ours 6, peer 0",
        "flashes D12: ours 6, peer 0", "bbox_nm: ours (0, 0, 50800000, 25400000), peer None")),
    "synthetic-tracespace/step-repeats/multi-polarity-over-existing.gbr": Differs(
        UNCLOSED_SR, (
            "flashes D10: ours 4, peer 0", "flashes D13: ours 4, peer 0",
            "bbox_nm: ours (-9525000, -9525000, 9525000, 9525000), peer (0, 0, 0, 0)")),
}

EXPECTED = {"gerbonara": GERBONARA, "pygerber": PYGERBER}


# --------------------------------------------------------------------------- readers, cached


def describe(e: BaseException) -> str:
    """'Type: message', then ' <- Cause: message' for each chained cause."""
    parts = []
    while e is not None:
        parts.append(f"{type(e).__name__}: {' '.join(str(e).split())}")
        e = e.__cause__
    return " <- ".join(parts)


@functools.cache
def _ours(rel: str):
    from galileo_cnc.readers.gerber import read_gerber
    from galileo_cnc.readers.gerber.transformed import with_source_apertures

    # Peers count per D code of the file; ours puts a flash under %LR on the aperture's
    # image (a key of its own), so count those under the file's D code too.
    return ours_summary(with_source_apertures(read_gerber(corpus_dir() / rel)))


@functools.cache
def _peer(name: str, rel: str):
    """(summary, None) or (None, 'Type: message <- Cause...')."""
    logging.disable(logging.WARNING)  # pygerber logs style advice for every file
    try:
        return PEERS[name](corpus_dir() / rel), None
    except Exception as e:  # a peer's failure is data, checked against the tables
        return None, describe(e)
    finally:
        logging.disable(logging.NOTSET)


# pygerber reads about 30 kB/s: the suite compares it on files up to this size
# (329 of the 493, about 30 s); gerbonara and the bench cover every file.
# GALILEO_PYGERBER_MAX_BYTES=0 compares pygerber on all of them (some 10 minutes).
PYGERBER_MAX_BYTES = int(os.environ.get("GALILEO_PYGERBER_MAX_BYTES", "20000")) or None


def _compared(name: str, rel: str) -> bool:
    return name != "pygerber" or PYGERBER_MAX_BYTES is None \
        or (corpus_dir() / rel).stat().st_size <= PYGERBER_MAX_BYTES


# --------------------------------------------------------------------------- tests


@pytest.mark.parametrize("name, rel", [(name, rel) for name in sorted(PEERS) for rel in PATHS
                                       if _compared(name, rel)])
def test_peer_agrees(name: str, rel: str):
    expect = EXPECTED[name].get(rel)
    peer, error = _peer(name, rel)
    if isinstance(expect, Fails):
        assert error is not None, f"{name} now reads {rel}; review its entry: {expect.reason}"
        assert re.search(expect.error, error), \
            f"{name} fails on {rel} differently than listed ({expect.reason}): {error}"
        return
    assert error is None, f"{name} cannot read {rel} and no entry says why: {error}"
    ours = _ours(rel)
    if expect is None:
        problems = differences(ours, peer)
    else:
        problems = expect.check(ours, peer, rel, name)
    assert not problems, f"{rel} vs {name}" + (f" ({expect.reason})" if expect else "") \
        + ":\n  " + "\n  ".join(problems)


def test_expectations_name_corpus_files():
    """Every entry names a readable corpus file: no stale entries after a corpus change."""
    if GERBER_CURATED:
        pytest.skip(f"the tables name files of the full corpus ({FULL / 'gerber'}); the "
                    f"curated one in tests/corpus holds a selection")
    known = set(PATHS)
    stale = [f"{name}: {rel}" for name, table in EXPECTED.items() for rel in table
             if rel not in known]
    assert not stale, "entries for files not in the corpus: " + ", ".join(stale)


@pytest.mark.parametrize("arc, box", [
    # (sx, sy, ex, ey, cx, cy, clockwise) -> (xmin, ymin, xmax, ymax)
    ((1000, 0, 0, 1000, 0, 0, False), (0, 0, 1000, 1000)),  # CCW quarter
    ((1000, 0, 0, 1000, 0, 0, True), (-1000, -1000, 1000, 1000)),  # CW three quarters
    ((1000, 0, 1000, 0, 0, 0, True), (-1000, -1000, 1000, 1000)),  # start == end: circle
    ((707, 707, -707, 707, 0, 0, False), (-707, 707, 707, 1000)),  # over the top
    ((-707, -707, 707, -707, 0, 0, False), (-707, -1000, 707, -707)),  # CCW under
    ((-707, -707, 707, -707, 0, 0, True), (-1000, -707, 1000, 1000)),  # CW the long way
])
def test_arc_box_reaches_axis_extremes(arc, box):
    from peers import _Box

    b = _Box()
    b.arc(*arc)
    assert b.result() == box
