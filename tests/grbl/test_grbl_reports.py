"""GRBL's replies parsed: status reports with fields in any order, WCO carried
over, $$ settings, $I build info, banner, ok/error/ALARM."""

from __future__ import annotations

import itertools

import pytest

from galileo_cnc.grbl.link import GrblLink, Reply
from galileo_cnc.grbl.reports import (
    GrblError, StatusTracker, banner_version, parse_build_info, parse_settings, parse_status,
)

FIELDS = ["WPos:1.000,-2.500,0.125", "Bf:15,127", "Ln:12", "FS:500,8000", "Pn:XZP",
          "WCO:0.000,1.551,-5.664", "Ov:120,50,100", "A:SF"]


@pytest.mark.parametrize("order", list(itertools.permutations(range(1, len(FIELDS))))[::997])
def test_status_fields_in_any_order(order):
    line = "<Hold:1|" + "|".join([FIELDS[0]] + [FIELDS[i] for i in order]) + ">"
    s = parse_status(line)
    assert (s.state, s.substate) == ("Hold", 1)
    assert s.wpos_nm == (1_000_000, -2_500_000, 125_000) and s.mpos_nm is None
    assert s.wco_nm == (0, 1_551_000, -5_664_000)
    assert (s.planner_free, s.rx_free, s.line_number) == (15, 127, 12)
    assert (s.feed, s.spindle, s.pins) == (500, 8000, "XZP")
    assert s.overrides == (120, 50, 100) and s.accessories == "SF"


def test_minimal_report_and_plain_feed_field():
    s = parse_status("<Idle|MPos:0.000,0.000,0.000|F:0>")
    assert s.state == "Idle" and s.substate is None and s.feed == 0 and s.spindle is None
    assert s.pins == "" and s.accessories is None and s.overrides is None


def test_wco_sent_now_and_then_is_carried_over():
    tracker = StatusTracker()
    first = tracker.update(parse_status("<Idle|MPos:10.000,5.000,0.000|FS:0,0|WCO:2.000,1.000,0.000>"))
    assert first.wpos_nm == (8_000_000, 4_000_000, 0)
    later = tracker.update(parse_status("<Run|MPos:12.500,5.000,0.000|FS:100,0>"))
    assert later.wpos_nm == (10_500_000, 4_000_000, 0)
    work = tracker.update(parse_status("<Run|WPos:1.000,1.000,1.000|FS:100,0>"))
    assert work.mpos_nm == (3_000_000, 2_000_000, 1_000_000)
    tracker.update(parse_status("<Idle|MPos:0.000,0.000,0.000|FS:0,0|Ov:100,100,100>"))
    assert tracker.accessories == ""        # Ov without A: nothing is on


def test_unknown_fields_kept_bad_ones_refused():
    s = parse_status("<Idle|MPos:0.000,0.000,0.000,1.000|Xx:7>")
    assert s.unknown == {"Xx": "7"} and len(s.mpos_nm) == 4
    with pytest.raises(GrblError, match="Bf"):
        parse_status("<Idle|MPos:0.000,0.000,0.000|Bf:x,1>")
    with pytest.raises(GrblError, match="without a position"):
        parse_status("<Idle|FS:0,0>")


def test_banner_build_info_and_settings():
    assert banner_version("Grbl 1.1h ['$' for help]") == "1.1h"
    assert banner_version("Grbl 0.9j ['$' for help]") == "0.9j"
    assert banner_version("galileo-cnc 1") is None
    info = parse_build_info(["[VER:1.1h.20190830:my plotter]", "[OPT:V,15,128]"])
    assert (info.version, info.options, info.planner_blocks, info.rx_buffer_bytes,
            info.user_text) == ("1.1h.20190830", "V", 15, 128, "my plotter")
    lines = [f"${n}=0" for n in (13, 20, 22)] + \
        [f"${n}=250.000" for n in (100, 101, 102)] + \
        [f"${n}=500.000" for n in (110, 111, 112, 120, 121, 122)] + \
        ["$130=200.000", "$131=150.500", "$132=-0.001"]
    settings = parse_settings(lines)
    assert settings.steps_per_mm_text(1) == "250.000"
    assert settings.max_travel_nm(1) == 150_500_000 and settings.max_travel_nm(2) == -1000
    assert not settings.soft_limits and not settings.homing and not settings.report_inches
    assert settings.describe(100).startswith("$100=250.000  X-axis travel resolution")
    with pytest.raises(GrblError, match=r"\$130"):
        parse_settings(lines[:-3])


class _Lines:
    """Just enough of a serial port for classify()."""
    timeout = 0.0


def test_replies_and_alarms_classified():
    link = GrblLink(_Lines())
    assert link.classify("ok") == Reply(True)
    assert link.classify("error:33") == Reply(False, 33)
    assert "Motion command target is invalid" in Reply(False, 33).text
    assert link.classify("[MSG:Caution: Unlocked]") == "[MSG:Caution: Unlocked]"
    assert link.messages == ["[MSG:Caution: Unlocked]"]
    with pytest.raises(GrblError, match="ALARM:2: Soft limit") as raised:
        link.classify("ALARM:2")
    assert raised.value.alarm and raised.value.code == 2 and link.alarms == [2]
