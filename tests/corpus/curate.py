"""Rebuild this curated corpus from the full one: `python3 tests/corpus/curate.py [SHARED]`.

SHARED is the full corpus folder (default ../shared/corpus beside the checkout). The
selection below covers what the tests exercise (several EDA and CAD tools, mm and inch,
arcs, macros, regions, step and repeat, load transforms, incremental notation, broken
files; R12 to R2018, binary and headerless DXF, blocks, splines) and every file a test
names; each kept file's MANIFEST.tsv row is copied as it is, with the upstream notes
(UPSTREAM_*) of its folders. The files are copied byte for byte, never edited.
"""

from __future__ import annotations

import csv
import re
import shutil
import sys
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
SHARED = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parents[1].parent / "shared" / "corpus"

# Gerber boards kept whole up to BOARD_FILE_BYTES a file (bigger layers only when named).
GERBER_BOARDS = (
    "allegro/tracespace-371", "allegro/minnowmax-reva1", "altium/pcb1-x2",
    "altium/protel-thermal", "altium/pygerber-issue-198", "altium/pygerber-issue-340",
    "altium/usbvil", "cuprum/tracespace-365", "diptrace/panel", "eagle/pcb-tools-example",
    "eagle/gyw-electro-x2", "eagle/core", "easyeda/tracespace-367", "fab3000/jaseg-fab3000",
    "freepcb/fcpoly-test", "fusion360/pmw3360-breakout", "geda-pcb/cslk", "geda-pcb/dan",
    "geda-pcb/numpres", "geda-pcb/pick-and-place", "kicad/arduino-kicad6", "kicad/carte-test",
    "kicad/flashpads-nox2noap", "kicad/flashpads-x2ap", "kicad/simple-2layer",
    "kicad/world-clock-2", "kicad/pygerber-issue-242", "kicad/atmega328-motor-board",
    "mentor-xpedition/ekf-ccgr0", "mentor-xpedition/nollezappare-veribest",
    "orcad/rs232-cm-orcad-layout", "p-cad/zxinet", "pads/osu-mars-rover-2011",
    "pcb-rnd/epl-isolatedpwr", "upverter/sportiduino", "zuken-visula/jj",
    "zuken-emulated/8seg-driver", "target3001/solarcast-irnasiotbank", "unknown/ekf2",
)
# Kept whole: feature fixtures, the specification's examples, derived and broken files,
# and the drill files.
GERBER_WHOLE = ("synthetic-", "ucamco-spec/", "derived-incremental/", "invalid/", "drill/")
BOARD_FILE_BYTES = 100_000
# Named by a test (tests/plan/test_paths.py, test_repeats.py, readers/test_peers.py):
# kept although bigger.
GERBER_NAMED = {"kicad/atmega328-motor-board/ATMEGA328_Motor_Board-F.Cu.gtl",
                "mentor-xpedition/ekf-ccgr0/stp0.grb",
                "allegro/minnowmax-reva1/MinnowMax_smc_GAF.art"}

# DXF files up to DXF_FILE_BYTES, and the named bigger ones (tests/readers/test_dxf.py).
DXF_FILE_BYTES = 200_000
DXF_NAMED = {"netdxf/netdxf-sample.dxf", "binary/netdxf-sample-binary.dxf"}


def _rows(corpus: Path) -> tuple[list[str], list[dict]]:
    with open(corpus / "MANIFEST.tsv", newline="") as handle:
        reader = csv.DictReader(handle, delimiter="\t")
        return list(reader.fieldnames), list(reader)


def _keep_gerber(row: dict) -> bool:
    path = row["path"]
    if path in GERBER_NAMED or path.startswith(GERBER_WHOLE):
        return True
    return path.rsplit("/", 1)[0] in GERBER_BOARDS and int(row["bytes"]) <= BOARD_FILE_BYTES


def _keep_dxf(row: dict) -> bool:
    return row["path"] in DXF_NAMED or int(row["bytes"]) <= DXF_FILE_BYTES


def _copy(kind: str, keep) -> None:
    source, target = SHARED / kind, HERE / kind
    fields, rows = _rows(source)
    kept = [row for row in rows if keep(row)]
    # a derived file's original too: tests/readers/test_peers.py compares the two
    originals = set(re.findall(r"\(derived from (\S+)\)", " ".join(r["source"] for r in kept)))
    kept = [row for row in rows if keep(row) or row["path"] in originals]
    if target.exists():
        shutil.rmtree(target)
    sources = " ".join(row["source"] for row in kept)
    notes = {p for p in source.glob("UPSTREAM_LICENSE-*")  # the DXF corpus keeps them on top
             if p.stem.split("-", 1)[1].replace("-", "/", 1) in sources}
    for row in kept:
        folder = (source / row["path"]).parent
        while folder != source:  # upstream notes of the file's folder and the ones above
            notes.update(folder.glob("UPSTREAM_*"))
            folder = folder.parent
    for path in [source / row["path"] for row in kept] + sorted(notes) + [source / "README.md"]:
        out = target / path.relative_to(source)
        if path == source / "README.md":  # the full corpus's own notes, sources and licences
            out = target / "FULL_CORPUS_README.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, out)
    with open(target / "MANIFEST.tsv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields, delimiter="\t", lineterminator="\n")
        writer.writeheader()
        writer.writerows(kept)
    upstreams = Counter(row["source"].split("@")[0] for row in kept)
    print(f"{kind}: {len(kept)} of {len(rows)} files, "
          f"{sum(int(r['bytes']) for r in kept) / 1e6:.1f} MB; from", dict(upstreams))


if __name__ == "__main__":
    _copy("gerber", _keep_gerber)
    _copy("dxf", _keep_dxf)
