"""The fill's second process (plan/ink/background.py): the same answers as doing the
work here, errors brought back, and a fill that forks equal to one that does not."""

from __future__ import annotations

import os

import numpy as np
import pytest

from galileo_cnc.plan.ink import clip, fill
from galileo_cnc.plan.ink.background import Deferred

MM = 1_000_000


def child_pid_and(value):
    return os.getpid(), value


def fail(text):
    raise ValueError(text)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform: work runs inline")
def test_work_runs_in_another_process_and_comes_back_the_same():
    pid, value = Deferred(child_pid_and, {"rings": [np.arange(6).reshape(3, 2)]}).result()
    assert pid != os.getpid()
    assert np.array_equal(value["rings"][0], np.arange(6).reshape(3, 2))
    here, same = Deferred(child_pid_and, 7, fork=False).result()
    assert here == os.getpid() and same == 7


def test_an_error_in_the_work_is_raised_by_result():
    with pytest.raises(ValueError, match="no copper"):
        Deferred(fail, "no copper").result()


def test_cancel_ends_the_child_and_result_is_not_needed():
    work = Deferred(child_pid_and, 1)
    work.cancel()
    work.cancel()                       # twice is harmless
    assert work.result()[1] == 1        # asked anyway: done here


def ask(work):
    return os.getpid(), work.result()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform: work runs inline")
def test_a_forked_copy_of_its_owner_does_the_work_itself_and_leaves_the_child_alone():
    work = Deferred(child_pid_and, 5)
    asker, (worker, value) = Deferred(ask, work).result()
    assert value == 5 and worker == asker != os.getpid()     # done in the copy
    worker, value = work.result()                            # the owner's child is intact
    assert value == 5 and worker not in (os.getpid(), asker)


class Counted(fill.Deferred):
    """Deferred, noting each piece of work and whether it may fork."""

    made: list = []

    def __init__(self, fn, *args, fork=True):
        Counted.made.append((fn.__name__, args[3:5] if fn is fill._gaps else (), fork))
        super().__init__(fn, *args, fork=fork)


@pytest.mark.parametrize("share", [0.0, 0.3, 1.0])
def test_a_fill_with_its_gap_tests_forked_equals_one_without(share, monkeypatch):
    # a pour with sharp corners and holes (gaps at several depths), and pads
    pour = [[[0, 0], [12 * MM, 0], [6 * MM, 9 * MM]],
            [[4 * MM, 2 * MM], [5 * MM, 4 * MM], [6 * MM, 2 * MM]]]
    pads = [[[x, 10 * MM], [x + MM, 10 * MM], [x + MM, 11 * MM], [x, 11 * MM]]
            for x in range(0, 10 * MM, 2 * MM)]
    region = clip.union(pour + pads)
    monkeypatch.setattr(fill, "Deferred", Counted)
    monkeypatch.setattr(Counted, "made", [])
    monkeypatch.setattr(fill, "BACKGROUND_VERTICES", 0)
    monkeypatch.setattr(fill, "MAIN_GAP_SHARE", share)    # the deepest gaps found here
    forked = fill.fill_region(region, 300_000, 1_000)
    # per batch: depth 0's gap test while the deeper rings are made, then the other
    # depths' but the deepest (MAIN_GAP_SHARE) while the joins are made
    gap_work = [made for made in Counted.made if made[0] == "_gaps"]
    assert gap_work and all(fork for _name, _depths, fork in gap_work)
    assert gap_work[0][1] == (0, 1) and gap_work[1][1][0] == 1
    assert (gap_work[1][1][1] == 1) == (share == 1.0)        # 1: none of them there
    monkeypatch.setattr(fill, "BACKGROUND_VERTICES", 10 ** 12)
    inline = fill.fill_region(region, 300_000, 1_000)
    assert forked.gap_strokes == inline.gap_strokes > 0
    assert len(forked.paths) == len(inline.paths)
    assert all(np.array_equal(a, b) for a, b in zip(forked.paths, inline.paths))
    assert clip.area_nm2(forked.ink) == clip.area_nm2(inline.ink)


def sleep_then(seconds, value):
    import time

    time.sleep(seconds)
    return value


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform: work runs inline")
def test_a_result_never_asked_for_leaves_no_process_behind():
    work = Deferred(sleep_then, 60, "late")
    pid = work._pid
    assert pid is not None
    del work                                   # the coverage of a plan nobody printed
    with pytest.raises(ChildProcessError):     # killed and reaped: no child of that pid
        os.waitpid(pid, os.WNOHANG)


def test_a_fill_whose_later_batches_are_forked_equals_one_without(monkeypatch):
    # twelve pads and a pour with holes, filled in batches of a few islands: the
    # batches after the middle of the work go to a forked process
    pour = [[[0, 0], [12 * MM, 0], [6 * MM, 9 * MM]],
            [[4 * MM, 2 * MM], [5 * MM, 4 * MM], [6 * MM, 2 * MM]]]
    pads = [[[x, y], [x + MM, y], [x + MM, y + MM], [x, y + MM]]
            for x in range(0, 12 * MM, 2 * MM) for y in (10 * MM, 12 * MM)]
    region = clip.union(pour + pads)
    monkeypatch.setattr(fill, "Deferred", Counted)
    monkeypatch.setattr(Counted, "made", [])
    monkeypatch.setattr(fill, "BACKGROUND_VERTICES", 0)
    forked = fill.fill_region(region, 300_000, 1_000, batch_vertices=4)
    assert ("_fill_batches", (), True) in Counted.made
    monkeypatch.setattr(fill, "BACKGROUND_VERTICES", 10 ** 12)
    inline = fill.fill_region(region, 300_000, 1_000, batch_vertices=4)
    assert len(forked.recipes) == len(inline.recipes) > 6
    assert forked.rings == inline.rings and forked.gap_strokes == inline.gap_strokes
    assert len(forked.paths) == len(inline.paths)
    assert all(np.array_equal(a, b) for a, b in zip(forked.paths, inline.paths))
    assert all(np.array_equal(a, b) for a, b in zip(forked.coarse, inline.coarse))
    assert clip.area_nm2(forked.ink) == clip.area_nm2(inline.ink)
