"""GrblLink's reset handshake on a pseudo-terminal, with a GRBL that answers late
(a loaded host, a busy board): the link waits for the answer to its own soft reset
instead of resetting again, and the ALARM:3 that comes before the banner counts."""

from __future__ import annotations

import os
import pty
import select
import threading
import time

import serial

from galileo_cnc.grbl.link import SOFT_RESET, STATUS_QUERY, GrblLink

BANNER = b"Grbl 1.1h ['$' for help]\r\n"


def late_grbl(master: int, heard: list[bytes], delay_s: float, stop: threading.Event) -> None:
    """Reads what the link sends; after its first reset, answers after `delay_s`
    with ALARM:3 and the banner, as GRBL does after a reset while jogging."""
    answered = False
    reset_at = None
    while not stop.is_set():
        ready, _, _ = select.select([master], [], [], 0.05)
        if ready:
            data = os.read(master, 64)
            heard.append(data)
            if reset_at is None and SOFT_RESET in data:
                reset_at = time.monotonic()
        if reset_at is not None and not answered and time.monotonic() - reset_at >= delay_s:
            os.write(master, b"ALARM:3\r\n" + BANNER)
            answered = True


def test_a_late_answer_to_a_soft_reset_is_waited_for_and_its_alarm_counted():
    master, slave = pty.openpty()
    port = serial.Serial(os.ttyname(slave), 115200, timeout=0.1)
    heard: list[bytes] = []
    stop = threading.Event()
    grbl = threading.Thread(target=late_grbl, args=(master, heard, 1.6, stop), daemon=True)
    grbl.start()
    try:
        link = GrblLink(port)
        assert link.soft_reset(timeout_s=5.0) == "1.1h"
        time.sleep(0.2)                       # anything more the link would send
    finally:
        stop.set()
        grbl.join()
        port.close()
        os.close(master)
        os.close(slave)
    sent = b"".join(heard)
    # one reset, and no `?` asking a silent board what it stands in
    assert sent.count(SOFT_RESET) == 1 and STATUS_QUERY not in sent
    assert link.alarms == [3] and link.boot_lines == ["ALARM:3"]
