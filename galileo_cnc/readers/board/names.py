"""A layer's role from the name an EDA tool gave its file (or wrote into its header).

Three kinds of names, tried in this order:

1. KiCad's layer names inside the name: `-F_Cu`, `-B.SilkS`, `-In2_Cu`, `-Edge_Cuts`.
2. Short codes, as the extension (Protel/Altium `.GTL .GBL .GTO .GBO .GTS .GBS .GTP .GBP
   .GKO .GM1 .G1..`, Eagle `.cmp .sol .plc .pls .stc .sts .crc .crs .dim .gml`, OrCAD
   `.top .bot .smt .ssb`) or as the whole stem (PADS `SST.pho`, EKF `stp0.grb`).
3. Words: a side (top, bottom, front, back, primary, secondary, component ...) with a
   kind (silk, mask, paste, outline ...), as DipTrace (`_TopSilk`), Mentor
   (`SoldermaskBottom`), EasyEDA (`TopSolderMaskLayer`), gEDA (`.topsilk.gbr`),
   Target 3001! (`.PasteBot`), Zuken (`Resist-B`) and Allegro (`silk_prm`) write them.
   A side alone is that side's copper (`mainboard_Top.gbr`, `Bottom.pho`); a numbered
   layer (`L02`, `lyr1`, `Layer3`, `Conductive-1`) is copper whose side the board
   settles (board.py): layer 1 is the top.

Drill files (known by their content) have their own words: PTH/NPTH, plated/unplated.
Each answer is a Placement with the rule's words as its "why".
"""

from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Placement:
    """A file's role and why; `layer` is the copper layer number a name gave (0: none)."""

    role: str
    why: str
    layer: int = 0


# 1. KiCad: <project>-<layer>.<ext>, the layer's dot written as '_' since KiCad 5.
_KICAD = [
    (re.compile(r"(?:^|[-_.])f[._]cu(?:$|[-_.])"), "top-copper", "F.Cu"),
    (re.compile(r"(?:^|[-_.])b[._]cu(?:$|[-_.])"), "bottom-copper", "B.Cu"),
    (re.compile(r"(?:^|[-_.])in\d+[._]cu(?:$|[-_.])"), "inner-copper", "In<n>.Cu"),
    (re.compile(r"(?:^|[-_.])f[._]silk(?:s|screen)?(?:$|[-_.])"), "top-silk", "F.SilkS"),
    (re.compile(r"(?:^|[-_.])b[._]silk(?:s|screen)?(?:$|[-_.])"), "bottom-silk", "B.SilkS"),
    (re.compile(r"(?:^|[-_.])f[._]mask(?:$|[-_.])"), "top-mask", "F.Mask"),
    (re.compile(r"(?:^|[-_.])b[._]mask(?:$|[-_.])"), "bottom-mask", "B.Mask"),
    (re.compile(r"(?:^|[-_.])f[._]paste(?:$|[-_.])"), "top-paste", "F.Paste"),
    (re.compile(r"(?:^|[-_.])b[._]paste(?:$|[-_.])"), "bottom-paste", "B.Paste"),
    (re.compile(r"(?:^|[-_.])edge[._]cuts(?:$|[-_.])"), "outline", "Edge.Cuts"),
]

