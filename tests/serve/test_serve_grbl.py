"""`galileo-cnc serve` drives stock GRBL 1.1h in simavr as it drives our machine (the
machine interface is shared; issue 34): through the API alone, a two-pen board is
uploaded, planned and started, the first pen answered, the job stopped with the stop
button at the second pen, resumed (GRBL kept its position: the job goes on from
there), and finished; where GRBL stands at the end is the job's end, the pen up, and
GRBL's journal says finished. Skips outside CI without simavr (grbl_support.py).
The board is opened as GRBL without the probe (tests/transport has it): 3 s saved."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from galileo_cnc.grbl.gcode import expected_end_steps, job_to_gcode, pen_from_config
from galileo_cnc.grbl.job import grbl_journal
from galileo_cnc.stream.journal import FINISHED
from galileo_cnc.transport.discovery import GRBL

from serve_support import serving, wait_for

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
from grbl_support import CONFIG, QUICK_ACCEL, SCALE, SETTINGS, grbl_machine  # noqa: E402

STEPS_PER_MM = 160
#: two short lines in two pens: the job asks for a pen twice, so it can be stopped
#: between drawing and more to draw
TWO_PENS = b"%FSLAX26Y26*%\n%MOMM*%\n" + b"".join(
    b"%%ADD1%dC,0.%d*%%\nD1%d*\nX1000000Y%d000000D02*\nX4000000Y%d000000D01*\n"
    % (pen, pen + 3, pen, pen + 1, pen + 1) for pen in range(2)) + b"M02*\n"


def _answer_pens(client, until: int = 0) -> list[str]:
    """Answers pen prompts until the `until`-th of the job (not answered) or the end;
    the apertures of those answered."""
    answered: list[str] = []
    while True:
        state = wait_for(client, lambda s: s["prompt"] or s["activity"] is None)
        prompt = state["prompt"]
        if prompt is None or len(answered) + 1 == until:
            return answered
        assert prompt["kind"] == "pen", prompt
        assert client.post("/api/prompt", json={"id": prompt["id"],
                                                "answer": True}).status_code == 200
        answered.append(re.search(r"aperture (D\d+)", prompt["text"])[1])
        wait_for(client, lambda s, i=prompt["id"]: (s["prompt"] or {}).get("id") != i)


def test_serve_runs_stops_and_resumes_a_job_on_grbl(fresh_sim):
    with grbl_machine({**SETTINGS, **QUICK_ACCEL}) as (board, setup_link):
        setup_link.port.close()                         # the server opens the board
        with serving(board.port, CONFIG, GRBL) as (server, service, client):
            state = client.get("/api/state").json()
            assert state["kind"] == "grbl" and "GRBL 1.1h" in state["machine"]
            upload = client.post("/api/uploads", content=TWO_PENS,
                                 headers={"x-filename": "two-pens.gbr"}).json()["id"]
            answer = client.post("/api/plans", json={"upload": upload, "mode": "centre"})
            assert answer.status_code == 201, answer.text
            plan = answer.json()
            assert plan["pen_changes"] == 2
            planned = service.get_plan(plan["id"]).planned
            lines = job_to_gcode(planned.job, SCALE, pen_from_config(CONFIG),
                                 feed_steps_per_s=CONFIG.feed_steps_per_s,
                                 flash_dwell_ms=CONFIG.flash_dwell_ms)
            end_mm = [s / STEPS_PER_MM for s in expected_end_steps(lines, SCALE)[-1]]

            assert client.post("/api/jobs", json={"plan": plan["id"]}).status_code == 202
            assert _answer_pens(client, until=2) == ["D10"]    # the second pen: stop there
            assert client.post("/api/stop").json() == {"stopping": True}
            stopped = wait_for(client, lambda s: s["activity"] is None)
            assert stopped["history"][-1]["result"].startswith("stopped: ")
            assert stopped["resumable"] == "two-pens.gbr"

            assert client.post("/api/resume").status_code == 202
            # GRBL's queue was dropped: the resume goes back over it, to the first pen
            assert _answer_pens(client) == ["D10", "D11"]
            done = wait_for(client, lambda s: s["activity"] is None and
                            s["state"] == "GRBL Idle")
            board.stop()
    assert [h["result"] for h in done["history"]][-1] == "finished"
    assert done["resumable"] is None and grbl_journal().load().state == FINISHED
    assert done["position"] == end_mm
