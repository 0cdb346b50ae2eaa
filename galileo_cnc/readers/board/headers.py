"""A layer's role from the comments its tool wrote at the top of the file.

Tools without X2 still say what a file is, in words of their own:

- Allegro / OrCAD PCB Editor: a FILE IDENTIFICATION RECORD listing the film's
  `G04 Layer:  CLASS/SUBCLASS*` (ETCH/TOP, PIN/SOLDERMASK_BOTTOM, REF DES/SILKSCREEN_TOP ...).
- Mentor Expedition: `G04 Layer : SoldermaskBottom.gdo*`, EasyEDA: `G04 Layer: TopLayer*`:
  the layer's name, read by the name rules (names.py).
- gEDA pcb: `G04 contains layers component (3) ...` (the component side is the top, the
  solder side the bottom).
- Drill files: `;TYPE=PLATED` (Altium, EasyEDA, P-CAD), Mentor's `; Contents: Thru /
  Drill / Plated`, Allegro's tool lines `;T01 Holesize ... PLATED`.
"""

from __future__ import annotations

import re

from galileo_cnc.readers.board.names import Placement, gerber_name_role

_ALLEGRO_LAYER = re.compile(r"^G04 Layer:\s+([^/*\n]+)/([^*\n]+)\*", re.M)
_NAMED_LAYER = re.compile(r"^G04 Layer ?: *([^/*\n]+?) *\*", re.M)
_GEDA_LAYERS = re.compile(r"^G04 contains layers ([^*\n]*)\*", re.M)
_IGNORED_CLASSES = ("KEEPOUT", "KEEPIN", "CONSTRAINT REGION", "DRC ERROR", "TOLERANCE")
_FILMS = (("SOLDERMASK", "mask"), ("PASTEMASK", "paste"), ("SILKSCREEN", "silk"))
_OUTLINES = {"OUTLINE", "DESIGN_OUTLINE"}


def header_role(head: str) -> Placement | None:
    """The role the tool's own header comments give a Gerber layer, or None."""
    record = [(c.strip().upper(), s.strip().upper()) for c, s in _ALLEGRO_LAYER.findall(head)]
    if record:
        return _allegro_role(record)
    named = _NAMED_LAYER.search(head)
    if named:
        placed = gerber_name_role(named.group(1))
        if placed:
            return Placement(placed.role, f"header names the layer '{named.group(1)}' "
                             f"({placed.why.removeprefix('name: ')})", placed.layer)
    geda = _GEDA_LAYERS.search(head)
    if geda:
        names = set(re.findall(r"([A-Za-z][\w-]*) \(\d+\)", geda.group(1)))
        if "component" in names and "solder" not in names:
            return Placement("top-copper", "header: gEDA layer group holding the component side")
        if "solder" in names and "component" not in names:
            return Placement("bottom-copper", "header: gEDA layer group holding the solder side")
    return None


def _allegro_role(record: list[tuple[str, str]]) -> Placement | None:
    layers = [(c, s) for c, s in record if not any(i in c for i in _IGNORED_CLASSES)]
    etch = {s for c, s in layers if c == "ETCH"}
    if len(etch) == 1:
        (sub,) = etch
        role = {"TOP": "top-copper", "BOTTOM": "bottom-copper"}.get(sub, "inner-copper")
        return Placement(role, f"header: Allegro film of ETCH/{sub}")
    if etch:
        return None
    subclasses = {s for _, s in layers}
    for film, kind in _FILMS:
        sides = {side for side in ("TOP", "BOTTOM") if f"{film}_{side}" in subclasses}
        if len(sides) == 1:
            (side,) = sides
            return Placement(f"{side.lower()}-{kind}", f"header: Allegro film of {film}_{side}")
        if sides:
            return None
    if layers and all(c == "BOARD GEOMETRY" and s in _OUTLINES for c, s in layers):
        return Placement("outline", "header: Allegro film of BOARD GEOMETRY/OUTLINE")
    if layers:
        shown = ", ".join(f"{c}/{s}" for c, s in layers[:2])
        return Placement("other", f"header: Allegro film of drawing layers ({shown} ...)")
    return None


_TYPE = re.compile(r"^;\s*TYPE=(PLATED|NON_PLATED)\s*$", re.M | re.I)
_MENTOR_CONTENTS = re.compile(r"^;\s*Contents\s*:[^\n]*?(Non-Plated|Plated)\s*$", re.M | re.I)
_ALLEGRO_TOOL = re.compile(r"^;T\d+ Holesize .*?\b(NON_PLATED|PLATED)\b", re.M)


def drill_header_role(head: str) -> Placement | None:
    """Plated or not, from a drill file's own comments, or None when they do not say."""
    contents = _MENTOR_CONTENTS.search(head)
    if contents:
        plated = contents.group(1).lower() == "plated"
        return Placement("drill-plated" if plated else "drill-unplated",
                         f"header: Mentor contents '{contents.group(1)}'")
    tools = set(t.upper() for t in _ALLEGRO_TOOL.findall(head))
    if tools == {"PLATED"}:
        return Placement("drill-plated", "header: every tool is PLATED (Allegro)")
    if tools == {"NON_PLATED"}:
        return Placement("drill-unplated", "header: every tool is NON_PLATED (Allegro)")
    if tools:
        return Placement("drill", "header: PLATED and NON_PLATED tools (Allegro)")
    types = set(t.upper() for t in _TYPE.findall(head))
    if types == {"PLATED"}:
        return Placement("drill-plated", "header: ;TYPE=PLATED")
    if types == {"NON_PLATED"}:
        return Placement("drill-unplated", "header: ;TYPE=NON_PLATED")
    return None   # both TYPE lines: Altium writes both into every file
