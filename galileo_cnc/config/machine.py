"""Machine configuration: one frozen record, the seed's machine as defaults.

Everything the host, the reference machine and the firmware header must agree on
lives here (DESIGN.md §3 rule 6): mechanics, feeds, ramps, pen heights, travel,
pins and homing. A user edits it as a TOML file; any field may be overridden.

Units are in the field names. Lengths the user thinks of in millimetres (feeds,
travel) are given in mm; the integer values the machine works with (steps,
steps/s, ticks) are derived properties, rounded once, here.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.errors import GalileoError

NO_PIN = -1


class ConfigError(GalileoError):
    """A configuration file or override is malformed."""


@dataclass(frozen=True, slots=True)
class MachineConfig:
    """The plotter's mechanics, speeds, pen heights, travel, pins and homing."""

    # Mechanics: 200 steps/rev motor on an M8x1.25 threaded rod -> 160 steps/mm.
    steps_per_rev: int = 200
    pitch_mm: float = 1.25
    # Feeds. The seed ran 5 mm/s (240 rpm) and warned above 6.25 mm/s (300 rpm).
    feed_mm_s: float = 5.0
    feed_warn_mm_s: float = 6.25
    # Pen-up travel runs at the fastest feed the seed considered safe.
    rapid_feed_mm_s: float = 6.25
    # Pen lift/lower (Z) moves.
    z_feed_mm_s: float = 5.0
    # Ramps (docs/motion.md §5): start at ramp_start_factor x the step period and
    # approach 1x; the ramp length follows from the axis acceleration bound.
    accel_mm_s2: float = 250.0
    ramp_start_factor: int = 3
    # Junction speeds (docs/motion.md §5.7): 0 stops at every vertex; > 0 (GRBL's $11,
    # whose default is 0.01 mm) plans speed through corners over the whole job: the
    # streamer sends each move's exit index and the firmware and sim:// ramp to it. Every
    # axis changes speed at a vertex by at most vertex_speed_change_mm_s, below the speed
    # an axis already jumps to from rest at the start of a rapid (rapid / 3 = 2.08 mm/s,
    # with the default ramp_start_factor).
    junction_deviation_mm: float = 0.01
    vertex_speed_change_mm_s: float = 2.0
    # Fastest step rate the firmware supports on one axis: 50 ticks = 25 us = 40 kHz.
    min_step_period_ticks: int = 50
    # Pen: Z = pen_down_z_steps draws, pen_lift_steps above it is "up".
    pen_down_z_steps: int = 0
    pen_lift_steps: int = 300
    flash_dwell_ms: int = 200
    # Travel (soft limits) in machine coordinates; 0 is the power-on / homed position.
    x_travel_mm: float = 200.0
    y_travel_mm: float = 200.0
    z_min_steps: int = 0
    z_max_steps: int = 600
    # Pins (Arduino Uno numbering), the seed's wiring. NO_PIN (-1): not fitted.
    x_dir_pin: int = 10
    x_step_pin: int = 11
    y_dir_pin: int = 8
    y_step_pin: int = 9
    z_dir_pin: int = 12
    z_step_pin: int = 13
    x_home_pin: int = 7
    y_home_pin: int = 6
    z_home_pin: int = NO_PIN
    # Homing: seek toward the switch (-1: toward the low end) at a constant slow
    # rate, trip after `home_debounce_reads` consecutive active reads, back off.
    x_home_dir: int = -1
    y_home_dir: int = -1
    z_home_dir: int = 1
    home_feed_mm_s: float = 1.0
    home_debounce_reads: int = 4
    home_pulloff_steps: int = 160
    # Simulated machine only: where the end-stop switches trip, in steps relative
    # to the power-on position (the reference machine needs a physical world).
    sim_x_endstop_steps: int = -400
    sim_y_endstop_steps: int = -400
    sim_z_endstop_steps: int = 700
    # The pens the user owns, widths in mm (TOML: a [pens] table, widths_mm = [0.3, 0.8]).
    # Ink mode fills copper with them, widest first (docs/ink.md); not in config.h.
    pen_widths_mm: tuple = (0.4,)
    # On a stock GRBL board (TOML: a [grbl] table): the pen on the Z axis ("z", at the
    # pen heights above) or a servo on the spindle output ("servo": M3 S<down> lowers
    # it, M5 raises it, or M3 S<up> when servo_up_s > 0, each change followed by a
    # dwell: GRBL does not wait for a servo). Not in config.h.
    grbl_pen: str = "z"
    servo_down_s: int = 1000
    servo_up_s: int = 0
    servo_dwell_ms: int = 150

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type == "int" and (not isinstance(value, int) or isinstance(value, bool)):
                raise ConfigError(f"config: {f.name} must be an integer, got {value!r}")
            if f.type == "float":
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ConfigError(f"config: {f.name} must be a number, got {value!r}")
                if not math.isfinite(value):
                    raise ConfigError(f"config: {f.name} must be a finite number, got {value!r}")
                object.__setattr__(self, f.name, float(value))
        positive = ("steps_per_rev", "pitch_mm", "feed_mm_s", "feed_warn_mm_s",
                    "rapid_feed_mm_s", "z_feed_mm_s", "accel_mm_s2", "min_step_period_ticks",
                    "x_travel_mm", "y_travel_mm", "home_feed_mm_s", "home_debounce_reads")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ConfigError(f"config: {name} must be > 0, got {getattr(self, name)!r}")
        if self.grbl_pen not in GRBL_PENS:
            raise ConfigError(f"config: grbl_pen ([grbl] pen) must be one of {', '.join(GRBL_PENS)}, "
                              f"got {self.grbl_pen!r}")
        for name in ("servo_down_s", "servo_up_s"):
            if not 0 <= getattr(self, name) <= MAX_SPINDLE_S:
                raise ConfigError(f"config: {name} must be 0..{MAX_SPINDLE_S} (GRBL's S "
                                  f"word, scaled by its $30), got {getattr(self, name)!r}")
        if not 0 <= self.servo_dwell_ms <= MAX_SERVO_DWELL_MS:
            raise ConfigError(f"config: servo_dwell_ms must be 0..{MAX_SERVO_DWELL_MS}, "
                              f"got {self.servo_dwell_ms!r}")
        if not 2 <= self.ramp_start_factor <= MAX_RAMP_START_FACTOR:
            raise ConfigError(f"config: ramp_start_factor must be 2..{MAX_RAMP_START_FACTOR} "
                              f"(a move starts at that many times its step period), got "
                              f"{self.ramp_start_factor!r}")
        if self.min_step_period_ticks < MIN_STEP_PERIOD_TICKS:
            raise ConfigError(f"config: min_step_period_ticks must be at least "
                              f"{MIN_STEP_PERIOD_TICKS} (the firmware squares step rates in "
                              f"32 bits), got {self.min_step_period_ticks}")
        fastest = self.max_feed_steps_per_s
        ramp_at_fastest = (self.ramp_start_factor - 1) * fastest * fastest   # about R x A
        if ramp_at_fastest >= MAX_RAMP_EVENTS * self.accel_steps_per_s2:
            least = ramp_at_fastest / MAX_RAMP_EVENTS
            raise ConfigError(f"config: accel_mm_s2 = {self.accel_mm_s2:g} is too low: a ramp "
                              f"to the fastest feed ({fastest / self.steps_per_mm:g} mm/s) "
                              f"would take more steps than the firmware counts (at least "
                              f"{least / self.steps_per_mm:.2f} mm/s2 here)")
        for name in ("junction_deviation_mm", "vertex_speed_change_mm_s"):
            if getattr(self, name) < 0:
                raise ConfigError(f"config: {name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("pen_lift_steps", "flash_dwell_ms", "home_pulloff_steps"):
            if getattr(self, name) < 0:
                raise ConfigError(f"config: {name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("x_home_dir", "y_home_dir", "z_home_dir"):
            if getattr(self, name) not in (-1, 1):
                raise ConfigError(f"config: {name} must be -1 or 1, got {getattr(self, name)!r}")
        self._check_pens()
        self._check_pins()
        if self.z_min_steps > self.z_max_steps:
            raise ConfigError("config: z_min_steps must not exceed z_max_steps")
        for name in ("feed_mm_s", "rapid_feed_mm_s", "z_feed_mm_s", "home_feed_mm_s"):
            sps = self.feed_steps_per_s_of(getattr(self, name))
            if not MIN_FEED_STEPS_PER_S <= sps <= self.max_feed_steps_per_s:
                low, high = (MIN_FEED_STEPS_PER_S / self.steps_per_mm,
                             self.max_feed_steps_per_s / self.steps_per_mm)
                raise ConfigError(
                    f"config: {name} = {getattr(self, name):g} mm/s "
                    f"({getattr(self, name) * 60:g} mm/min) is outside what this machine "
                    f"runs, {low:g} .. {high:g} mm/s ({low * 60:g} .. {high * 60:g} mm/min) "
                    f"[{sps} steps/s, {MIN_FEED_STEPS_PER_S}..{self.max_feed_steps_per_s}]")

    def _check_pins(self) -> None:
        # D0/D1 are the serial line; the Uno has D2..D13 and A0..A5 (14..19) besides.
        pins = {f.name: getattr(self, f.name) for f in fields(self) if f.name.endswith("_pin")}
        for name, pin in pins.items():
            optional = name.endswith("_home_pin")
            if not (FIRST_PIN <= pin <= LAST_PIN or (optional and pin == NO_PIN)):
                raise ConfigError(f"config: {name} = {pin} is not a pin of the board (use "
                                  f"{FIRST_PIN}..{LAST_PIN}" + (f", or {NO_PIN} for none)"
                                                               if optional else ")"))
        fitted = [(pin, name) for name, pin in pins.items() if pin != NO_PIN]
        seen: dict[int, str] = {}
        for pin, name in fitted:
            if pin in seen:
                raise ConfigError(f"config: {name} and {seen[pin]} are both pin {pin}")
            seen[pin] = name

    def _check_pens(self) -> None:
        widths = self.pen_widths_mm
        if isinstance(widths, (int, float)) and not isinstance(widths, bool):
            widths = (widths,)
        if (not isinstance(widths, (list, tuple)) or not 1 <= len(widths) <= MAX_PENS
                or any(isinstance(w, bool) or not isinstance(w, (int, float))
                       or not MIN_PEN_MM <= w <= MAX_PEN_MM for w in widths)):
            got = ", ".join(f"{w:g}" if isinstance(w, (int, float)) else repr(w)
                            for w in widths) if isinstance(widths, (list, tuple)) \
                else repr(widths)
            raise ConfigError(f"config: pens widths_mm must be 1 to {MAX_PENS} widths from "
                              f"{MIN_PEN_MM:g} to {MAX_PEN_MM:g} mm, got {got or 'none'}")
        object.__setattr__(self, "pen_widths_mm",
                           tuple(sorted({float(w) for w in widths}, reverse=True)))

    @property
    def pen_widths_nm(self) -> tuple[int, ...]:
        """The pens, widest first, in nm."""
        return tuple(round(w * 1_000_000) for w in self.pen_widths_mm)

    # ---- derived integer values -------------------------------------------------
    @property
    def steps_per_mm(self) -> float:
        """160.0 for the seed's mechanics."""
        return self.steps_per_rev / self.pitch_mm

    @property
    def pitch_nm(self) -> int:
        return round(self.pitch_mm * 1_000_000)

    @property
    def nm_per_step(self) -> int:
        """One step's length in nm, rounded down (6250 on the seed's machine)."""
        return self.pitch_nm // self.steps_per_rev

    def nm_to_steps(self, nm: int) -> int:
        """Nearest step (halves away from zero), in exact integer arithmetic."""
        num = abs(nm) * self.steps_per_rev
        steps = (2 * num + self.pitch_nm) // (2 * self.pitch_nm)
        return steps if nm >= 0 else -steps

    def nm_to_steps_function(self) -> Callable[[int], int]:
        """`nm_to_steps` with this machine's numbers looked up once, for loops over
        hundreds of thousands of points (the planner): the same arithmetic."""
        per_rev, pitch2 = self.steps_per_rev, 2 * self.pitch_nm
        half = self.pitch_nm

        def nm_to_steps(nm: int) -> int:
            steps = (2 * abs(nm) * per_rev + half) // pitch2
            return steps if nm >= 0 else -steps
        return nm_to_steps

    def nm_to_steps_array(self, nm: np.ndarray) -> np.ndarray:
        """`nm_to_steps` of every element of an int64 array, in the same integer
        arithmetic (coordinates within +-10^12 nm: no overflow)."""
        nm = np.asarray(nm, dtype=np.int64)
        if nm.size and int(np.abs(nm).max()) > 10 ** 12:
            return np.array([self.nm_to_steps(int(v)) for v in nm.ravel().tolist()],
                            dtype=np.int64).reshape(nm.shape)
        steps = (2 * np.abs(nm) * self.steps_per_rev + self.pitch_nm) // (2 * self.pitch_nm)
        return np.where(nm >= 0, steps, -steps)

    def mm_to_steps(self, mm: float) -> int:
        return self.nm_to_steps(round(mm * 1_000_000))

    def feed_steps_per_s_of(self, mm_s: float) -> int:
        """A feed in mm/s as the integer steps/s the machine commands carry."""
        return int(math.floor(mm_s * self.steps_per_mm + 0.5))

    def feed_rpm(self, mm_s: float) -> float:
        """Motor speed for a feed: rpm = mm/s * 60 / pitch (= feed * 48 for the seed)."""
        return mm_s * 60.0 / self.pitch_mm

    @property
    def feed_steps_per_s(self) -> int:
        return self.feed_steps_per_s_of(self.feed_mm_s)

    @property
    def rapid_steps_per_s(self) -> int:
        return self.feed_steps_per_s_of(self.rapid_feed_mm_s)

    @property
    def z_feed_steps_per_s(self) -> int:
        return self.feed_steps_per_s_of(self.z_feed_mm_s)

    @property
    def home_feed_steps_per_s(self) -> int:
        return self.feed_steps_per_s_of(self.home_feed_mm_s)

    @property
    def accel_steps_per_s2(self) -> int:
        return max(1, round(self.accel_mm_s2 * self.steps_per_mm))

    @property
    def junction_deviation_nm(self) -> int:
        """0: a stop at every vertex (junction speeds off)."""
        return round(self.junction_deviation_mm * 1_000_000)

    @property
    def vertex_speed_change_steps_per_s(self) -> int:
        return round(self.vertex_speed_change_mm_s * self.steps_per_mm)

    @property
    def max_feed_steps_per_s(self) -> int:
        """The step rate that keeps one axis at or above the minimum step period."""
        return TICKS_PER_S // self.min_step_period_ticks

    @property
    def pen_up_z_steps(self) -> int:
        return self.pen_down_z_steps + self.pen_lift_steps

    @property
    def travel_min_steps(self) -> tuple[int, int, int]:
        return (0, 0, self.z_min_steps)

    @property
    def travel_max_steps(self) -> tuple[int, int, int]:
        return (self.mm_to_steps(self.x_travel_mm), self.mm_to_steps(self.y_travel_mm),
                self.z_max_steps)

    @property
    def home_pins(self) -> tuple[int, int, int]:
        return (self.x_home_pin, self.y_home_pin, self.z_home_pin)

    @property
    def home_dirs(self) -> tuple[int, int, int]:
        return (self.x_home_dir, self.y_home_dir, self.z_home_dir)

    @property
    def sim_endstop_steps(self) -> tuple[int, int, int]:
        return (self.sim_x_endstop_steps, self.sim_y_endstop_steps, self.sim_z_endstop_steps)

    # ---- construction -----------------------------------------------------------
    def travel_refusal(self, axis: str, value_steps: int, limit_steps: int) -> str:
        """A soft-limit refusal in the user's units (machine coordinates), steps in brackets."""
        side = "beyond the travel's end at" if value_steps > limit_steps else \
            "below the travel's start at"
        return (f"{axis} would reach {value_steps / self.steps_per_mm:.3f} mm, {side} "
                f"{limit_steps / self.steps_per_mm:.3f} mm [{value_steps} steps]")

    def firmware_values(self) -> tuple[tuple[str, int, str], ...]:
        """What the firmware is built with from this profile: config.h's `CFG_` names,
        integer values and comments, in header order. The digest in the firmware's
        banner covers exactly these, so the host can tell a board built for another
        machine (docs/protocol.md, Banner)."""
        tmin, tmax = self.travel_min_steps, self.travel_max_steps
        return (
            ("STEPS_PER_REV", self.steps_per_rev, "mechanics (informational: the host converts)"),
            ("PITCH_NM", round(self.pitch_mm * 1_000_000), ""),
            ("FEED_STEPS_PER_S", self.feed_steps_per_s, "default feed"),
            ("RAPID_STEPS_PER_S", self.rapid_steps_per_s, "pen-up travel"),
            ("Z_FEED_STEPS_PER_S", self.z_feed_steps_per_s, "pen up / down"),
            ("HOME_FEED_STEPS_PER_S", self.home_feed_steps_per_s, "homing seek and pull-off"),
            ("MAX_FEED_STEPS_PER_S", self.max_feed_steps_per_s, "= TICKS_PER_S / MIN_STEP_PERIOD"),
            ("MIN_STEP_PERIOD_TICKS", self.min_step_period_ticks, ""),
            ("ACCEL_STEPS_PER_S2", self.accel_steps_per_s2, "axis acceleration bound A"),
            ("RAMP_START_FACTOR", self.ramp_start_factor, "a move starts at this x the period"),
            ("PEN_DOWN_Z_STEPS", self.pen_down_z_steps, ""),
            ("PEN_UP_Z_STEPS", self.pen_up_z_steps, ""),
            ("FLASH_DWELL_MS", self.flash_dwell_ms, ""),
            ("X_TRAVEL_MIN_STEPS", tmin[0], "soft limits, machine steps"),
            ("X_TRAVEL_MAX_STEPS", tmax[0], ""),
            ("Y_TRAVEL_MIN_STEPS", tmin[1], ""),
            ("Y_TRAVEL_MAX_STEPS", tmax[1], ""),
            ("Z_TRAVEL_MIN_STEPS", tmin[2], ""),
            ("Z_TRAVEL_MAX_STEPS", tmax[2], ""),
            ("X_STEP_PIN", self.x_step_pin, "Arduino pin numbers"),
            ("X_DIR_PIN", self.x_dir_pin, ""),
            ("Y_STEP_PIN", self.y_step_pin, ""),
            ("Y_DIR_PIN", self.y_dir_pin, ""),
            ("Z_STEP_PIN", self.z_step_pin, ""),
            ("Z_DIR_PIN", self.z_dir_pin, ""),
            ("X_HOME_PIN", self.x_home_pin, f"{NO_PIN}: no end-stop; INPUT_PULLUP, active LOW"),
            ("Y_HOME_PIN", self.y_home_pin, ""),
            ("Z_HOME_PIN", self.z_home_pin, ""),
            ("X_HOME_DIR", self.x_home_dir, "seek direction"),
            ("Y_HOME_DIR", self.y_home_dir, ""),
            ("Z_HOME_DIR", self.z_home_dir, ""),
            ("HOME_DEBOUNCE_READS", self.home_debounce_reads, "consecutive active reads"),
            ("HOME_PULLOFF_STEPS", self.home_pulloff_steps, ""),
        )

    def firmware_text(self) -> str:
        """`NAME=value` pairs of `firmware_values`, as the firmware's `C` query answers."""
        return " ".join(f"{name}={value}" for name, value, _ in self.firmware_values())

    def firmware_digest(self) -> str:
        """Eight hex digits naming `firmware_values`; the banner's `config` field."""
        return hashlib.sha256(self.firmware_text().encode("ascii")).hexdigest()[:8]

    def replace(self, **overrides: Any) -> "MachineConfig":
        _check_keys(overrides, "override")
        return dataclasses.replace(self, **overrides)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "config") -> "MachineConfig":
        """Build from a TOML-like mapping: top-level keys or a `[machine]` table, the
        pens from a `[pens]` table (widths_mm), a GRBL board's pen from a `[grbl]`
        table (pen, servo_down_s, servo_up_s, servo_dwell_ms)."""
        tables = {}          # keys from the [pens] and [grbl] tables
        if isinstance(data.get("pens"), Mapping):
            unknown = sorted(set(data["pens"]) - {"widths_mm"})
            if unknown:
                named = ", ".join(unknown_key_text(key, {"widths_mm"}) for key in unknown)
                raise ConfigError(f"{source}: unknown pens setting(s): {named} "
                                  "(expected widths_mm = [0.3, 0.8])")
            if "widths_mm" in data["pens"]:
                tables["pen_widths_mm"] = data["pens"]["widths_mm"]
        if isinstance(data.get("grbl"), Mapping):
            names = {"pen": "grbl_pen", "servo_down_s": "servo_down_s",
                     "servo_up_s": "servo_up_s", "servo_dwell_ms": "servo_dwell_ms"}
            unknown = sorted(set(data["grbl"]) - set(names))
            if unknown:
                raise ConfigError(f"{source}: unknown grbl setting(s): "
                                  f"{', '.join(unknown_key_text(k, names) for k in unknown)} "
                                  f"(known: {', '.join(names)})")
            tables.update({names[key]: value for key, value in data["grbl"].items()})
        if "machine" in data and isinstance(data["machine"], Mapping):
            extra = [k for k in data if k != "machine" and not isinstance(data[k], Mapping)]
            data = {**{k: data[k] for k in extra}, **data["machine"]}
        else:  # other tables (serial port, console) belong to other parts of the program
            data = {k: v for k, v in data.items() if not isinstance(v, Mapping)}
        _check_keys(data, source)
        try:
            return cls(**data, **tables)
        except ConfigError as problem:  # name the file, not just the key
            text = str(problem)
            if source != "config" and text.startswith("config: "):
                text = f"{source}: {text[len('config: '):]}"
            raise ConfigError(text) from None

    @classmethod
    def from_toml(cls, path: str | Path, **overrides: Any) -> "MachineConfig":
        config = cls.from_mapping(read_toml(path), source=str(path))
        return config.replace(**overrides) if overrides else config

    def to_toml(self) -> str:
        """The config as a `[machine]` TOML table (for writing a starter file)."""
        lines = ["[machine]"]
        for f in fields(self):
            if f.name != "pen_widths_mm":
                lines.append(f"{f.name} = {getattr(self, f.name)!r}")
        lines += ["", "[pens]", f"widths_mm = {list(self.pen_widths_mm)!r}"]
        return "\n".join(lines) + "\n"


MIN_FEED_STEPS_PER_S = 10
#: A slower start than 1/8 of the feed gains nothing; the firmware's ramp sums stay
#: in 32 bits up to it (firmware/galileo/planner.cpp).
MAX_RAMP_START_FACTOR = 8
#: The firmware counts a ramp's events in 24 bits (stepper.h).
MAX_RAMP_EVENTS = (1 << 24) - 1
#: Keeps the fastest step rate below 65 536 steps/s, whose square the firmware's ramp
#: length takes in 32 bits (planner.cpp).
MIN_STEP_PERIOD_TICKS = 31
#: The pen on a GRBL board: on the Z axis, or a servo on the spindle output.
GRBL_PENS = ("z", "servo")
#: Bounds of the servo's S words and its dwell (GRBL's $30 is 1000 by default).
MAX_SPINDLE_S = 100_000
MAX_SERVO_DWELL_MS = 10_000
#: Arduino Uno pins a profile may use: D2..D13 and A0..A5 as 14..19 (D0/D1: serial).
FIRST_PIN, LAST_PIN = 2, 19
#: Pens in a set, and the narrowest and widest pen, that the ink mode takes: the finest
#: technical pens draw 0.1 mm; a pen of a few um would take hours and gigabytes to plan
MAX_PENS, MIN_PEN_MM, MAX_PEN_MM = 8, 0.05, 5.0
_FIELD_NAMES = frozenset(f.name for f in fields(MachineConfig))


def pen_widths_from_text(text: str) -> tuple[float, ...]:
    """`--pens 0.3,0.8` as widths in mm (the config checks their range)."""
    try:
        return tuple(float(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise ConfigError(f"--pens: expected widths in mm like 0.3 or 0.3,0.8, got {text!r}") \
            from None


def _check_keys(data: Mapping[str, Any], source: str) -> None:
    unknown = sorted(set(data) - _FIELD_NAMES)
    if unknown:
        raise ConfigError(f"{source}: unknown machine setting(s): "
                          + "; ".join(unknown_key_text(key, _FIELD_NAMES, data[key])
                                      for key in unknown))


def unknown_key_text(key: str, known, value: Any = None) -> str:
    """`key`, and the known name it most likely meant (`feed_mm_min`: did you mean
    feed_mm_s?, with the value in mm/s when only the unit was wrong)."""
    close = difflib.get_close_matches(key, sorted(known), n=1, cutoff=0.6)
    if not close:
        return key
    text = f"{key} (did you mean {close[0]}?"
    if key.endswith("_mm_min") and close[0] == key[:-len("_mm_min")] + "_mm_s" \
            and isinstance(value, (int, float)) and not isinstance(value, bool):
        text += f" it is in mm/s: {value:g} mm/min is {close[0]} = {value / 60:g}"
    return text + ")"


def read_toml(path: str | Path, what: str = "config") -> dict:
    """A TOML file as a dict; ConfigError naming the file when it cannot be read."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read {what}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: bad TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: cannot read {what}: not UTF-8 text (byte "
                          f"0x{exc.object[exc.start]:02x} at offset {exc.start})") from None


def load_config(path: str | Path | None = None, **overrides: Any) -> MachineConfig:
    """The seed defaults, or a TOML file, with keyword overrides applied last."""
    if path is None:
        return MachineConfig().replace(**overrides) if overrides else MachineConfig()
    return MachineConfig.from_toml(path, **overrides)
