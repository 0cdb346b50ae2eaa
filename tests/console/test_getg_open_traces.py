"""getg on a board whose ink leaves trace pieces out: one summary, then a question
(issue 31, item 11), in the console on a pseudo-terminal as the user ran it."""

from __future__ import annotations

import re

from test_console import PEN_PROMPT, WAIT_S, console_on_a_pty, home  # noqa: F401  (home: a fixture)

HEADER = "%FSLAX46Y46*%\n%MOMM*%\nG75*\n"
PAIR = "X0Y{y}D02*\nX10000000Y{y}D01*\nX2000000Y{q}D02*\nX6000000Y{q}D01*\n"


def test_getg_sums_up_the_open_traces_and_asks_before_plotting(home, tmp_path):
    board = tmp_path / "tight.gbr"
    board.write_text(HEADER + "%ADD11C,0.15*%\nD11*\n" + "".join(
        PAIR.format(y=k * 2_000_000, q=k * 2_000_000 + 310_000) for k in range(3)) + "M02*\n")
    with console_on_a_pty(home) as (user, process):
        user.expect(r"connected to sim://")
        for answer in ("n", "y"):
            user.line(f"getg --pens 0.3 {board}")
            user.expect(r"use these offsets\? \[Y/n\]")
            user.line("y")
            user.expect(r"open traces: 3 trace pieces left out, 12 mm in all, the longest "
                        r"4 mm \(at .*tight\.gbr:9:1\)")
            user.expect(r"a pen of 0\.25 mm or thinner \(--pens\) would draw every trace")
            user.expect(r"plot it with these trace pieces left out\? \[y/N\]")
            user.line(answer)
            if answer == "n":                       # nothing plotted; then y: it runs
                user.expect(r"not plotted \(getg --pens MM,MM plans it for other pens\)")
        while user.expect(PEN_PROMPT + "|process has finished in").group(0) != \
                "process has finished in":
            user.type("\r")                       # the pen is in
        user.expect(r">>")
        user.type("\x04")                          # Ctrl-D leaves
        assert process.wait(WAIT_S) == 0
    text = user.screen.text
    assert "would join the ink of line" not in text          # no line per piece
    assert len(re.findall(r"process has finished", text)) == 1
