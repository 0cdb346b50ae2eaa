"""grbl/mill_job.py's G-code side, no GRBL needed: the lines sent and the M0s' words,
where a resume goes on and the lead-in that brings GRBL there (the tool re-zeroed after
a tool change, with the probe or the touch-off), the rewind over GRBL's queue, the
probe's G92 from the touch, and what the front end is asked at a pause."""

from __future__ import annotations

import pytest

from galileo_cnc.grbl.mill_plan import mill_program
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.grbl.mill_job import (MillPause, mill_lead_in, mill_lines, mill_rewind,
                                       mill_state, restart_at, touch_zero)

from mill_support import square_pad_board

BASE = {"safe_height_mm": 1.0, "board_thickness_mm": 0.4, "breakthrough_mm": 0.1,
        "tab_height_mm": 0.2}


@pytest.fixture(scope="module")
def jobs(tmp_path_factory) -> dict:
    """probe True/False: (MillProgram, lines, pauses) of the test board's --mill all."""
    board = square_pad_board(tmp_path_factory.mktemp("lead-in") / "board")
    made = {probe: mill_program(str(board), "all",
                                MillConfig.from_table({**BASE, "probe": probe}))[0]
            for probe in (True, False)}
    return {probe: (program, *mill_lines(program.text)) for probe, program in made.items()}


def texts(lead) -> list[str]:
    return [line.text for line in lead]


def test_lines_drop_comments_and_keep_each_m0s_words(jobs):
    made, lines, pauses = jobs[True]
    assert all("(" not in line.text for line in lines)
    assert len(pauses) == 9 and all(lines[i].text == "M0" for i in pauses)
    raw = made.text.splitlines()
    first = min(pauses)
    assert raw[lines[first].command] == f"M0 ({pauses[first]})"
    assert pauses[first] == "TOOL CHANGE: put in the 0.800 mm bit"


def test_resume_after_a_tool_change_re_zeroes_the_bit_where_it_was_changed(jobs):
    made, lines, pauses = jobs[True]
    change = max(i for i, words in pauses.items() if words.startswith("TOOL CHANGE"))
    assert pauses[change].endswith("end mill")
    cut = next(i for i in range(change, len(lines)) if lines[i].text.startswith("G1 X"))
    start = cut + 3                                 # in the middle of the cut-out
    lead, asked = mill_lead_in(lines, pauses, start, made)
    at_change = mill_state(lines, pauses, change).axes
    state = mill_state(lines, pauses, start)
    rezero = texts(lines[change:next(i for i in range(change, len(lines))
                                     if lines[i].text.startswith("M3"))])
    assert texts(lead) == ["G21 G90 G17 G94 G54", "G92.1",
                           f"G0 X{at_change[0]} Y{at_change[1]}", *rezero,
                           f"G0 X{state.axes[0]} Y{state.axes[1]}", "M3 S10000", "G4 P2",
                           f"G1 Z{state.axes[2]} F60", f"G1 F{state.feed}"]
    assert rezero[2].startswith("G38.2") and rezero[3] == "G92 Z0"
    assert asked == {3: "TOOL CHANGE: put in the 0.800 mm end mill (the tool the job goes "
                        "on with)",
                     4: pauses[change + 1], 8: pauses[change + 5]}
    # inside the change (after its M0, up to its M3) the whole change is done again
    assert restart_at(lines, pauses, change + 3) == change
    assert restart_at(lines, pauses, start) == start


def test_resume_before_any_tool_change_goes_up_in_the_first_bits_frame(jobs):
    made, lines, pauses = jobs[False]
    start = next(i for i, line in enumerate(lines) if line.text.startswith("G1 X")) + 1
    lead, asked = mill_lead_in(lines, pauses, start, made)
    state = mill_state(lines, pauses, start)
    assert texts(lead)[:3] == ["G21 G90 G17 G94 G54", "G92.1", "G0 Z1"] and not asked
    assert texts(lead)[3:] == [f"G0 X{state.axes[0]} Y{state.axes[1]}", "M3 S10000",
                               "G4 P2", "G1 Z-0.1 F60", f"G1 F{state.feed}"]


def test_touch_off_is_done_again_after_a_tool_change(jobs):
    made, lines, pauses = jobs[False]
    change = min(i for i, words in pauses.items() if words.startswith("TOOL CHANGE"))
    start = change + 9                              # past the M3 and its dwell
    assert lines[change + 5].text.startswith("M3")
    lead, asked = mill_lead_in(lines, pauses, start, made)
    assert "G1 Z0 F60" in texts(lead)               # the collet drop onto the board
    assert [words.split(":")[0] for words in asked.values()] == [
        "TOOL CHANGE", "TOUCH OFF", "TOUCH OFF"]


def test_rewind_stops_at_a_line_answered_after_its_moves(jobs):
    made, lines, pauses = jobs[True]
    m0 = max(pauses)
    assert mill_rewind(lines, m0 + 30, 0, 20) == m0 + 11      # 20 moves back, no sync
    assert lines[m0 + 2].text == "G4 P2"
    assert mill_rewind(lines, m0 + 5, 0, 20) == m0 + 3        # the dwell ran
    assert mill_rewind(lines, m0 + 30, m0 + 25, 20) == m0 + 25


def test_the_g92_after_a_probe_names_the_touch_and_the_pause_prompt():
    assert touch_zero("G92 Z0", 1_250_000) == "G92 Z-1.25"
    assert touch_zero("G92 Z0.5", -6_250) == "G92 Z0.50625"
    assert MillPause(-1, "", 7, "TOOL CHANGE: put in the 1.000 mm bit").prompt == \
        "paused for a bit change: put in the 1.000 mm bit"
    assert MillPause(-1, "", 7, "PROBE DONE: take the clip away").prompt == \
        "paused (M0): PROBE DONE: take the clip away"
