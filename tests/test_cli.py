"""The galileo-cnc command as a user runs it: a real subprocess."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def galileo(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "galileo_cnc", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)


def test_info_json_of_the_sample_board():
    result = galileo("info", "samples/led-blinker.gbr", "--json", "--margin", "2")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert (info["format"], info["units"], info["format_spec"]) == ("gerber", "mm", "4.6")
    assert info["counts"] == {"draws": 12, "arcs": 3, "flashes": 10, "regions": 1}
    assert info["bbox_mm"] == {"min_x": 6.0, "min_y": 5.0, "max_x": 46.0, "max_y": 36.0}
    assert info["bbox_with_apertures_mm"]["min_y"] == 4.8  # the 0.4 mm track at Y 5
    assert info["proposed_offset_mm"] == {"x": 4.0, "y": 3.0}
    d13 = next(a for a in info["apertures"] if a["code"] == 13)
    assert (d13["description"], d13["draws"], d13["arcs"]) == ("0.4 mm round", 7, 1)


def test_info_text_of_a_gcode_drawing():
    result = galileo("info", "samples/square-and-circle.nc")
    assert result.returncode == 0, result.stderr
    assert "format      gcode" in result.stdout and "4 draws, 1 arcs" in result.stdout


def test_bad_files_give_one_line_with_the_position_and_exit_1(tmp_path):
    broken = tmp_path / "broken.gbr"
    broken.write_text("%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.1*%\nD11*\n")
    result = galileo("info", str(broken))
    assert result.returncode == 1
    assert result.stderr.startswith(f"galileo-cnc: {broken}:4:1: aperture D11 is used but not defined")
    assert "Traceback" not in result.stderr

    result = galileo("info", str(tmp_path / "missing.gbr"))
    assert result.returncode == 1 and "cannot read" in result.stderr

    notes = tmp_path / "notes.txt"
    notes.write_text("shopping list: pens, paper\n")
    result = galileo("info", str(notes))
    assert result.returncode == 1 and "neither a Gerber RS-274X nor a G-code file" in result.stderr