# 2. Short codes: (code, role, tool and meaning).
_CODES = {
    # Protel / Altium (and everyone who copied them)
    "gtl": ("top-copper", "Protel/Altium top layer"),
    "gbl": ("bottom-copper", "Protel/Altium bottom layer"),
    "gto": ("top-silk", "Protel/Altium top overlay"),
    "gbo": ("bottom-silk", "Protel/Altium bottom overlay"),
    "gts": ("top-mask", "Protel/Altium top solder mask"),
    "gbs": ("bottom-mask", "Protel/Altium bottom solder mask"),
    "gtp": ("top-paste", "Protel/Altium top paste"),
    "gbp": ("bottom-paste", "Protel/Altium bottom paste"),
    "gko": ("outline", "Protel/Altium keep-out layer, the board outline"),
    "gm1": ("outline", "Protel/Altium mechanical layer 1, the board outline"),
    "gm": ("outline", "mechanical layer, the board outline"),
    "gml": ("outline", "Eagle milling layer"),
    "mil": ("outline", "Eagle milling layer"),
    "gpt": ("other", "Protel/Altium top pad master"),
    # two-letter names (FAB 3000, CAM tools writing Protel's letters as the whole name)
    "tl": ("top-copper", "top layer"),
    "bl": ("bottom-copper", "bottom layer"),
    "to": ("top-silk", "top overlay"),
    "bo": ("bottom-silk", "bottom overlay"),
    "ts": ("top-mask", "top solder mask"),
    "bs": ("bottom-mask", "bottom solder mask"),
    "tp": ("top-paste", "top paste"),
    "bp": ("bottom-paste", "bottom paste"),
    "gpb": ("other", "Protel/Altium bottom pad master"),
    # Eagle's classic CAM job
    "cmp": ("top-copper", "Eagle component side"),
    "sol": ("bottom-copper", "Eagle solder side"),
    "plc": ("top-silk", "Eagle silkscreen component side"),
    "pls": ("bottom-silk", "Eagle silkscreen solder side"),
    "stc": ("top-mask", "Eagle stop mask component side"),
    "sts": ("bottom-mask", "Eagle stop mask solder side"),
    "crc": ("top-paste", "Eagle cream component side"),
    "crs": ("bottom-paste", "Eagle cream solder side"),
    "dim": ("outline", "Eagle dimension layer"),
    # OrCAD Layout, PADS, pcb-rnd
    "top": ("top-copper", "top layer: OrCAD Layout, Target 3001!"),
    "bot": ("bottom-copper", "bottom layer: OrCAD Layout, Target 3001!"),
    "smt": ("top-mask", "solder mask top"),
    "smb": ("bottom-mask", "solder mask bottom"),
    "sst": ("top-silk", "silkscreen top"),
    "ssb": ("bottom-silk", "silkscreen bottom"),
    "spt": ("top-paste", "solder paste top"),
    "spb": ("bottom-paste", "solder paste bottom"),
    "ast": ("other", "assembly drawing top"),
    "asb": ("other", "assembly drawing bottom"),
    "fab": ("other", "fabrication drawing"),
    # Allegro's usual film names
    "smc": ("top-mask", "Allegro solder mask component side"),
    "sms": ("bottom-mask", "Allegro solder mask solder side"),
    "spc": ("top-paste", "Allegro solder paste component side"),
    "sps": ("bottom-paste", "Allegro solder paste solder side"),
    # EKF's CAM (German): Stopplack, Siebdruck (the paste stencil), Druck (legend);
    # side 0 is the solder side, 1 the component side (its Mentor headers say so:
    # stp0 is SoldermaskBottom)
    "stp0": ("bottom-mask", "EKF Stopplack side 0 (solder side)"),
    "stp1": ("top-mask", "EKF Stopplack side 1 (component side)"),
    "sieb0": ("bottom-paste", "EKF Sieb (paste stencil) side 0 (solder side)"),
    "sieb1": ("top-paste", "EKF Sieb (paste stencil) side 1 (component side)"),
    "d0": ("bottom-silk", "EKF Druck (legend) side 0 (solder side)"),
    "d1": ("top-silk", "EKF Druck (legend) side 1 (component side)"),
    "l0": ("bottom-copper", "EKF layer 0 (solder side)"),
}
_PATTERN_CODES = [
    (re.compile(r"g(\d+)"), "inner-copper", "Protel/Altium mid layer {0}"),
    (re.compile(r"gp(\d+)"), "inner-copper", "Protel/Altium internal plane {0}"),
    (re.compile(r"ly(\d+)"), "inner-copper", "Eagle inner layer {0}"),
    (re.compile(r"pow\d*"), "inner-copper", "power plane"),
    (re.compile(r"group(\d+)"), "inner-copper",
     "gEDA pcb copper group {0}, neither top nor bottom"),
    (re.compile(r"gm(\d+)"), "other", "Protel/Altium mechanical layer {0}"),
    (re.compile(r"g[dg](\d+)"), "other", "Protel/Altium drill drawing {0}"),
]

# Codes that name a layer only as the extension (`board.top` but not `board.top.gbr`,
# which the words read) or as one word of the stem (Allegro `MinnowMax_smc_GAF.art`).
_EXTENSION_ONLY = {"top", "bot"}
_WORD_CODES = {"smc", "sms", "spc", "sps", "sst", "ssb", "smt", "smb", "spt", "spb"}

# Extensions that say only "Gerber": the stem's words decide.
GENERIC_EXTENSIONS = {"gbr", "grb", "ger", "gbx", "pho", "art", "gdo", "fph", "phd", "gb",
                      "gerber", "txt", "nc"}
# Drill file extensions: a Gerber file named so is a drawing of the holes.
DRILL_EXTENSIONS = {"drl", "drd", "xln", "exc", "cnc", "ncd", "tap", "fdr", "rou", "drill",
                    "tx1", "tx2", "tx3", "ncdrill"}

# 3. Words.
_TOP = {"top", "front", "component", "comp", "primary", "prm", "toplayer"}
_BOTTOM = {"bottom", "bot", "back", "secondary", "sec", "bottomlayer"}
_PASTE = {"paste", "cream", "stencil", "metal", "metalmask", "pastemask", "sieb"}
_MASK = {"mask", "soldermask", "stop", "stopmask", "resist", "solderresist"}
_SILK = {"silk", "silks", "silkscreen", "legend", "overlay", "posi", "symbol", "screen"}
_OUTLINE = {"outline", "boardoutline", "edge", "edges", "cuts", "profile", "dimension",
            "mill", "milling", "contour", "border"}
_OTHER = {"assembly", "assy", "asm", "fab", "fabrication", "drawing", "drawings", "drill",
          "drills", "dwg", "notes", "courtyard", "adhesive", "glue", "map", "keepout",
          "document", "pads"}   # pads: Altium's pad master, not the copper
