"""Liveness on stock GRBL 1.1h in simavr: a line's `ok` may take as long as the moves
ahead of it, so the stream asks `?` a few times a second and judges the board by
those answers (link.StatusWatch).

- A move longer than the link's reply timeout (made 4 s for the test, from 30: 40 mm
  at 5 mm/s, 8 s) then 40 short lines, plotted with `galileo-cnc plot` over
  `simavr://?firmware=grbl` in real time, runs to its last line and ends exactly on
  its last point (GRBL's status, its pins).
- A board frozen mid-job (SIGSTOP to the simulator: the pty stays open, nothing
  answers) is reported within 5 s of its last status answer, and `plot --resume`
  finishes the job on its last point.
- A line lost on the cable (GRBL stands Idle, answering `?`, the line never
  answered) is named after reply_timeout_s; a dwell longer than that is not.
- The rule itself, on short moves (paced to the wall clock: free-running simavr is
  faster than a board, or slower on a loaded host): `?` goes out while a line's `ok`
  is held back behind a long move, and a frozen board stops the stream with `acked`
  equal to the lines GRBL confirmed."""

from __future__ import annotations

import re
import threading
import time

import numpy as np
import serial

from galileo_cnc.cli import main as cli
from galileo_cnc.cli.plot import TextProgress
from galileo_cnc.config.profile import load_profile
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.grbl.gcode import GcodeLine, expected_end_steps, job_to_gcode, pen_from_config
from galileo_cnc.grbl.link import STATUS_QUERY, STATUS_SILENCE_S, GrblLink, position_mm
from galileo_cnc.grbl.stream import GrblSilentError, stream
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.stream.journal import FAILED, FINISHED, Journal

from faults import FaultyPort
from grbl_support import profile  # noqa: F401  (the fixture)
from grbl_support import (QUICK_ACCEL, SCALE, SETTINGS, check_trace, grbl_elf,
                          grbl_machine, wait_until_still)

MM = 1_000_000          # nm
STEP_NM = 6250          # 160 steps/mm
#: the product's rule: a board that stops answering is reported within this
REPORTED_WITHIN_S = 5.0
#: stock GRBL as a user starts it in simavr, paced to the wall clock (realtime=1 is
#: the URL's default); the steps/mm are the profile's, and X and Y's max rates its
#: travel feed (100 mm/s: plot refuses a feed above GRBL's $110/$111), acceleration
#: 1000 mm/s^2 (at the 10 GRBL ships with, the 40 zig-zags of 0.05 mm alone take 5.6 s)
REALTIME_URL = ("simavr://?firmware=grbl&$100=160&$101=160&$102=160&$110=6000&$111=6000"
                "&$120=1000&$121=1000&$122=1000")
EXIT_OK, EXIT_FAILED = 0, 1             # plot's exit codes (docs/grbl.md)



def gcode_file(folder, texts: list[str]) -> str:
    path = folder / "job.nc"
    path.write_text("\n".join(texts) + "\n")
    return str(path)


def planned(path: str, profile: str) -> list[GcodeLine]:
    """The G-code `plot` sends for the file (as grbl_support.planned_gcode does)."""
    config = load_profile(profile).config
    job = plan_file(path, config, options=PlanOptions()).job
    return job_to_gcode(job, SCALE, pen_from_config(config),
                        feed_steps_per_s=config.feed_steps_per_s,
                        flash_dwell_ms=config.flash_dwell_ms)


def reported_work_steps(out: str) -> tuple[int, ...]:
    """The end position plot prints, in steps (GRBL reports 3 decimals of a mm)."""
    match = re.search(r"GRBL stands at X (\S+) Y (\S+) Z (\S+) mm \(work\)", out)
    assert match, out[-500:]
    return tuple(round(float(text) * MM / STEP_NM) for text in match.groups())


def grbl_journal() -> Journal:
    return Journal(data_dir() / "journal-grbl.json")


class CountingPort:
    """The link's pyserial port, passed through, counting the `?` bytes written."""

    def __init__(self, port):
        self.port = port
        self.queries = 0

    def write(self, data: bytes) -> int:
        self.queries += data.count(STATUS_QUERY)
        return self.port.write(data)

    def __getattr__(self, name):
        return getattr(self.port, name)


