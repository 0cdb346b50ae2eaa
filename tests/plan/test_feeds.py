"""Feeds checked in every front end (issue 31, item 12): a G-code `F600` (10 mm/s) or a
profile feed of 100 mm/s is said above the warning feed (6.25 mm/s), with the file line
and the F word as written, in mm/s and mm/min; `F60000` is refused in mm, not steps/s."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.feeds import FeedError, check_feeds
from galileo_cnc.plan.pipeline import plan_file
from galileo_cnc.readers import read_file

TESTS = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(TESTS / "cli"), str(TESTS / "console")]
from test_console import console_in_thread, home  # noqa: E402,F401  (home: the fixture)
from test_transform import shell  # noqa: E402,F401  (the fixture)

SQUARE = "G21 G90\nG0 X1 Y1\nM3\nG1 X11 Y1 F{first}\nG1 X11 Y11\nG1 X1 Y11 F{second}\nM5\n"
WARNING = (r"warning: {file}:4: F600 is 10 mm/s \(600 mm/min\), above the warning feed "
           r"6\.25 mm/s \(375 mm/min, feed_warn_mm_s in the profile\)")


@pytest.fixture
def fast(tmp_path) -> Path:
    """A square drawn at F600 (10 mm/s), then F 900 (written with a space)."""
    path = tmp_path / "fast.nc"
    path.write_text(SQUARE.format(first="600", second=" 900"))
    return path


def test_a_g_code_feed_above_the_warning_feed_is_said_once_with_its_line(fast):
    warnings = check_feeds(read_file(fast), MachineConfig())
    assert warnings == [
        f"warning: {fast}:4: F600 is 10 mm/s (600 mm/min), above the warning feed 6.25 mm/s "
        "(375 mm/min, feed_warn_mm_s in the profile): the motors may stall and lose steps; "
        "2 feeds of the file are above it, the fastest F900 at line 6 (15 mm/s (900 mm/min))"]
    assert plan_file(fast).feed_warnings == tuple(warnings)
    # a machine whose warning feed is higher says nothing
    assert check_feeds(read_file(fast), MachineConfig(feed_warn_mm_s=20)) == []


def test_a_feed_beyond_the_machine_is_refused_in_mm_with_the_file_line(tmp_path, shell):
    path = tmp_path / "racing.nc"
    path.write_text(SQUARE.format(first="600", second="60000"))
    with pytest.raises(FeedError) as refused:
        plan_file(path)
    assert str(refused.value) == (
        f"{path}:6:11: F60000 is 1000 mm/s (60000 mm/min), faster than the machine's limit "
        "of 250 mm/s (15000 mm/min) [160000 steps/s, at most 40000]")
    result = shell("plot", str(path), "--port", "sim://?speed=0")
    assert result.returncode == 1 and "F60000 is 1000 mm/s (60000 mm/min)" in result.stderr
    assert "steps/s, at most" in result.stderr and "outside" not in result.stderr
    # inches as the file wrote them: F0.1 in/min is 0.0423 mm/s, below the slowest 0.0625
    slow = tmp_path / "slow.nc"
    slow.write_text("G20 G90\nM3\nG1 X1 F0.1\nM5\n")
    with pytest.raises(FeedError, match=r"slow\.nc:3:7: F0\.1 is 0\.042333 mm/s \(2\.54 "
                                        r"mm/min\), slower than the machine's slowest"):
        plan_file(slow)


def test_every_front_end_warns(tmp_path, fast, shell):
    pattern = WARNING.format(file=str(fast).replace(".", r"\."))
    plot = shell("plot", str(fast), "--port", "sim://?speed=0")
    assert plot.returncode == 0, plot.stderr
    assert re.search(pattern, plot.stdout)
    for command in (["preview", "-o", str(tmp_path / "fast.png")],
                    ["convert", "-o", str(tmp_path / "out.nc")]):
        result = shell(command[0], str(fast), *command[1:])
        assert result.returncode == 0, result.stderr
        assert re.search(pattern, result.stderr), command
    info = shell("info", str(fast))
    assert re.search(pattern, info.stdout)


def test_a_profile_feed_of_100_mm_s_is_said_by_plot(tmp_path, shell):
    profile = tmp_path / "fast.toml"
    profile.write_text("[machine]\nfeed_mm_s = 100\n")
    result = shell("plot", "samples/led-blinker.gbr", "--mode", "centre", "--yes",
                   "--port", "sim://?speed=0", "--profile", str(profile))
    assert result.returncode == 0, result.stderr
    assert ("warning: the profile's feed_mm_s = 100 mm/s (6000 mm/min) is above the warning "
            "feed 6.25 mm/s (375 mm/min, feed_warn_mm_s in the profile)") in result.stdout


def test_getg_in_the_console_says_the_feed_warning(home, fast):  # noqa: F811
    with console_in_thread(home) as user:
        user.line(f"getg {fast}")
        user.expect(r"use these offsets\? \[Y/n\]")
        user.line("y")
        user.expect(r"warning: .*fast\.nc:4: F600 is 10 mm/s \(600 mm/min\), above the "
                    r"warning feed 6\.25 mm/s")
        user.expect(r"process has finished")


def test_grbl_refuses_a_feed_above_its_max_rate_before_the_job(tmp_path, fast, shell):
    """GRBL as it comes ($110/$111 = 500 mm/min, 8.33 mm/s) would run F600 at its own
    limit without a word: plot refuses the fastest, F900 at line 6, naming the line,
    before any line is sent."""
    sys.path[:0] = [str(TESTS / "grbl")]
    from grbl_support import grbl_elf

    grbl_elf()                      # built (or skipped with the missing package) first
    url = "simavr://?firmware=grbl&realtime=0&$100=160&$101=160&$102=160"
    result = shell("plot", str(fast), "--port", url, "--yes")
    assert result.returncode == 1
    assert (f"{fast}:6: F900 is 15 mm/s (900 mm/min): refused: GRBL runs 0.0625 .. 8.33333 "
            "mm/s here (its $110/$111 max rates 500.000/500.000 mm/min)") in result.stderr
    assert "process has finished" not in result.stdout
