"""Is this Gerber file a copper layer? X2 attributes first, then the header, then the name.

Only the X2 file attribute (`%TF.FileFunction,Copper,...`) says it for sure. Older
files say it through naming conventions (Protel/Altium .GTL/.GBL/.G1.., EAGLE
.cmp/.sol, KiCad F_Cu/B.Cu, gEDA .top/.bottom/.groupN, Allegro lyrN / lN_...,
Mentor _Lnn ...) and sometimes through a header comment ("top silk layer").
The answer is a best guess for choosing files (the corpus sweeps, a planner
warning), never a reason to refuse a file.
"""

from __future__ import annotations

import re
from pathlib import PurePath

_X2_FUNCTION = re.compile(r"TF\.FileFunction,([A-Za-z]+)")
# Words that mark another layer, in a file name or a header comment.
_OTHER_LAYER = re.compile(
    r"silk|legend|mask|paste|stencil|assy|assembl|fab|drill|outline|profile|edge|mill|"
    r"keepout|sieb|overlay|symbol|resist|courtyard|comment|drawing|posi|mechanical|"
    r"board_?outline", re.IGNORECASE)
# Extensions of other layers (Protel/EAGLE/OrCAD/PADS conventions).
_HEADER_OTHER_LAYER = re.compile(r"silk|legend|overlay|paste|solder ?mask|stop ?mask", re.IGNORECASE)
_OTHER_EXTENSIONS = {"gto", "gbo", "gtp", "gbp", "gts", "gbs", "gko", "gml", "gm1", "gd1", "gg1",
                     "gpt", "gpb", "plc", "pls", "stc", "sts", "crc", "crs", "smc", "sms",
                     "mil", "xln", "drl", "drd", "asb", "ast", "ssb", "sst", "smb", "smt",
                     "spb", "spt", "txt", "dri", "gpi"}
_COPPER_EXTENSIONS = {"gtl", "gbl", "cmp", "sol", "top", "bot"}
_COPPER_NAME = re.compile(
    r"copper|conductive|toplayer|bottomlayer|"
    r"(?:^|[^a-z0-9])(?:f|b|in\d+)[._]cu(?:$|[^a-z])|"      # KiCad F_Cu, B.Cu, In1_Cu
    r"(?:^|[._-])(?:top|bottom|back|front|group\d+|output_group\d+)$|"  # gEDA, DipTrace
    r"(?:^|[^a-z])lyr\d+|(?:^|[^a-z])layer_?\d+|(?:^|[_-])l\d+(?:$|[_-])|^l\d+(?:-\d+)?$|"
    r"^(?:gnd|pwr|vcc|pow)\d*$|^[tb]l$|^top$", re.IGNORECASE)


def looks_like_copper(name: str, text: str = "") -> bool:
    """Best guess whether a Gerber file (its name, and the start of its text) is copper."""
    head = text[:4000]
    x2 = _X2_FUNCTION.search(head)
    if x2:
        return x2.group(1).lower() == "copper"
    path = PurePath(name)
    suffix = path.suffix[1:].lower()
    stem = path.stem if suffix and not suffix.isdigit() else path.name
    if suffix in _OTHER_EXTENSIONS or re.fullmatch(r"gp\d+|gm\d+", suffix):
        return False  # Altium internal planes (.GPn) are drawn negative: not copper as dark
    if _OTHER_LAYER.search(path.name):
        return False
    # Header comments that name the layer ("G04 top silk layer"); Allegro's film
    # record lists every layer it merged ("G04 Layer: PIN/SOLDERMASK_TOP"): skipped.
    comments = " ".join(c for c in re.findall(r"G0?4([^*]*)\*", head)[:30]
                        if not c.strip().lower().startswith("layer:"))
    if _HEADER_OTHER_LAYER.search(comments):
        return False
    if suffix in _COPPER_EXTENSIONS or re.fullmatch(r"g\d+", suffix):
        return True
    return bool(_COPPER_NAME.search(stem))