def back_and_forth(start_mm: float, end_mm: float, feed: int, short: int) -> list[GcodeLine]:
    """One long line at `feed` mm/min, then `short` lines of 0.05 mm zig-zag."""
    step = 0.05 if end_mm < start_mm else -0.05
    texts = ["G21 G90 G94", f"G1 X{start_mm:g} Y0 F{feed}", f"G1 X{end_mm:g}"]
    texts += [f"G1 X{end_mm + step * (i + 1):.2f} Y{0.05 * ((i + 1) % 2):.2f}"
              for i in range(short)]
    return [GcodeLine(text, i) for i, text in enumerate(texts)]


def test_status_is_asked_while_an_ok_waits_and_a_silent_board_is_named():
    with grbl_machine(realtime=True) as (board, link):
        port = CountingPort(link.port)
        link.port = port
        # alive: the long line's successors wait for the planner; `?` keeps coming
        lines = back_and_forth(0, 20, 600, 30)     # 2 s, then 30 short
        acks: list[int] = []
        seen: list[tuple[int, str, int]] = []      # (lines acked, state, x nm)
        result = stream(link, lines, travel_check=False,
                        on_ack=lambda index, reply: acks.append(index),
                        on_status=lambda s: seen.append((len(acks), s.state, s.mpos_nm[0])))
        assert result.acked == len(lines) and acks == list(range(len(lines)))
        assert link.tracker.last.mpos_nm[:2] == (18_500_000, 0)     # 20 - 30 * 0.05
        # one ok held back over many status rounds, GRBL running the long line meanwhile
        waits = {}
        for acked, state, x in seen:
            waits.setdefault(acked, []).append((state, x))
        held, during = max(waits.items(), key=lambda item: len(item[1]))
        assert 2 < held < len(lines) and len(during) >= 5, waits
        running = [x for state, x in during if state == "Run"]
        assert len(running) >= 3 and running == sorted(running) and running[0] < running[-1]
        assert port.queries >= len(seen) >= result.statuses >= 5

        # silent: frozen in the middle of the way back
        acks.clear()
        frozen: list[float] = []

        def freeze_half_way(status) -> None:
            if not frozen and status.state == "Run" and status.mpos_nm[0] < 12 * MM:
                board.freeze()
                frozen.append(time.monotonic())

        back = back_and_forth(20, 0, 600, 30)
        try:
            stream(link, back, travel_check=False,
                   on_ack=lambda index, reply: acks.append(index), on_status=freeze_half_way)
        except GrblSilentError as silent:
            stopped = silent
        else:
            raise AssertionError("a frozen board was not noticed")
        took = time.monotonic() - frozen[0]
        board.thaw()
        board.stop()
    print(f"silent board reported {stopped.silent_s:.2f} s after its last status answer, "
          f"{took:.2f} s after the freeze")
    assert stopped.acked == len(acks) < len(back) and not stopped.alarm
    assert STATUS_SILENCE_S <= stopped.silent_s <= REPORTED_WITHIN_S
    assert stopped.status.state == "Run" and 0 < stopped.status.mpos_nm[0] < 12 * MM
    text = str(stopped)
    assert text.startswith(f"GRBL gave no answer to status queries for {stopped.silent_s:.1f} s")
    assert f"last reported at {position_mm(stopped.status)}" in text
    assert text.endswith("Once the board answers and stands still, resume continues "
                         "the job")



def test_a_lost_line_is_named_once_grbl_stands_idle_but_a_dwell_is_not():
    with grbl_machine(realtime=True) as (board, link):
        link.reply_timeout_s = 1.0
        # GRBL stands Idle through a dwell longer than that, answering `?`: no stall
        done = stream(link, [GcodeLine("G4 P1.5", 0), GcodeLine("G1 X1 F600", 1)],
                      travel_check=False)
        assert done.acked == 2 and link.tracker.last.mpos_nm[0] == 1 * MM
        # the last line never reaches GRBL: Idle, not moving, the line unanswered
        link.port = FaultyPort(link.port, drop_line=3)
        lines = [GcodeLine(f"G1 X{x}", i) for i, x in enumerate((2, 3, 4))]
        try:
            stream(link, lines, travel_check=False)
        except GrblSilentError as stuck:
            stopped = stuck
        else:
            raise AssertionError("a line lost on the way was waited for forever")
        board.stop()
    assert stopped.acked == 2 and stopped.silent_s < 1.0 and not stopped.alarm
    assert re.match(r"GRBL stood Idle for \d+ s without answering a line sent to it \(a "
                    r"byte lost on the line\?\), at X 3\.000 Y 0\.000", str(stopped)), stopped

