"""The [mill] keys drilling and the cut-out read: bits, probe, board, tabs, each refused
naming the key and the value when wrong."""

import pytest

from galileo_cnc.config.machine import ConfigError
from galileo_cnc.config.mill import MillConfig


def test_the_drilling_and_cut_out_keys_in_mm_made_integer_nm():
    mill = MillConfig.from_table({"drills": [1.0, 0.8, 1.0], "probe": True,
                                  "probe_plate_mm": 0.05, "board_thickness_mm": 0.8,
                                  "cutout_step_down_mm": 0.3, "tabs": 0,
                                  "tab_spacing_mm": 25, "tab_width_mm": 1.5,
                                  "tab_height_mm": 0.4, "breakthrough_mm": 0})
    assert mill.drills_nm == (800_000, 1_000_000)          # sorted, each bit once
    assert (mill.probe, mill.probe_plate_nm, mill.board_thickness_nm) == (True, 50_000, 800_000)
    assert (mill.cutout_step_down_nm, mill.tabs, mill.tab_spacing_nm) == (300_000, 0, 25_000_000)
    assert (mill.tab_width_nm, mill.tab_height_nm, mill.breakthrough_nm) == (1_500_000, 400_000, 0)


@pytest.mark.parametrize("table, expected", [
    ({"drills": 0.8}, "[mill] drills = 0.8: must be a list of bit diameters in mm"),
    ({"drills": []}, "[mill] drills = []: must be a list"),
    ({"drills": [0.8, 0]}, "[mill] drills = 0: must be > 0 and <= 10"),
    ({"probe": "yes"}, "[mill] probe = 'yes': must be true or false"),
    ({"tabs": -1}, "[mill] tabs = -1: must be a whole number 0..100"),
    ({"board_thickness_mm": 0}, "[mill] board_thickness_mm = 0: must be > 0"),
    ({"cutout_step_down_mm": 0}, "[mill] cutout_step_down_mm = 0: must be > 0"),
])
def test_a_bad_key_is_refused_naming_it(table, expected):
    with pytest.raises(ConfigError) as caught:
        MillConfig.from_table(table, "profile.toml")
    assert expected in str(caught.value)
