"""The mill: the tool in the spindle and how it cuts (a `[mill]` table in the profile).

```toml
[mill]
tool = "vbit"              # the tool in the spindle: "vbit" or "endmill"
tip_mm = 0.1               # V-bit: the flat at its tip
angle_deg = 30             # V-bit: the included angle of its point
diameter_mm = 0.8          # end mill: its diameter
cut_depth_mm = 0.1         # below the copper's top (Z = 0)
safe_height_mm = 2.0       # above it, for every move between cuts
spindle_rpm = 10000
feed_mm_min = 120          # cutting
plunge_feed_mm_min = 60    # Z down into the board
passes = 1                 # isolation passes round every copper island
overlap = 0.25             # each next pass overlaps the one before by this share of the cut
drills = [0.8, 1.0]        # drilling: the bits at hand (mm); a hole takes the largest that fits
breakthrough_mm = 0.2      # drilling: how far a drill goes past the board's bottom
probe = false              # a probe is wired (GRBL's probe pin): Z is re-zeroed with G38.2
probe_plate_mm = 0.0       # the touch plate's thickness on the board's top
board_thickness_mm = 1.6   # cut-out (and drilling) goes through this
cutout_step_down_mm = 0.5  # cut-out, milled holes and slots: the most each depth pass goes down
tabs = 4                   # cut-out: tabs holding the board (0: none)
tab_spacing_mm = 0         # cut-out: a tab every this many mm instead of a count (0: use tabs)
tab_width_mm = 2.0         # cut-out: the board's material each tab leaves, along the edge
tab_height_mm = 0.5        # cut-out: the tab's height above the board's bottom
height_map = false         # probe the board's top on a grid first, Z corrected by it
height_map_spacing_mm = 5.0  # height map: the most its grid's points lie apart
probe_feed_mm_min = 50     # height map: G38.2's feed
probe_clearance_mm = 1.0   # height map: each probe starts this far above Z = 0
probe_depth_mm = 1.0       # height map: and finds the board no deeper than this below it
```

A V-bit at depth d cuts tip + 2 d tan(angle / 2) wide at the copper's top; an end mill
cuts its diameter. Lengths are mm in the file and in every message and integer nm
here (`tip_nm`, `cut_width_nm`, ...); feeds are kept in um/min, the angle in
millidegrees. docs/mill.md.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

from galileo_cnc.config.machine import ConfigError, unknown_key_text

NM_PER_MM = 1_000_000
TOOL_KINDS = ("vbit", "endmill")
#: GRBL's S word is scaled by its $30 (max spindle speed); no hobby spindle turns faster.
MAX_SPINDLE_RPM = 100_000
#: Passes round an island: more than this is a pocket, not isolation.
MAX_PASSES = 20
#: Overlap as a share of the cut width: at 0.9 a pass moves a tenth of the cut.
MAX_OVERLAP = 0.9
#: The sizes a table may give, in mm: a tool wider than this is no PCB tool.
MAX_TOOL_MM = 10.0
MAX_HEIGHT_MM = 100.0
#: Tabs round one board: more hold nothing better.
MAX_TABS = 100


@dataclass(frozen=True, slots=True)
class MillConfig:
    """The tool in the spindle and its cut, integer units (module doc)."""

    tool: str = "vbit"                  # one of TOOL_KINDS
    tip_nm: int = 100_000
    angle_mdeg: int = 30_000
    diameter_nm: int = 800_000
    cut_depth_nm: int = 100_000
    safe_height_nm: int = 2_000_000
    spindle_rpm: int = 10_000
    feed_um_min: int = 120_000
    plunge_feed_um_min: int = 60_000
    passes: int = 1
    overlap_permille: int = 250
    drills_nm: tuple[int, ...] = (800_000, 1_000_000)
    breakthrough_nm: int = 200_000
    probe: bool = False
    probe_plate_nm: int = 0
    board_thickness_nm: int = 1_600_000
    cutout_step_down_nm: int = 500_000
    tabs: int = 4
    tab_spacing_nm: int = 0
    tab_width_nm: int = 2_000_000
    tab_height_nm: int = 500_000
    height_map: bool = False
    height_map_spacing_nm: int = 5_000_000
    probe_feed_um_min: int = 50_000
    probe_clearance_nm: int = 1_000_000
    probe_depth_nm: int = 1_000_000

    @property
    def cut_width_nm(self) -> int:
        """The width the tool cuts at the copper's top (module doc)."""
        if self.tool == "endmill":
            return self.diameter_nm
        half_angle = math.radians(self.angle_mdeg / 1000) / 2
        return self.tip_nm + round(2 * self.cut_depth_nm * math.tan(half_angle))

    @property
    def step_nm(self) -> int:
        """How much further out each next pass runs: the cut less the overlap."""
        return max(1, self.cut_width_nm * (1000 - self.overlap_permille) // 1000)

    def describe(self) -> str:
        """The tool and its cut, as a user reads it."""
        if self.tool == "endmill":
            tool = f"end mill {_mm(self.diameter_nm)} mm"
        else:
            tool = f"V-bit {self.angle_mdeg / 1000:g} deg, tip {_mm(self.tip_nm)} mm"
        return (f"{tool}, {_mm(self.cut_depth_nm)} mm deep: cuts {_mm(self.cut_width_nm)} mm "
                f"wide; {self.passes} pass(es), overlap {self.overlap_permille / 10:g} %")

    @classmethod
    def from_table(cls, table: Mapping[str, Any], source: str = "profile",
                   base: "MillConfig | None" = None) -> "MillConfig":
        """The `[mill]` table of `source` (a file name for messages); every error names
        the key and the value. `base`: the config the keys not given keep (options on
        the command line over the profile's table, in the table's keys and units)."""
        if not isinstance(table, Mapping):
            raise ConfigError(f"{source}: [mill] must be a table, got {table!r}")
        unknown = sorted(set(table) - set(_KEYS))
        if unknown:
            named = ", ".join(unknown_key_text(key, _KEYS, table[key]) for key in unknown)
            raise ConfigError(f"{source}: [mill] has unknown key(s): {named} "
                              f"(known: {', '.join(_KEYS)})")
        values: dict[str, Any] = {}
        tool = table.get("tool", base.tool if base is not None else "vbit")
        if tool not in TOOL_KINDS:
            raise ConfigError(f"{source}: [mill] tool = {tool!r}: must be one of "
                              f"{', '.join(repr(kind) for kind in TOOL_KINDS)}")
        values["tool"] = tool
        for key, (field, scale, low, high, low_open) in _NUMBERS.items():
            if key in table:
                values[field] = _number(source, key, table[key], scale, low, high, low_open)
        if "passes" in table:
            passes = table["passes"]
            if isinstance(passes, bool) or not isinstance(passes, int) \
                    or not 1 <= passes <= MAX_PASSES:
                raise ConfigError(f"{source}: [mill] passes = {passes!r}: must be a whole "
                                  f"number 1..{MAX_PASSES}")
            values["passes"] = passes
        if "tabs" in table:
            tabs = table["tabs"]
            if isinstance(tabs, bool) or not isinstance(tabs, int) or not 0 <= tabs <= MAX_TABS:
                raise ConfigError(f"{source}: [mill] tabs = {tabs!r}: must be a whole number "
                                  f"0..{MAX_TABS}")
            values["tabs"] = tabs
        for key in ("probe", "height_map"):
            if key in table:
                if not isinstance(table[key], bool):
                    raise ConfigError(f"{source}: [mill] {key} = {table[key]!r}: must be "
                                      f"true or false")
                values[key] = table[key]
        if "drills" in table:
            values["drills_nm"] = _drills(source, table["drills"])
        config = dataclasses.replace(base, **values) if base is not None else cls(**values)
        if config.tool == "vbit" and config.cut_width_nm <= 0:
            raise ConfigError(f"{source}: [mill] a V-bit with tip_mm = 0 and cut_depth_mm "
                              f"= 0 cuts nothing")
        return config


def _drills(source: str, drills: Any) -> tuple[int, ...]:
    """The `drills` list: bit diameters in mm, made integer nm, smallest first."""
    if not isinstance(drills, list) or not drills:
        raise ConfigError(f"{source}: [mill] drills = {drills!r}: must be a list of bit "
                          f"diameters in mm, e.g. [0.8, 1.0]")
    return tuple(sorted({_number(source, "drills", value, NM_PER_MM, 0.0, MAX_TOOL_MM, True)
                         for value in drills}))


def _mm(nm: int) -> str:
    return f"{nm / NM_PER_MM:.3f}".rstrip("0").rstrip(".") or "0"


def _number(source: str, key: str, value: Any, scale: int, low: float, high: float,
            low_open: bool) -> int:
    """`value` (in the key's unit) checked against low..high and made an integer."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise ConfigError(f"{source}: [mill] {key} = {value!r}: must be a number")
    if value < low or (low_open and value == low) or value > high:
        bound = f"> {low:g}" if low_open else f">= {low:g}"
        raise ConfigError(f"{source}: [mill] {key} = {value!r}: must be {bound} and "
                          f"<= {high:g}")
    return round(value * scale)


#: key -> (field, scale to the field's unit, lowest, highest, lowest excluded)
_NUMBERS = {
    "tip_mm": ("tip_nm", NM_PER_MM, 0.0, MAX_TOOL_MM, False),
    "angle_deg": ("angle_mdeg", 1000, 0.0, 179.0, True),
    "diameter_mm": ("diameter_nm", NM_PER_MM, 0.0, MAX_TOOL_MM, True),
    "cut_depth_mm": ("cut_depth_nm", NM_PER_MM, 0.0, MAX_TOOL_MM, True),
    "safe_height_mm": ("safe_height_nm", NM_PER_MM, 0.0, MAX_HEIGHT_MM, True),
    "spindle_rpm": ("spindle_rpm", 1, 0.0, MAX_SPINDLE_RPM, False),
    "feed_mm_min": ("feed_um_min", 1000, 1.0, 100_000.0, False),
    "plunge_feed_mm_min": ("plunge_feed_um_min", 1000, 1.0, 100_000.0, False),
    "overlap": ("overlap_permille", 1000, 0.0, MAX_OVERLAP, False),
    "breakthrough_mm": ("breakthrough_nm", NM_PER_MM, 0.0, MAX_TOOL_MM, False),
    "probe_plate_mm": ("probe_plate_nm", NM_PER_MM, 0.0, MAX_TOOL_MM, False),
    "board_thickness_mm": ("board_thickness_nm", NM_PER_MM, 0.0, MAX_HEIGHT_MM, True),
    "cutout_step_down_mm": ("cutout_step_down_nm", NM_PER_MM, 0.0, MAX_TOOL_MM, True),
    "tab_spacing_mm": ("tab_spacing_nm", NM_PER_MM, 0.0, 10_000.0, False),
    "tab_width_mm": ("tab_width_nm", NM_PER_MM, 0.0, MAX_HEIGHT_MM, True),
    "tab_height_mm": ("tab_height_nm", NM_PER_MM, 0.0, MAX_HEIGHT_MM, True),
    "height_map_spacing_mm": ("height_map_spacing_nm", NM_PER_MM, 0.0, MAX_HEIGHT_MM, True),
    "probe_feed_mm_min": ("probe_feed_um_min", 1000, 1.0, 100_000.0, False),
    "probe_clearance_mm": ("probe_clearance_nm", NM_PER_MM, 0.0, MAX_HEIGHT_MM, True),
    "probe_depth_mm": ("probe_depth_nm", NM_PER_MM, 0.0, MAX_TOOL_MM, True),
}
_KEYS = ("tool", *_NUMBERS, "passes", "drills", "probe", "tabs", "height_map")
