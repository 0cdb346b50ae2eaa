"""The profile's [mill] table: the tool's cut width from its shape, integer units inside,
and every bad value refused naming the file, the key and the value."""

import pytest

from galileo_cnc.config.machine import ConfigError
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.config.profile import load_profile


def _profile(tmp_path, text: str):
    path = tmp_path / "profile.toml"
    path.write_text(text)
    return load_profile(path)


def test_a_v_bit_cuts_its_tip_plus_the_cone_at_depth(tmp_path):
    mill = _profile(tmp_path, "[mill]\ntool = \"vbit\"\ntip_mm = 0.1\nangle_deg = 60\n"
                              "cut_depth_mm = 0.1\nfeed_mm_min = 150\nplunge_feed_mm_min = 50\n"
                              "safe_height_mm = 1.5\nspindle_rpm = 12000\npasses = 3\n"
                              "overlap = 0.5\n").mill
    # 0.1 + 2 * 0.1 * tan(30 deg) = 0.21547 mm
    assert mill.cut_width_nm == 215_470
    assert (mill.tip_nm, mill.angle_mdeg, mill.cut_depth_nm) == (100_000, 60_000, 100_000)
    assert (mill.feed_um_min, mill.plunge_feed_um_min, mill.safe_height_nm) == (
        150_000, 50_000, 1_500_000)
    assert (mill.spindle_rpm, mill.passes, mill.overlap_permille) == (12_000, 3, 500)
    assert mill.step_nm == 107_735
    assert "cuts 0.215 mm wide; 3 pass(es), overlap 50 %" in mill.describe()


def test_an_end_mill_cuts_its_diameter_and_no_table_gives_the_defaults(tmp_path):
    mill = _profile(tmp_path, "[mill]\ntool = \"endmill\"\ndiameter_mm = 0.8\n").mill
    assert mill.cut_width_nm == 800_000
    assert _profile(tmp_path, "[machine]\npitch_mm = 1.25\n").mill == MillConfig()


@pytest.mark.parametrize("text, expected", [
    ("tool = \"drill\"", "[mill] tool = 'drill': must be one of 'vbit', 'endmill'"),
    ("tip_mm = -0.1", "[mill] tip_mm = -0.1: must be >= 0 and <= 10"),
    ("angle_deg = 0", "[mill] angle_deg = 0: must be > 0 and <= 179"),
    ("angle_deg = 180", "[mill] angle_deg = 180: must be > 0 and <= 179"),
    ("cut_depth_mm = \"deep\"", "[mill] cut_depth_mm = 'deep': must be a number"),
    ("safe_height_mm = nan", "[mill] safe_height_mm = nan: must be a number"),
    ("feed_mm_min = 0", "[mill] feed_mm_min = 0: must be >= 1 and <= 100000"),
    ("spindle_rpm = true", "[mill] spindle_rpm = True: must be a number"),
    ("passes = 0", "[mill] passes = 0: must be a whole number 1..20"),
    ("passes = 1.5", "[mill] passes = 1.5: must be a whole number 1..20"),
    ("overlap = 1", "[mill] overlap = 1: must be >= 0 and <= 0.9"),
    ("feed_mm_s = 2", "[mill] has unknown key(s): feed_mm_s (did you mean feed_mm_min?)"),
    ("tip_mm = 0\ncut_depth_mm = 0.0", "[mill] cut_depth_mm = 0.0: must be > 0"),
])
def test_a_bad_mill_table_is_refused_naming_the_file_key_and_value(tmp_path, text, expected):
    with pytest.raises(ConfigError) as caught:
        _profile(tmp_path, f"[mill]\n{text}\n")
    assert expected in str(caught.value)
    assert str(tmp_path / "profile.toml") in str(caught.value)


def test_options_over_the_profile_keep_what_they_do_not_name(tmp_path):
    mill = _profile(tmp_path, "[mill]\ntool = \"endmill\"\ndiameter_mm = 0.3\npasses = 2\n").mill
    over = MillConfig.from_table({"passes": 4, "overlap": 0.5}, "command line", base=mill)
    assert (over.tool, over.diameter_nm, over.passes, over.overlap_permille) == (
        "endmill", 300_000, 4, 500)
    with pytest.raises(ConfigError, match=r"command line: \[mill\] passes = 40: must be"):
        MillConfig.from_table({"passes": 40}, "command line", base=mill)


def test_the_height_map_keys_in_mm_made_integer_and_each_refused_naming_it(tmp_path):
    mill = _profile(tmp_path, "[mill]\nheight_map = true\nheight_map_spacing_mm = 2.5\n"
                              "probe_feed_mm_min = 30\nprobe_clearance_mm = 0.5\n"
                              "probe_depth_mm = 0.8\n").mill
    assert (mill.height_map, mill.height_map_spacing_nm, mill.probe_feed_um_min) == (
        True, 2_500_000, 30_000)
    assert (mill.probe_clearance_nm, mill.probe_depth_nm) == (500_000, 800_000)
    assert MillConfig().height_map is False
    for text, expected in (
            ("height_map = 1", "[mill] height_map = 1: must be true or false"),
            ("height_map_spacing_mm = 0", "[mill] height_map_spacing_mm = 0: must be > 0"),
            ("probe_feed_mm_min = 0.5", "[mill] probe_feed_mm_min = 0.5: must be >= 1"),
            ("probe_clearance_mm = -1", "[mill] probe_clearance_mm = -1: must be > 0"),
            ("probe_depth_mm = 20", "[mill] probe_depth_mm = 20: must be > 0 and <= 10"),
            ("height_map_spacing = 5", "unknown key(s): height_map_spacing (did you mean "
                                       "height_map_spacing_mm?)")):
        with pytest.raises(ConfigError) as caught:
            _profile(tmp_path, f"[mill]\n{text}\n")
        assert expected in str(caught.value) and "profile.toml" in str(caught.value)
