"""Where the shared Gerber corpus lives, and its manifest (tests read it in place)."""

from __future__ import annotations

import csv
import os
from pathlib import Path

CORPUS = Path(os.environ.get("GALILEO_CORPUS",
                             Path(__file__).resolve().parents[1].parent / "shared" / "corpus" / "gerber"))


def manifest() -> list[dict]:
    with open(CORPUS / "MANIFEST.tsv", newline="") as handle:
        return list(csv.DictReader(handle, delimiter="\t"))


def corpus_paths(*kinds: str) -> list[str]:
    """Corpus paths (relative) of the given manifest kinds, e.g. 'real', 'invalid'."""
    if not (CORPUS / "MANIFEST.tsv").exists():
        return []
    return [row["path"] for row in manifest() if row["kind"] in kinds]
