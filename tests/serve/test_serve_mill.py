"""A mill job through `galileo-cnc serve`'s API (issue 35) on stock GRBL 1.1h in simavr
with its probe pin: an uploaded board's drilling planned by the server ({"mill":
"drill"}), started, each M0 (the bit change, the probe clipped on and off) answered as
the page answers a pen change, stopped at the probe's clip, resumed (the tool change
done again) and run to the last hole; a mill plan without the token is refused; islands
closer than the tool's cut come back as the error."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import httpx

from galileo_cnc.grbl.mill_plan import mill_table
from galileo_cnc.simavr.grbl_firmware import ProbeSurface
from galileo_cnc.transport.discovery import GRBL

from serve_support import serving, wait_for

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "grbl"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "cli"))
from grbl_support import CONFIG, QUICK_ACCEL, SETTINGS, grbl_machine  # noqa: E402
from mill_support import square_pad_board  # noqa: E402
from test_plot_mill import MILL_SET  # noqa: E402


def test_serve_drills_a_board_on_grbl_answering_the_bit_change(fresh_sim, tmp_path):
    folder = square_pad_board(tmp_path / "board")
    board_zip = Path(shutil.make_archive(str(folder), "zip", folder)).read_bytes()
    with grbl_machine({**SETTINGS, **QUICK_ACCEL}, probe=ProbeSurface(z0=0)) as (board, link):
        link.port.close()                               # the server opens the board
        with serving(board.port, CONFIG, GRBL) as (server, service, client):
            upload = client.post("/api/uploads", content=board_zip,
                                 headers={"x-filename": "pads.zip"}).json()["id"]
            request = {"upload": upload, "mill": "drill", "mill_set": mill_table(list(MILL_SET))}
            # ---- no token, no plan
            bare = httpx.post(f"http://127.0.0.1:{server.port}/api/plans", json=request)
            assert bare.status_code == 401, bare.text
            # ---- a tool wider than the gap between the pads: refused, the places listed
            refused = client.post("/api/plans", json={
                "upload": upload, "mill": "isolate",
                "mill_set": {"tool": "endmill", "diameter_mm": 3}})
            assert refused.status_code == 422, refused.text
            error = refused.json()["error"]
            assert "closer than the 3 mm cut" in error, error
            assert "islands 0 and 1: 2.4 mm apart at X5.000 Y3.800 mm (work)" in error
            assert "accept_shorts: true mills the board with them joined" in error
            assert str(service.store.folder) not in error, error  # named as the page knows it
            # ---- the drilling: planned by the server, started, its pauses answered
            answer = client.post("/api/plans", json=request)
            assert answer.status_code == 201, answer.text
            plan = answer.json()
            assert plan["mill"] == "drill" and plan["preview"] is None
            assert plan["lines"][0] == ("pads.zip (mill drill): 3 holes and slots with 0.8, "
                                        "1 mm bits, 1 bit change")
            assert plan["pen_changes"] == 3             # the bit, the probe on, the probe off
            assert client.post("/api/jobs", json={"plan": plan["id"]}).status_code == 202
            # ---- stopped at the probe's clip, the tool change's second M0
            first = _answer_pauses(client, until=2)
            assert client.post("/api/stop").json() == {"stopping": True}
            stopped = wait_for(client, lambda s: s["activity"] is None)
            assert stopped["history"][-1]["result"].startswith("stopped: "), stopped
            assert stopped["resumable"] == "pads.zip (mill drill)"
            # ---- resumed: the tool change is done whole again, then the job to its end
            assert client.post("/api/resume").status_code == 202
            resumed = _answer_pauses(client)
            state = wait_for(client, lambda s: s["activity"] is None)
            record = state["history"][-1]
            assert record["file"] == "pads.zip (mill drill)"
            assert record["result"] == "finished", record
            assert state["resumable"] is None
            # the last hole (1.0 mm, at 3, 7) drilled, the tool up at the safe height
            assert state["position"] == [3.0, 7.0, 1.0]
    assert first[0] == "paused for a bit change: put in the 1.000 mm bit"
    assert first[1].startswith("paused (M0): PROBE: clip the probe to the 1.000 mm bit")
    assert resumed[:2] == first and len(resumed) == 3


def _answer_pauses(client, until: int | None = None) -> list[str]:
    """Each pause's prompt answered (go on) until the job ends, or until the `until`-th
    prompt, which is left open; returns the prompts' texts."""
    prompts = []
    while True:
        state = wait_for(client, lambda s: s["prompt"] or s["activity"] is None)
        prompt = state["prompt"]
        if prompt is None:
            return prompts
        assert prompt["kind"] == "pen"
        prompts.append(prompt["text"])
        if len(prompts) == until:
            return prompts
        assert client.post("/api/prompt", json={"id": prompt["id"],
                                                "answer": True}).status_code == 200
        wait_for(client, lambda s, i=prompt["id"]: (s["prompt"] or {}).get("id") != i)


def test_serve_mill_on_sim_is_a_dry_run_planned_and_plotted_as_a_plot(served, tmp_path):
    """On sim:// a mill plan is the dry run: a plot of the job's G-code with its preview,
    its lines the dry run's note, the job's summary and every bit change it will not
    wait for; started, it runs to the end with no prompt."""
    server, service, client = served
    folder = square_pad_board(tmp_path / "board")
    board_zip = Path(shutil.make_archive(str(folder), "zip", folder)).read_bytes()
    upload = client.post("/api/uploads", content=board_zip,
                         headers={"x-filename": "pads.zip"}).json()["id"]
    answer = client.post("/api/plans", json={"upload": upload, "mill": "all",
                                             "mill_set": mill_table(list(MILL_SET))})
    assert answer.status_code == 201, answer.text
    plan = answer.json()
    assert plan["options"]["dry_run"] is True and plan["options"]["mill"] == "all"
    lines = plan["lines"]
    assert lines[0].startswith("note: sim://") and "a dry run" in lines[0]
    assert lines[1].startswith("pads.zip (mill all): ")
    assert sum("TOOL CHANGE: put in the" in line for line in lines) == 3
    assert not any(str(service.store.folder) in line for line in lines)
    preview = client.get(plan["preview"])
    assert preview.status_code == 200 and "<svg" in preview.text
    assert client.post("/api/jobs", json={"plan": plan["id"]}).status_code == 202
    state = wait_for(client, lambda s: s["activity"] is None)
    assert state["prompt"] is None
    assert state["history"][-1]["result"] == "finished", state["history"][-1]
