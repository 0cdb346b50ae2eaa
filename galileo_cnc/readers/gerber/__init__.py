"""Gerber RS-274X (and X2/X3) reader."""

from __future__ import annotations

import re

from galileo_cnc.readers.gerber.reader import GerberReader, read_gerber

__all__ = ["GerberReader", "read_gerber", "looks_like_gerber"]

# Statements that only Gerber files start with (after G04 comments and blanks).
_GERBER_START = re.compile(r"\s*(?:%(?:FS|MO|TF|TA|AM|AD|IN|IP|LN|OF|SF|AS|MI|IR|G04)|G04[^*]*\*|G7[01]\*|G75\*|G01\*)")


def looks_like_gerber(text: str) -> bool:
    """True if the start of `text` looks like RS-274X (checks the first few KB only)."""
    head = text[:8192]
    return bool(_GERBER_START.match(head)) or ("%FS" in head and "*%" in head)
