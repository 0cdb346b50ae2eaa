"""Bad profiles are refused before anything moves, naming the file, the key and what
was expected; the whole `galileo-cnc` command is run so the user's message is tested."""

import subprocess
import sys
from pathlib import Path

import pytest

from galileo_cnc.config.machine import ConfigError, MachineConfig
from galileo_cnc.config.profile import load_profile

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr"


@pytest.mark.parametrize("text, expected", [
    (b"[machine]\npitch_mm = nan\n", "pitch_mm must be a finite number, got nan"),
    (b"[machine]\nfeed_mm_s = inf\n", "feed_mm_s must be a finite number, got inf"),
    (b"[machine]\naccel_mm_s2 = -inf\n", "accel_mm_s2 must be a finite number"),
    (b"[machine]\nsteps_per_rev = 2.5\n", "steps_per_rev must be an integer, got 2.5"),
    (b"[machine]\nramp_start_factor = 9\n", "ramp_start_factor must be 2..8 (a move starts "
     "at that many times its step period), got 9"),
    (b"[machine]\nramp_start_factor = 1\n", "ramp_start_factor must be 2..8"),
    (b"[machine]\naccel_mm_s2 = 1.0\nramp_start_factor = 8\n", "accel_mm_s2 = 1 is too low: "
     "a ramp to the fastest feed (250 mm/s) would take more steps than the firmware counts "
     "(at least 4.17 mm/s2 here)"),
    (b"[machine]\nmin_step_period_ticks = 30\n", "min_step_period_ticks must be at least 31"),
    (b"[machine]\npitch_mm = \"fine\"\n", "pitch_mm must be a number, got 'fine'"),
    (b"[machine]\nx_step_pin = 1\n", "x_step_pin = 1 is not a pin of the board"),
    (b"[machine]\ny_dir_pin = 20\n", "y_dir_pin = 20 is not a pin of the board"),
    (b"[machine]\nx_step_pin = -1\n", "x_step_pin = -1 is not a pin of the board (use 2..19)"),
    (b"[machine]\nx_step_pin = 10\n", "x_step_pin and x_dir_pin are both pin 10"),
    (b"[pens]\nwidths_mm = [nan]\n", "widths_mm must be 1 to 8 widths from 0.05 to 5 mm"),
    (b"[serial]\nbaud = 0\n", "[serial] baud: baud rate 0 not supported"),
    (b"[serial]\nbaud = \"fast\"\n", "[serial] baud: baud rate 'fast' not supported"),
    (b"[serial]\nbaud = true\n", "baud rate True not supported"),
    (b"[serial]\nport = 3\n", "[serial] port must be text"),
    (b"\xff\xfe[machine]\n", "not UTF-8 text (byte 0xff at offset 0)"),
    (b"[machine\n", "bad TOML"),
    (b"[grbl]\npen = \"pneumatic\"\n", "grbl_pen ([grbl] pen) must be one of z, servo"),
    (b"[grbl]\nservo_down_s = -5\n", "servo_down_s must be 0..100000"),
    (b"[grbl]\nservo_dwell_ms = 1.5\n", "servo_dwell_ms must be an integer, got 1.5"),
    (b"[grbl]\nservo = true\n", "unknown grbl setting(s): servo (did you mean servo_up_s?) (known: pen,"),
    (b"[machine]\nfeed_mm_min = 300\n", "unknown machine setting(s): feed_mm_min (did you "
     "mean feed_mm_s? it is in mm/s: 300 mm/min is feed_mm_s = 5)"),
    (b"[machine]\nsteps_per_revolution = 200\n", "steps_per_revolution (did you mean "
     "steps_per_rev?)"),
    (b"[machin]\nfeed_mm_s = 3\n", "unknown table(s): [machin] (did you mean [machine]?)"),
    (b"[serial]\nbaud_rate = 9600\n", "baud_rate (did you mean baud?) (known: port, baud)"),
    (b"[pens]\nwidth_mm = [0.3]\n", "width_mm (did you mean widths_mm?)"),
])
def test_bad_profile_names_file_key_and_expectation(tmp_path, text, expected):
    profile = tmp_path / "profile.toml"
    profile.write_bytes(text)
    with pytest.raises(ConfigError) as refused:
        load_profile(profile)
    assert str(refused.value).startswith(f"{profile}: ")
    assert expected in str(refused.value)


def test_a_home_switch_may_be_absent_but_a_motor_pin_may_not():
    assert MachineConfig(x_home_pin=-1).x_home_pin == -1
    assert MachineConfig(x_home_pin=19, y_home_pin=14).y_home_pin == 14
    with pytest.raises(ConfigError, match="z_step_pin = -1"):
        MachineConfig(z_step_pin=-1)


def test_explicit_bad_baud_is_refused_not_taken_as_absent(tmp_path):
    with pytest.raises(ConfigError, match="--baud: baud rate 0 not supported"):
        load_profile(None, baud=0)
    assert load_profile(None, baud=9600).baud == 9600


@pytest.mark.parametrize("profile_text", [b"[machine]\npitch_mm = nan\n", b"\xff[serial]\n"])
def test_plot_with_a_bad_profile_stops_with_one_line(tmp_path, profile_text):
    profile = tmp_path / "p.toml"
    profile.write_bytes(profile_text)
    done = subprocess.run([sys.executable, "-m", "galileo_cnc", "plot", "--profile", str(profile),
                           "--port", "sim://", str(SAMPLE)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode != 0
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().startswith(f"galileo-cnc: {profile}: ")
    assert "%" not in done.stdout          # no progress bar: nothing was streamed


def test_a_servo_pen_is_the_profiles_choice_and_survives_the_journal(tmp_path):
    from galileo_cnc.config.machine import tomllib
    from galileo_cnc.grbl.gcode import pen_from_config

    profile = tmp_path / "profile.toml"
    profile.write_text('[grbl]\npen = "servo"\nservo_down_s = 700\nservo_up_s = 200\n')
    config = load_profile(profile).config
    pen = pen_from_config(config)
    assert (pen.servo, pen.down_s, pen.up_s, pen.servo_dwell_ms) == (True, 700, 200, 150)
    # the journal keeps the profile as to_toml's text: the same pen comes back
    assert MachineConfig.from_mapping(tomllib.loads(config.to_toml())) == config
    assert not pen_from_config(MachineConfig()).servo           # the default: Z axis
    # not in config.h: the firmware digest does not change with the GRBL pen
    assert config.firmware_digest() == MachineConfig().firmware_digest()
