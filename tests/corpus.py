"""Where the tests read the Gerber and DXF corpora, and their manifests (read in place).

Each corpus is, first found: the folder its variable names ($GALILEO_CORPUS for Gerber,
$GALILEO_DXF_CORPUS for DXF), the full corpus beside the checkout (../shared/corpus/gerber,
../shared/corpus/dxf), or the curated selection in the repository (tests/corpus/gerber,
tests/corpus/dxf), so a clone runs the suite alone. A test that needs a file the corpus
in use lacks skips through `corpus_file`, naming the file and where the full corpus lives.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FULL = REPO.parent / "shared" / "corpus"  # the full corpus (bench/ reads it too)
CURATED = REPO / "tests" / "corpus"


def _found(variable: str, kind: str) -> Path:
    if os.environ.get(variable):
        return Path(os.environ[variable])
    if (FULL / kind / "MANIFEST.tsv").is_file():
        return FULL / kind
    return CURATED / kind


CORPUS = GERBER_CORPUS = _found("GALILEO_CORPUS", "gerber")
DXF_CORPUS = _found("GALILEO_DXF_CORPUS", "dxf")
#: the curated selection is in use: tests that count files expect its numbers
GERBER_CURATED = CORPUS == CURATED / "gerber"
DXF_CURATED = DXF_CORPUS == CURATED / "dxf"


def manifest(corpus: Path = CORPUS) -> list[dict]:
    path = corpus / "MANIFEST.tsv"
    if not path.is_file():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle, delimiter="\t"))


def corpus_paths(*kinds: str) -> list[str]:
    """Gerber corpus paths (relative) of the given manifest kinds, e.g. 'real', 'invalid'."""
    return [row["path"] for row in manifest() if row["kind"] in kinds]


def corpus_file(relative: str, corpus: Path = CORPUS) -> Path:
    """The corpus file, or a skip naming it when the corpus in use does not hold it."""
    path = corpus / relative
    if not path.is_file():
        import pytest  # here: bench/ imports this module without pytest

        kind, variable = ("dxf", "GALILEO_DXF_CORPUS") if corpus == DXF_CORPUS \
            else ("gerber", "GALILEO_CORPUS")
        pytest.skip(f"optional corpus file {relative} is not in {corpus}; the full corpus "
                    f"lives in {FULL / kind} (or set ${variable})")
    return path