def test_a_move_longer_than_any_timeout_plots_to_its_last_line(profile, tmp_path, capsys,
                                                               monkeypatch):
    """40 mm at 5 mm/s (8 s: GRBL holds back the next lines' `ok` all that time,
    twice the link's reply timeout, made 4 s here), then 40 lines of 0.05 mm, plotted
    in real time over the simavr:// URL; meanwhile the progress shows the head moving
    along the line, from GRBL's status answers."""
    grbl_elf()                      # built (or skipped with the missing package) first
    monkeypatch.setitem(GrblLink.__init__.__kwdefaults__, "reply_timeout_s", 4.0)
    shown = []                      # what plot's progress line was given
    original = TextProgress.__call__

    def recorded(self, progress):
        shown.append(progress)
        original(self, progress)

    monkeypatch.setattr(TextProgress, "__call__", recorded)
    texts = ["G21 G90", "G0 X0 Y0", "G1 X40 Y0 F300"]
    texts += [f"G1 X{40 - 0.05 * (i + 1):.2f} Y{0.05 * ((i + 1) % 2):.2f}" for i in range(40)]
    path = gcode_file(tmp_path, texts)
    trace_file = tmp_path / "grbl.npz"
    began = time.monotonic()
    code = cli.main(["plot", path, "--port", REALTIME_URL, "--yes", "--profile", profile,
                     "--trace", str(trace_file)])
    took = time.monotonic() - began
    out, err = capsys.readouterr()
    with capsys.disabled():
        print(f"\nthe 8 s line and 40 short ones plotted in {took:.1f} s")
    assert code == EXIT_OK, err + out[-800:]
    lines = planned(path, profile)
    assert sum(1 for line in lines if line.text.startswith("G1 X")) == 41
    assert "process has finished" in out and "no answer" not in out + err
    assert "ALARM" not in out + err and "error" not in out + err
    assert f"{len(lines)}/{len(lines)} lines" in out
    end = expected_end_steps(lines, SCALE)[-1]
    assert end[:2] == (39 * 160, 1 * 160)       # the last point, the 1 mm margin added
    assert reported_work_steps(out) == end          # GRBL's own status at the end
    trace = Trace.load(trace_file)                  # and its step pins
    assert trace.final_position == end == tuple(trace.displacement())
    pos = trace.positions()
    last_of_tick = np.r_[trace.tick[1:] != trace.tick[:-1], True]
    checked = check_trace(np.vstack([np.zeros((1, 3), np.int64), pos[last_of_tick]]), lines)
    assert checked["motions"] == sum(1 for line in lines if line.text.startswith(("G0", "G1")))
    # while the long line ran, its `ok` long given, the status answers moved the head
    # along it (X rising, Y 1 mm) and counted the ETA down with no new line confirmed
    along = [p for p in shown if p.position_nm is not None and p.position_nm[1] == 1 * MM
             and 2 * MM < p.position_nm[0] < 38 * MM]
    assert len({p.confirmed for p in along}) <= 3 and len(along) >= 25, len(along)
    xs = [p.position_nm[0] for p in along]
    assert xs == sorted(xs) and xs[-1] - xs[0] > 25 * MM
    assert along[-1].eta_s < along[0].eta_s
    assert shown[-1].position_nm[:2] == (39 * MM, 1 * MM)


