"""GrblLink's reset handshake on a pseudo-terminal, with a GRBL that answers late
(a loaded host, a busy board) or not at all (its reset byte lost on the line): the
link waits for the answer to its own soft reset instead of resetting again at once,
sends the reset again only after a longer silence, and the ALARM:3 that comes before
the banner counts. And `wait_idle` with a GRBL that still reports Run after its
`G4 P0` was answered: watched on until Idle, not an error at a job's last line."""

from __future__ import annotations

import os
import pty
import re
import select
import threading
import time
from contextlib import contextmanager

import pytest
import serial

from galileo_cnc.grbl.link import RESET_AGAIN_S, SOFT_RESET, STATUS_QUERY, GrblLink
from galileo_cnc.grbl.reports import GrblError

BANNER = b"Grbl 1.1h ['$' for help]\r\n"


def grbl_on_a_pty(master: int, heard: list[bytes], answer: int, delay_s: float,
                  stop: threading.Event) -> None:
    """Reads what the link sends; `delay_s` after its reset number `answer` (the
    ones before are lost), writes ALARM:3 and the banner, as GRBL does after a reset
    while jogging."""
    resets, reset_at, answered = 0, None, False
    while not stop.is_set():
        ready, _, _ = select.select([master], [], [], 0.05)
        if ready:
            data = os.read(master, 64)
            heard.append(data)
            resets += data.count(SOFT_RESET)
            if reset_at is None and resets >= answer:
                reset_at = time.monotonic()
        if reset_at is not None and not answered and time.monotonic() - reset_at >= delay_s:
            os.write(master, b"ALARM:3\r\n" + BANNER)
            answered = True


@contextmanager
def scripted_grbl(script, *args):
    """(port, heard): a pyserial port on a pseudo-terminal whose other end
    `script(master, heard, *args, stop)` plays GRBL in a thread; `heard` gets what the
    link sends."""
    master, slave = pty.openpty()
    port = serial.Serial(os.ttyname(slave), 115200, timeout=0.1)
    heard: list[bytes] = []
    stop = threading.Event()
    grbl = threading.Thread(target=script, args=(master, heard, *args, stop), daemon=True)
    grbl.start()
    try:
        yield port, heard
    finally:
        stop.set()
        grbl.join()
        port.close()
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("answer, delay_s, resets", [
    (1, 1.6, 1),                    # late: waited for, not reset again
    (2, 0.1, 2),                    # the first reset lost: sent again after a while
])
def test_a_soft_reset_waits_for_its_answer_and_counts_the_alarm(answer, delay_s, resets):
    with scripted_grbl(grbl_on_a_pty, answer, delay_s) as (port, heard):
        link = GrblLink(port)
        began = time.monotonic()
        assert link.soft_reset(timeout_s=10.0) == "1.1h"
        took = time.monotonic() - began
        time.sleep(0.2)                       # anything more the link would send
    sent = b"".join(heard)
    # no `?` asking a silent board what it stands in: the reset was ours
    assert sent.count(SOFT_RESET) == resets and STATUS_QUERY not in sent
    assert link.alarms == [3] and link.boot_lines == ["ALARM:3"]
    if resets == 2:                           # not before the silence was long enough
        assert took >= RESET_AGAIN_S


def grbl_still_running_after_its_ok(master: int, heard: list[bytes], runs: int,
                                    late: bytes, early: bytes, moving: bool,
                                    stop: threading.Event) -> None:
    """Answers `G4 P0` with ok, then `early` at once, then its first `runs` status
    queries with Run (moving on a step each, or standing) and the ones after with
    Idle; `late` (a reply read late) goes out after the first Run report."""
    queries = 0
    while not stop.is_set():
        ready, _, _ = select.select([master], [], [], 0.05)
        if not ready:
            continue
        data = os.read(master, 64)
        heard.append(data)
        if b"G4 P0\n" in data:
            os.write(master, b"ok\r\n" + early)
        for _ in range(data.count(STATUS_QUERY)):
            queries += 1
            running = queries <= runs
            x = f"{1 + queries / 1000 if moving else 1:.3f}" if running else "2.000"
            os.write(master, f"<{'Run' if running else 'Idle'}|MPos:{x},0.000,0.000|FS:0,0>"
                     f"\r\n".encode())
            if queries == 1 and late:
                os.write(master, late)


def wait_idle_on(runs: int, late: bytes = b"", early: bytes = b"", moving: bool = True):
    """wait_idle against grbl_still_running_after_its_ok: (its status or the error it
    raised, the bytes the link sent, the link)."""
    with scripted_grbl(grbl_still_running_after_its_ok, runs, late, early,
                       moving) as (port, heard):
        link = GrblLink(port, reply_timeout_s=1.0)
        try:
            outcome = link.wait_idle()
        except GrblError as problem:
            outcome = problem
        time.sleep(0.1)
        pending = link.read_line(0.1)           # a reply left unread: out of step
    assert pending is None or pending.startswith("<"), pending
    return outcome, b"".join(heard)


@pytest.mark.parametrize("runs", [0, 1, 4])
def test_wait_idle_watches_a_board_still_running_after_its_ok_until_it_stands(runs):
    status, sent = wait_idle_on(runs)
    assert status.state == "Idle" and status.mpos_nm == (2_000_000, 0, 0)
    assert sent.count(STATUS_QUERY) > runs


@pytest.mark.parametrize("when", ["early", "late"])
def test_wait_idle_reads_a_late_ok_on_the_way_and_raises_a_late_refusal(when):
    # before the first report after the ok, or after a Run report; every reply read
    status, _sent = wait_idle_on(4, **{when: b"ok\r\n"})
    assert status.state == "Idle"
    problem, _sent = wait_idle_on(4, **{when: b"error:20\r\nok\r\n"})
    assert isinstance(problem, GrblError) and problem.code == 20
    assert "GRBL refused a line: error:20" in str(problem)


def test_wait_idle_names_a_board_that_reports_run_without_moving():
    problem, _sent = wait_idle_on(1000, moving=False)
    assert isinstance(problem, GrblError)
    assert re.search(r"GRBL reports Run but has not moved for \d+ s, at X 1\.000 Y 0\.000 "
                     r"Z 0\.000 mm", str(problem)), problem