_PLANE = {"gnd", "ground", "pwr", "power", "vcc", "plane"}
_NUMBERED = re.compile(r"(?<![a-z0-9])(?:l|lyr|layer|conductive|etch|signal|sig)"
                       r"[-_ ]?0*(\d{1,2})(?![0-9])")
_GLUED = re.compile(r"(top|bottom|front|back|component|solder)"
                    r"(silk|mask|paste|copper|side|layer)")
_TOKEN = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+")
_SIDE_LETTER = re.compile(r"[-_]([ab])$")   # Zuken: Symbol-A, Resist-B


def split_name(name: str) -> tuple[str, str]:
    """(stem, extension) lowercase; an extension is 1-10 letters/digits after the last dot."""
    base = name.replace("\\", "/").rsplit("/", 1)[-1]
    stem, dot, ext = base.rpartition(".")
    if not dot or not stem or not re.fullmatch(r"[A-Za-z0-9]{1,10}", ext):
        return base.lower(), ""
    return stem.lower(), ext.lower()


def words(text: str) -> list[str]:
    """The words of a name: split at punctuation and at camelCase, lowercase, and a
    side glued to a kind split off (gEDA's `topsilk`, `componentmask`)."""
    result = []
    for token in _TOKEN.findall(text):
        token = token.lower()
        glued = _GLUED.fullmatch(token)
        result.extend(glued.groups() if glued else (token,))
    return result


def _code(code: str) -> tuple[str, str] | None:
    if code in _CODES:
        return _CODES[code]
    for pattern, role, meaning in _PATTERN_CODES:
        found = pattern.fullmatch(code)
        if found:
            return role, meaning.format(*found.groups())
    return None


def gerber_name_role(name: str) -> Placement | None:
    """The role a Gerber layer's file name gives, or None."""
    stem, ext = split_name(name)
    lowered = name.lower()
    for pattern, role, layer in _KICAD:
        if pattern.search(lowered):
            return Placement(role, f"name: KiCad layer {layer}")
    if ext in DRILL_EXTENSIONS or (not ext and stem in DRILL_EXTENSIONS):
        return Placement("other", f"name: a Gerber file named '{ext or stem}', as drill "
                         "files are: a drawing of the holes")
    if ext and ext not in GENERIC_EXTENSIONS:
        coded = _code(ext)
        if coded:
            return Placement(coded[0], f"name: .{ext.upper()} ({coded[1]})")
    last = stem.rsplit(".", 1)[-1]   # gEDA: board.topsilk.gbr, board.group3.gbr
    coded = None if last in _EXTENSION_ONLY else _code(last)
    if coded:
        return Placement(coded[0], f"name: {last} ({coded[1]})")
    for word in words(last):
        if word in _WORD_CODES:
            role, meaning = _CODES[word]
            return Placement(role, f"name: {word} ({meaning})")
    generic = ext in GENERIC_EXTENSIONS or not ext
    text = stem if generic else f"{stem}.{ext}"
    original = name.replace("\\", "/").rsplit("/", 1)[-1]
    return _word_role(text, original[:len(original) - len(ext) - 1] if generic and ext
                      else original)


def _word_role(text: str, original: str) -> Placement | None:
    found = set(words(original))
    side = ""
    if found & _TOP:
        side = "top"
    if found & _BOTTOM:
        side = "" if side else "bottom"   # both: no side
        if not side:
            return None
    letter = _SIDE_LETTER.search(text)
    if not side and letter:
        side = "top" if letter.group(1) == "a" else "bottom"
    shown = " ".join(words(original))

    def said(kind: str) -> str:
        return f"name: the words '{shown}' ({kind})"

    if found & _OTHER:
        return Placement("other", said("a drawing"))
    if found & _OUTLINE:
        return Placement("outline", said("the board outline"))
    for kind, vocabulary in (("paste", _PASTE), ("mask", _MASK), ("silk", _SILK)):
        if found & vocabulary:
            if not side:
                return None
            return Placement(f"{side}-{kind}", said(f"{side} {kind}"))
    numbered = _NUMBERED.search(text)
    if side:
        return Placement(f"{side}-copper", said(f"{side} copper"))
    if numbered:
        number = int(numbered.group(1))
        if number == 1:
            return Placement("top-copper", said("copper layer 1, the top"), layer=1)
        return Placement("inner-copper", said(f"copper layer {number}"), layer=number)
    if found & _PLANE:
        return Placement("inner-copper", said("a power or ground plane"))
    return None


def drill_name_role(name: str) -> Placement | None:
    """Plated or not, from a drill file's name (PTH/NPTH, plated/unplated ...), or None."""
    lowered = name.replace("\\", "/").rsplit("/", 1)[-1].lower()
    found = set(words(name.replace("\\", "/").rsplit("/", 1)[-1]))
    if (found & {"npth", "nplt", "unplated", "nonplated"}
            or re.search(r"non[-_]?plated|unplated|npth|nplt", lowered)):
        return Placement("drill-unplated", f"name: '{lowered}' says not plated")
    if found & {"pth", "plt", "plated"} or re.search(r"plated|(?<!n)pth|(?<!n)plt", lowered):
        return Placement("drill-plated", f"name: '{lowered}' says plated")
    return None