def test_a_board_that_stops_answering_is_reported_and_the_job_resumes(profile, tmp_path,
                                                                       capsys):
    """The board freezes mid-job (SIGSTOP to the simulator, the pty open): the plot
    stops within 5 s of GRBL's last status answer, saying so, with the journal on the
    last confirmed line; thawed and at rest, `plot --resume` finishes the job."""
    # 50 mm/s and QUICK_ACCEL: about 0.07 s a line, some 4 s of moves in all; the half
    # left when the board freezes still outlasts the watcher's look at the journal
    texts = ["G21 G90", "G0 X0 Y0", "G1 X2.5 Y0 F3000"]
    texts += [f"G1 X{2.5 * (i % 2):.1f} Y{0.5 * (i + 1):.1f}" for i in range(50)]
    path = gcode_file(tmp_path, texts)
    lines = planned(path, profile)
    pen = pen_from_config(load_profile(profile).config)
    with grbl_machine({**SETTINGS, **QUICK_ACCEL, 10: "3"}, realtime=True) as (board, link):
        link.port.close()
        frozen: list[float] = []
        done = threading.Event()

        def freeze_mid_job() -> None:
            """Freezes the board once GRBL confirmed half the job (journal: 0.25 s)."""
            while not done.is_set():
                try:
                    entry = grbl_journal().load()
                except Exception:           # being replaced as it is read
                    entry = None
                if entry is not None and entry.confirmed >= len(lines) // 2:
                    board.freeze()
                    frozen.append(time.monotonic())
                    return
                time.sleep(0.05)

        watcher = threading.Thread(target=freeze_mid_job, daemon=True)
        watcher.start()
        try:
            code = cli.main(["plot", path, "--port", board.port, "--yes", "--profile", profile])
            ended = time.monotonic()
        finally:
            done.set()
            watcher.join()
        out, err = capsys.readouterr()
        assert frozen, "the job ended before the board was frozen"
        board.thaw()
        stopped = grbl_journal().load()
        silent = re.search(r"no answer to status queries for (\d+\.\d) s", out + err)
        with capsys.disabled():
            print(f"\nfrozen at line {stopped.confirmed + 1} of {len(lines)}: reported "
                  f"{ended - frozen[0]:.2f} s after the freeze, {silent and silent[1]} s "
                  f"after GRBL's last status answer")
        assert code == EXIT_FAILED and silent, out[-800:] + err
        assert STATUS_SILENCE_S <= float(silent[1]) <= REPORTED_WITHIN_S
        assert ended - frozen[0] <= REPORTED_WITHIN_S + 5.0      # a loaded host's margin
        assert "resume continues the job" in out + err
        # the last confirmed line named by its file line (a job streams in pieces)
        place = re.search(r"the last line GRBL confirmed came from (\S+):(\d+)\.", out + err)
        assert place and place[1] == path and 3 < int(place[2]) < len(texts)
        assert stopped.state == FAILED and "no answer to status queries" in stopped.reason
        assert len(lines) // 2 <= stopped.confirmed < len(lines) - 10

        # the user waits for the machine to stand, puts the pen on the work zero
        wait_until_still(board.port)
        with serial.Serial(board.port, 115200, timeout=0.2) as user_port:
            user = GrblLink.connect(user_port)
            user.command_checked("G90 G0 X0 Y0")
            user.command_checked(f"G1 Z{SCALE.mm(2, pen.down_z_steps)} F3000")
            user.wait_idle()
        code = cli.main(["plot", path, "--resume", "--yes", "--port", board.port,
                         "--profile", profile])
        out, err = capsys.readouterr()
        assert code == EXIT_OK, err + out[-800:]
        wait_until_still(board.port)
        with serial.Serial(board.port, 115200, timeout=0.2) as port:
            final = GrblLink(port).status()
        board.stop()
    assert "process has finished" in out
    # the resume names why it goes back over GRBL's queue: the silence that ended the job
    assert re.search(r"resuming at G-code line \d+ of \d+: the job failed \(GRBL gave no "
                     r"answer to status queries", out), out[-1500:]
    assert grbl_journal().load().state == FINISHED
    end = expected_end_steps(lines, SCALE)[-1]
    assert reported_work_steps(out) == end
    assert tuple(round(nm / STEP_NM) for nm in final.mpos_nm) == end     # G54 = 0
