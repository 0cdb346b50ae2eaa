"""`getg --mill JOB BOARD` and `resume` in the console (console/mill.py, issue 35) on
stock GRBL 1.1h in simavr with its probe pin, as a user types them: the drilling asks
for its second bit as a pen change is asked and runs to its end; a cut-out stopped
with q mid-way is resumed and ends where the job's G-code ends (GRBL's own report)."""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.grbl.mill_job import mill_journal
from galileo_cnc.grbl.mill_plan import DRY_RUN_NAME, mill_program, mill_table
from galileo_cnc.stream.journal import FINISHED, Journal

from test_console import WAIT_S, console_in_thread, home  # noqa: F401  (the fixture)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "cli"))
from grbl_support import CONFIG, MM, grbl_elf  # noqa: E402
from mill_support import square_pad_board  # noqa: E402
from test_plot_mill import GRBL_URL, MILL_SET  # noqa: E402

#: the cut-out slower than MILL_SET's, so that q lands inside it
CUTOUT_SET = (*MILL_SET, "feed_mm_min=2000")
_STANDS = r"GRBL stands at X (\S+) Y (\S+) Z (\S+) mm \(work\)"


def mill_line(job: str, pairs, board: Path) -> str:
    return f"getg --mill {job} " + " ".join(f"--mill-set {pair}" for pair in pairs) + \
        f" {board}"


def wait_confirmed(job: str, lines: int) -> None:
    """Until the mill journal says GRBL confirmed `lines` lines of the `--mill job`."""
    journal = mill_journal()
    deadline = time.monotonic() + WAIT_S
    while True:
        entry = journal.load()
        if entry is not None and f"--mill {job}" in entry.board.get("name", "") and \
                entry.confirmed >= lines:
            return
        assert time.monotonic() < deadline, f"the job never reached line {lines}: {entry}"
        time.sleep(0.02)


def job_end(text: str) -> tuple[int, int, int]:
    """Where the G-code leaves the tool, in GRBL's steps: the last X, Y and Z it names
    (all absolute, work zero at GRBL's power-up)."""
    end = {}
    for line in text.splitlines():
        for axis, value in re.findall(r"([XYZ])(-?[\d.]+)", line.split("(")[0]):
            end[axis] = float(value)
    return tuple(round(end[axis] * MM) for axis in "XYZ")


def test_getg_mill_drills_asks_for_the_bit_and_resumes_a_stopped_cutout(home, tmp_path):  # noqa: F811
    grbl_elf()                      # built (or skipped with the missing package) first
    board = square_pad_board(tmp_path / "board")
    with console_in_thread(home, GRBL_URL, CONFIG) as user:
        user.expect(r"")
        assert "connected to GRBL 1.1h" in user.screen.text

        # ---- the drilling: planned, summed up, confirmed; the bit change asked
        user.line(mill_line("drill", MILL_SET, board))
        user.expect(r"board \(--mill drill\): 3 holes and slots with 0\.8, 1 mm bits, "
                    r"1 bit change")
        user.expect(r"run the mill job\? \[Y/n\]")
        user.line("")
        user.expect(r"paused for a bit change: put in the 1\.000 mm bit, then press "
                    r"Enter \(q stops\)")
        user.line("")
        user.expect(r"paused \(M0\): PROBE: clip the probe to the 1\.000 mm bit")
        user.line("")
        user.expect(r"paused \(M0\): PROBE DONE")
        user.line("")
        done = user.expect(r"process has finished in .*; " + _STANDS)
        assert done.groups() == ("3.000", "7.000", "1.000")    # the last hole, tool up
        user.expect(r">>")

        # ---- the cut-out, stopped with q once it cuts, then resumed to its end
        user.line(mill_line("cutout", CUTOUT_SET, board))
        user.expect(r"run the mill job\? \[Y/n\]")
        user.line("")
        user.expect(r"\(q (or Ctrl-C )?stops")      # the bar: its title is the board
        wait_confirmed("cutout", 20)        # GRBL cuts the outline's first edges
        user.type("q")
        stopped = user.expect(r"job stopped after (\d+) of (\d+) G-code lines: stopped by "
                              r"the user")
        user.expect(r"type resume to continue it")
        user.expect(r">>")
        user.line("resume")
        user.expect(r"continue the mill job\? \[Y/n\]")
        user.line("")
        user.expect(r"GRBL kept its position since the job stopped")
        finished = user.expect(r"process has finished in .*; " + _STANDS)
        user.expect(r">>")
        user.line("resume")                 # nothing is left
        user.expect(r"no interrupted GRBL job to resume")
    confirmed, total = (int(n) for n in stopped.groups())
    assert 0 < confirmed < total, stopped.group(0)
    mill = MillConfig.from_table(mill_table(list(CUTOUT_SET)), "--mill-set")
    program, _, _ = mill_program(str(board), "cutout", mill)
    assert tuple(round(float(v) * MM) for v in finished.groups()) == job_end(program.text)
    assert "Traceback" not in user.screen.text


def test_getg_mill_on_sim_is_a_dry_run_plotted_as_getg_plots(home, tmp_path):  # noqa: F811
    """On sim:// (no G-code) `getg --mill all` plans the job, says it is a dry run,
    lists the M0 pauses it will not wait for, then plots the dry run's G-code through
    getg's own questions; the journal keeps it for `resume`."""
    board = square_pad_board(tmp_path / "board")
    mill = MillConfig.from_table(mill_table(list(MILL_SET)), "--mill-set")
    program, _, _ = mill_program(str(board), "all", mill)
    changes = program.text.count("(TOOL CHANGE: put in the ")
    with console_in_thread(home) as user:                       # sim://: no G-code
        user.line(mill_line("all", MILL_SET, board))
        user.expect(r"note: sim://\S* runs galileo-cnc firmware, not G-code: a dry run")
        user.expect(r"use these offsets\? \[Y/n\]")
        listed = re.findall(r"M0 at [^\n]+?:\d+: TOOL CHANGE: put in the [\d.]+ mm (?:bit|end mill|V-bit)",
                            user.screen.text)
        user.line("")
        user.expect(r"process has finished")
        user.expect(r">>")
        user.line(f"getg --accept-shorts {board}")              # a mill option alone
        user.expect(r"getg: --mill-set, --accept-shorts and --drill-order go with --mill")
        user.expect(r">>")
    assert changes >= 2 and len(listed) == changes
    entry = Journal.default().load()
    assert entry.state == FINISHED and entry.source.endswith(DRY_RUN_NAME)
    assert "Traceback" not in user.screen.text
