"""The console's kept plan (console/plans.py): handed out again only for the same
file, bytes and all, planned the same way for the same machine."""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.console.plans import PlanCache
from galileo_cnc.machine.timing import job_timing
from galileo_cnc.plan.pipeline import PlanOptions, load_artwork, plan_file

BOARD = Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr"
TWO_PENS = MachineConfig().replace(pen_widths_mm=(0.3, 0.8))


def as_resume_asks(planned) -> dict:
    """The request stream/resume.py makes from the journal of this plan's job."""
    job = planned.job
    return dict(offset=tuple(planned.offset_nm), optimize=job.ordered,
                options=PlanOptions(mode=job.mode, file_order=not job.grouped,
                                    pens_nm=tuple(job.pens_nm), layers=tuple(job.layers),
                                    units=job.units))


def test_getg_again_and_resume_take_the_kept_plan(tmp_path):
    board = tmp_path / "board.gbr"
    shutil.copy(BOARD, board)
    plans = PlanCache()
    first = plans.plan_file(load_artwork(board), TWO_PENS)
    assert plans.plan_file(load_artwork(board), TWO_PENS) is first
    # resume: the journal's machine (read back from its TOML), offset, mode, pens, order
    journal_machine = MachineConfig.from_mapping(tomllib.loads(TWO_PENS.to_toml()), "journal")
    assert plans.plan_file(str(board), journal_machine, **as_resume_asks(first)) is first
    assert plans.reused == 2
    # and the kept plan is the plan: planned afresh, the same commands
    assert plan_file(str(board), TWO_PENS).job.commands == first.job.commands


def test_another_file_machine_pen_or_offset_is_planned_again(tmp_path):
    board = tmp_path / "board.gbr"
    shutil.copy(BOARD, board)
    plans = PlanCache()
    first = plans.plan_file(str(board), TWO_PENS)
    assert plans.plan_file(str(board), TWO_PENS.replace(feed_mm_s=3.0)) is not first
    assert plans.plan_file(str(board), TWO_PENS) is not first      # only the last is kept
    kept = plans.plan_file(str(board), TWO_PENS)
    assert plans.plan_file(str(board), MachineConfig()) is not kept            # one 0.4 mm pen
    kept = plans.plan_file(str(board), TWO_PENS)
    assert plans.plan_file(str(board), TWO_PENS, (0, 0)) is not kept
    kept = plans.plan_file(str(board), TWO_PENS)
    assert plans.plan_file(str(board), TWO_PENS, options=PlanOptions(mode="centre")) \
        is not kept


def test_a_file_that_changed_is_planned_again_even_for_resume(tmp_path):
    board = tmp_path / "board.gbr"
    shutil.copy(BOARD, board)
    plans = PlanCache()
    first = plans.plan_file(str(board), TWO_PENS)
    text = board.read_text()
    board.write_text(text.replace("M02*", "G04 edited*\nM02*"))
    again = plans.plan_file(str(board), TWO_PENS, **as_resume_asks(first))
    assert again is not first and plans.reused == 0


def test_the_timing_is_kept_with_the_job_for_its_machine():
    plans = PlanCache()
    job = plans.plan_file(str(BOARD), TWO_PENS).job
    timing = plans.timing(job, TWO_PENS)
    assert plans.timing(job, TWO_PENS) is timing
    assert list(timing.end_ticks) == list(job_timing(job.commands, TWO_PENS).end_ticks)
    slower = TWO_PENS.replace(feed_mm_s=2.0)
    assert plans.timing(job, slower).total_s > timing.total_s       # another machine
