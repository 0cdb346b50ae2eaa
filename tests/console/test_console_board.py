"""A double-sided board at the console (issue 32): `getg BOARD` plots the top, asks
for the turn-over about the axis (named on the machine), plots the bottom mirrored
with the same offset; a `q` on the bottom and `resume` finish that side. On sim://
and on the firmware in simavr; the journal keeps which side it was."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.board_plan import BoardChoice, plan_board
from galileo_cnc.plan.pipeline import PlanOptions
from galileo_cnc.preview.render import LINE_COLOURS
from galileo_cnc.simavr.board import SimulatedBoard
from galileo_cnc.stream.journal import FINISHED
from galileo_cnc.stream.resume import position_after

from boards import make_board
from firmware_support import ELF, build_firmware, build_harness
from test_console import console_in_thread, home  # noqa: F401  (the fixture)

TWO_PENS = MachineConfig().replace(pen_widths_mm=(0.3, 0.8))

#: what a pen change says: the ink's pens, or an aperture's pen (centre mode)
PEN = r"insert (?:pen for aperture|the \d[\d.]* mm pen)"


def a_board_evening(user, board: Path, mode: str) -> dict:
    """getg BOARD: top, turn-over, bottom stopped with q at its last pen change, resume."""
    user.line(f"getg --mode {mode} {board}")
    user.expect(r"use these offsets\?")
    user.line("y")
    user.expect(r"top side, to be turned over about the vertical line X 6\.0000 mm "
                r"\(board\)")
    changes = int(user.expect(r"(\d+) pen changes?").group(1))
    for _ in range(changes):
        user.expect(PEN)
        user.type("\r")
    user.expect(r"process has finished")
    user.expect(r"bottom side, mirrored about the vertical line X 6\.0000 mm \(board\)")
    turn = user.expect(r"turn the blank over about the vertical line X (-?[\d.]+) mm \(work\) "
                       r"against the fence; plot the bottom side\?")
    user.line("y")
    changes = int(user.expect(r"(\d+) pen changes?").group(1))
    assert changes >= 2                       # the second one is after some ink
    for _ in range(changes - 1):
        user.expect(PEN)
        user.type("\r")
    user.expect(PEN)
    user.type("q")
    user.expect(r"job stopped after \d+ of \d+ commands.*type resume to continue it")
    user.line("resume")
    user.expect(r"continue the job\? \[Y/n\]")
    user.line("")
    user.expect(PEN)                          # the pen it stopped for first
    user.type("\r")
    user.expect(r"process has finished")
    return {"axis_on_machine_mm": float(turn.group(1))}


def bottom_job(board: Path, config: MachineConfig, mode: str):
    options = PlanOptions(mode=mode)
    top = plan_board(board, config, choice=BoardChoice(side="top"), options=options)
    bottom = plan_board(board, config, top.offset_nm, choice=BoardChoice(side="bottom"),
                        options=options)
    return top, bottom


def journal_of(home_dir: Path) -> dict:
    [path] = list(home_dir.rglob("journal*.json"))
    return json.loads(path.read_text())


def check_the_evening(home_dir: Path, board: Path, seen: dict, status, mode: str) -> None:
    top, bottom = bottom_job(board, TWO_PENS, mode)
    assert top.offset_nm == bottom.offset_nm                      # one offset
    assert seen["axis_on_machine_mm"] == pytest.approx(6 - top.offset_nm[0] / 1e6, abs=1e-3)
    assert status == ("idle", *position_after(bottom.job, len(bottom.job), TWO_PENS))
    entry = journal_of(home_dir)
    assert entry["state"] == FINISHED and entry["board"]["side"] == "bottom"
    assert Path(entry["source"]) == board.resolve()


def test_a_board_evening_on_sim(home, tmp_path):  # noqa: F811
    board = make_board(tmp_path / "board")
    with console_in_thread(home, config=TWO_PENS) as user:
        seen = a_board_evening(user, board, "ink")
        status = user.status()
    check_the_evening(home, board, seen, status, "ink")


def test_a_board_evening_on_the_firmware_in_simavr(home, tmp_path):  # noqa: F811
    build_firmware()
    build_harness()
    board = make_board(tmp_path / "board")
    with SimulatedBoard(ELF) as machine:
        with console_in_thread(home, machine.port, config=TWO_PENS) as user:
            # centre mode (an aperture's pen each, pads with holes as rings): the same
            # evening in less than half the machine time of the ink's
            seen = a_board_evening(user, board, "centre")
            status = user.status()
        machine.stop()
    check_the_evening(home, board, seen, status, "centre")


def test_getg_side_options_on_a_file_alone_are_refused(home, tmp_path):  # noqa: F811
    lone = make_board(tmp_path / "board") / "board-F_Cu.gbr"
    with console_in_thread(home) as user:
        user.line(f"getg --side bottom {lone}")
        user.expect(re.escape("are for a board (a folder, .zip or .gbrjob)"))


def test_a_one_sided_board_is_plotted_without_a_turn_over(home, tmp_path):  # noqa: F811
    board = make_board(tmp_path / "board")
    (board / "board-B_Cu.gbr").unlink()
    with console_in_thread(home) as user:
        user.line(f"getg {board}")
        user.expect(r"use these offsets\?")
        user.line("y")
        user.expect(r"top side, ")
        user.expect(r"process has finished")
        user.line("status")
        screen = user.expect(r"state \w+")
        assert "turn the blank over about the" not in user.screen.text[:screen.end()]


def test_getg_draws_the_outline_and_the_silk_after_the_copper(home, tmp_path):  # noqa: F811
    """`getg BOARD --outline --silk`: on each side the copper, then the outline and the
    silk, each after a pen change that names it; the silk off the copper is said in mm,
    the journal keeps both choices for resume, and the head ends where the plan of the
    bottom with both ends."""
    board = make_board(tmp_path / "board", silk=True)
    with console_in_thread(home) as user:
        user.line(f"getg --outline --silk {board}")
        user.expect(r"use these offsets\?")
        user.line("y")
        for side in ("top", "bottom"):
            user.expect(r"--silk: [\d.]+ mm of the silk (and \d+ dots? )?left out within "
                        r"0\.250 mm of copper")
            if side == "bottom":
                user.expect(r"plot the bottom side\?")
                user.line("y")
            user.expect(r"insert the 0\.4 mm pen")
            user.type("\r")
            user.expect(re.escape("insert the outline pen (0.4 mm)"))
            user.type("\r")
            user.expect(re.escape("insert the silk pen (0.4 mm)"))
            user.type("\r")
            user.expect(r"process has finished")
        status = user.status()
        # a picture of each side, as `preview` on the shell draws it
        pictures = tmp_path / "pictures"
        pictures.mkdir()
        user.line(f"preview --outline --silk {board} -o {pictures / 'board.svg'}")
        for side in ("top", "bottom"):
            user.expect(rf"{side} side, ")
            user.expect(re.escape(f"{pictures / f'board-{side}.svg'}: "))
        user.line(f"preview --side bottom --mode sideways {board}")
        user.expect(r"preview: unknown option --mode sideways \(preview \[--mode")
    for side in ("top", "bottom"):
        svg = (pictures / f"board-{side}.svg").read_text()
        for role in ("outline", "silk"):
            assert 'color="#%02x%02x%02x"' % LINE_COLOURS[role] in svg, role
    choice = BoardChoice(side="top", outline=True, silk=True)
    top = plan_board(board, MachineConfig(), choice=choice)
    bottom = plan_board(board, MachineConfig(), top.offset_nm,
                        choice=BoardChoice(side="bottom", outline=True, silk=True))
    plain = plan_board(board, MachineConfig(), top.offset_nm,
                       choice=BoardChoice(side="bottom"))
    assert len(bottom.job) > len(plain.job)
    assert status == ("idle", *position_after(bottom.job, len(bottom.job), MachineConfig()))
    entry = journal_of(home)
    assert entry["state"] == FINISHED and entry["board"]["side"] == "bottom"
    assert entry["board"]["outline"] is True and entry["board"]["silk"] is True
