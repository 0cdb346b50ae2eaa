"""Is this a DXF file? Content sniffing, without ezdxf.

A binary DXF starts with its sentinel `AutoCAD Binary DXF`. An ASCII DXF is pairs
of lines, a group code (an integer) and its value; after any `999` comments the
first pair is `0` / `SECTION` (files without a HEADER start with their ENTITIES
section the same way). Neither Gerber nor G-code can start so.
"""

from __future__ import annotations

SNIFF_LINES = 64  # comments allowed before the first section
SNIFF_CHARS = 1 << 20  # split no more than this into lines (a huge file is not split whole)


def looks_like_dxf(text: str) -> bool:
    """True for text that starts like an ASCII DXF file, or a binary DXF's sentinel."""
    if text.startswith("AutoCAD Binary DXF"):
        return True
    lines = text[:SNIFF_CHARS].removeprefix("\ufeff").splitlines()[:SNIFF_LINES]
    index = 0
    while index + 1 < len(lines):
        code, value = lines[index].strip(), lines[index + 1].strip()
        if code == "999":
            index += 2
            continue
        return code == "0" and value.upper() == "SECTION"
    return False
