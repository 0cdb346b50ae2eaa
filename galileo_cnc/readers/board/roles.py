"""A board file's role, from the first that says: X2, the job file, the tool's header, the name.

Only a file's head is read (HEAD_BYTES): X2 file attributes, the header comments and
the content sniff all sit at the top, so a 2 MB copper layer costs a few KB here.

1. X2: `%TF.FileFunction,Copper,L1,Top*%` (also written as `G04 #@! TF.FileFunction`
   by KiCad 4-5, and as `; #@! TF.FileFunction,Plated,1,2,PTH` in KiCad's drill files).
2. The Gerber job file (.gbrjob): its FilesAttributes give each file's FileFunction.
3. The tool's header comments (headers.py: Allegro, Mentor, EasyEDA, gEDA, drill TYPE).
4. The file's name (names.py: KiCad, Protel/Altium, Eagle, gEDA, DipTrace, Mentor, ...).

What a file is comes first, from its content: a Gerber layer gets a layer role, an
Excellon file a drill role (drill-plated, drill-unplated, or drill when it holds both
or does not say), so a Gerber drill drawing named `.drd` is not taken for the drill file.
"""

from __future__ import annotations

import re

from galileo_cnc.readers.board.headers import drill_header_role, header_role
from galileo_cnc.readers.board.names import Placement, drill_name_role, gerber_name_role
from galileo_cnc.readers.gcode.sniff import _classify_code_line
from galileo_cnc.readers.gerber import looks_like_gerber

ROLES = ("top-copper", "bottom-copper", "inner-copper", "top-silk", "bottom-silk",
         "top-mask", "bottom-mask", "top-paste", "bottom-paste", "outline",
         "drill-plated", "drill-unplated", "drill", "other")
DRILL_ROLES = ("drill-plated", "drill-unplated", "drill")
HEAD_BYTES = 65_536

_FILE_FUNCTION = re.compile(r"TF\.FileFunction,([^*%\r\n]*)")
_SIDES = {"top": "top", "bot": "bottom"}
_OTHER_FUNCTIONS = {"drillmap", "assemblydrawing", "fabricationdrawing", "arraydrawing",
                    "otherdrawing", "component", "keep-out", "pads", "glue", "carbonmask",
                    "goldmask", "heatsinkmask", "peelablemask", "silvermask", "tinmask",
                    "depthrout", "vcut", "viafill", "other", "plated-drill-map"}


def file_kind(head: str) -> str | None:
    """'gerber', 'excellon' or None (neither), from the start of the file."""
    if looks_like_gerber(head):
        return "gerber"
    lines = 0
    for raw in head.splitlines()[:400]:
        line = raw.strip()
        if not line or line.startswith(";") or line == "%":
            continue
        if line.upper() in ("M48", "M72", "M71") or line.upper().startswith(("METRIC", "INCH")):
            return "excellon"
        if _classify_code_line(line) == "excellon":
            return "excellon"
        lines += 1
        if lines > 40:
            break
    return None


def function_role(value: str) -> str | None:
    """The role of an X2 .FileFunction value ('Copper,L1,Top,Signal'), or None."""
    fields = [f.strip() for f in value.split(",")]
    kind = fields[0].lower()
    side = _SIDES.get(fields[1].lower()) if len(fields) > 1 else None
    if kind == "copper" and len(fields) > 2:
        where = fields[2].lower()
        return {"top": "top-copper", "bot": "bottom-copper", "inr": "inner-copper"}.get(where)
    if kind in ("soldermask", "legend", "paste") and side:
        return f"{side}-{ {'soldermask': 'mask', 'legend': 'silk'}.get(kind, kind)}"
    if kind == "profile":
        return "outline"
    if kind == "plated":
        return "drill-plated"
    if kind == "nonplated":
        return "drill-unplated"
    if kind in _OTHER_FUNCTIONS:
        return "other"
    return None


def x2_role(head: str, kind: str) -> Placement | None:
    found = _FILE_FUNCTION.search(head)
    if not found:
        return None
    role = function_role(found.group(1))
    said = f"X2 FileFunction {found.group(1).strip()}"
    if role in DRILL_ROLES and kind == "gerber":
        return Placement("other", f"{said}, in a Gerber file: the holes drawn, not an "
                         "Excellon drill file")
    if role is None or (role in DRILL_ROLES) != (kind == "excellon"):
        return None
    return Placement(role, said)


def place(name: str, head: str, kind: str, job: dict[str, str] | None = None) -> Placement | None:
    """The role of the file `name` (its path inside the board) whose first bytes are
    `head` and whose content is `kind`; `job` maps file names to a job file's
    FileFunction. None: nothing says."""
    placed = x2_role(head, kind)
    if placed is None and job:
        function = job.get(name) or job.get(name.replace("\\", "/").rsplit("/", 1)[-1])
        role = function_role(function) if function else None
        if role and (role in DRILL_ROLES) == (kind == "excellon"):
            placed = Placement(role, f"job file: FileFunction {function}")
    if kind == "excellon":
        return placed or drill_header_role(head) or drill_name_role(name) or Placement(
            "drill", "content: an Excellon drill file that does not say plated or not")
    if placed is None:
        placed = header_role(head) or gerber_name_role(name)
    if placed is not None and placed.why.startswith("X2"):
        by_name = gerber_name_role(name)
        if by_name and by_name.role != placed.role:
            return Placement(placed.role,
                             f"{placed.why} (over the name, which says {by_name.role})")
    return placed
