"""MachineConfig: the seed's machine as defaults, TOML loading, overrides."""

import numpy as np
import pytest

from galileo_cnc.config.hardware import TICKS_PER_S
from galileo_cnc.config.machine import ConfigError, MachineConfig, load_config
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import Flash, PenDown, PenUp
from galileo_cnc.machine import simulate
from galileo_cnc.machine.ramps import axial_interval_sub


def test_seed_mechanics():
    c = MachineConfig()
    assert c.steps_per_mm == 160
    assert c.feed_mm_s == 5.0
    assert c.feed_rpm(c.feed_mm_s) == 240           # rpm = feed * 48
    assert c.feed_rpm(1.0) == 48
    assert c.feed_steps_per_s == 800
    assert c.feed_warn_mm_s == 6.25
    assert c.feed_rpm(c.feed_warn_mm_s) == 300
    assert c.pen_lift_steps == 300
    assert c.flash_dwell_ms == 200
    # 800 steps/s -> 1.25 ms = 2500 ticks of 0.5 us per step along an axis.
    assert axial_interval_sub(c.feed_steps_per_s) == 2500 * 256
    assert c.mm_to_steps(1.0) == 160
    assert c.nm_to_steps(6250) == 1 and c.nm_to_steps(-3125) == -1


@pytest.mark.parametrize("pitch_mm, steps_per_rev", [(1.25, 200), (8.0, 3200), (0.7, 400)])
def test_the_planners_step_function_rounds_as_nm_to_steps(pitch_mm, steps_per_rev):
    import random

    c = MachineConfig(pitch_mm=pitch_mm, steps_per_rev=steps_per_rev)
    fast = c.nm_to_steps_function()
    half = c.pitch_nm // (2 * steps_per_rev)
    rng = random.Random(7)
    values = [rng.randrange(-10 ** 10, 10 ** 10) for _ in range(20_000)]
    values += [k * half + d for k in range(-50, 50) for d in (-1, 0, 1)]   # halves
    assert [fast(v) for v in values] == [c.nm_to_steps(v) for v in values]
    # and the planner's arrays, also past the range they are worked out in int64
    values += [10 ** 13 + 3 * half, -(10 ** 15) - half]
    assert c.nm_to_steps_array(np.array(values, dtype=np.int64)).tolist() == \
        [c.nm_to_steps(v) for v in values]


def test_seed_pins():
    c = MachineConfig()
    assert (c.x_dir_pin, c.x_step_pin, c.y_dir_pin, c.y_step_pin) == (10, 11, 8, 9)
    assert (c.z_dir_pin, c.z_step_pin, c.x_home_pin, c.y_home_pin) == (12, 13, 7, 6)


def test_pen_lift_and_flash_dwell_reproduce_in_trace():
    c = MachineConfig()
    up = simulate([PenUp()], c)
    assert up.final_position == (0, 0, 300) and len(up) == 300
    flash = simulate([PenUp(), Flash()], c)
    t = flash.tick[300:]  # down 300 steps, dwell, up 300 steps
    assert len(t) == 600
    # The dwell sits between the last down step and the first up step.
    gap = int(t[300] - t[299])
    first_interval = int(up.tick[0])  # interval before the first step of a Z move
    assert gap == 200 * TICKS_PER_S // 1000 + first_interval
    assert flash.final_position == (0, 0, 300)
    assert simulate([PenDown()], c).final_position == (0, 0, 0)


def test_toml_load_and_override(tmp_path):
    path = tmp_path / "machine.toml"
    path.write_text('[machine]\nfeed_mm_s = 4\npen_lift_steps = 250\n\n[serial]\nport = "x"\n')
    c = MachineConfig.from_toml(path)
    assert c.feed_mm_s == 4.0 and isinstance(c.feed_mm_s, float)
    assert c.pen_lift_steps == 250
    assert c.steps_per_mm == 160
    c2 = load_config(path, pen_lift_steps=100)
    assert c2.pen_lift_steps == 100
    top = tmp_path / "top.toml"
    top.write_text("flash_dwell_ms = 150\n")
    assert load_config(top).flash_dwell_ms == 150
    assert load_config().flash_dwell_ms == 200


def test_every_field_overridable():
    c = MachineConfig()
    for name in MachineConfig.__dataclass_fields__:
        value = getattr(c, name)
        if name.startswith("sim_") or isinstance(value, float):
            continue
        c.replace(**{name: value})


@pytest.mark.parametrize("text, word", [
    ("feed_mm_s = 'fast'\n", "feed_mm_s"),
    ("pen_lift_steps = 1.5\n", "pen_lift_steps"),
    ("no_such_thing = 1\n", "no_such_thing"),
    ("feed_mm_s = 0\n", "feed_mm_s"),
    ("feed_mm_s = 1000\n", r"feed_mm_s = 1000 mm/s \(60000 mm/min\) is outside what this "
                           r"machine runs, 0\.0625 \.\. 250 mm/s \(3\.75 \.\. 15000 mm/min\)"),
    ("x_home_dir = 2\n", "x_home_dir"),
    ("= broken\n", "bad TOML"),
])
def test_bad_config_is_a_galileo_error(tmp_path, text, word):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=word) as info:
        MachineConfig.from_toml(path)
    assert isinstance(info.value, GalileoError)


def test_frozen():
    with pytest.raises(Exception):
        MachineConfig().feed_mm_s = 3.0  # type: ignore[misc]


def test_to_toml_round_trip(tmp_path):
    c = MachineConfig(feed_mm_s=3.5, z_home_pin=5)
    path = tmp_path / "out.toml"
    path.write_text(c.to_toml())
    assert MachineConfig.from_toml(path) == c
