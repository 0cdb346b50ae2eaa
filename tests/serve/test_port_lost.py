"""A job survives the page, not its port (issue 34): a port that dies mid-job stops it
with a resumable journal; the state offers `resume`, which opens the port again and
finishes the job, every step of it as if it had never stopped."""

from __future__ import annotations

import httpx

from galileo_cnc.backends import open_machine
from galileo_cnc.backends.galileo import GalileoMachine
from galileo_cnc.config.profile import load_profile
from galileo_cnc.machine import simulate
from galileo_cnc.serve.server import WebServer
from galileo_cnc.serve.service import MachineService
from galileo_cnc.sim.simulator import named_machine
from galileo_cnc.transport.link import MachineLink
from galileo_cnc.transport.port import open_port

from faults import FaultyPort
from serve_support import GERBER, wait_for

URL = "sim://serve-lost?speed=0"        # a named machine keeps its power in the process


def test_a_lost_port_stops_the_job_and_resume_finishes_it(fresh_sim):
    profile = load_profile(None, port=URL)
    opened = []

    def open_it():
        opened.append(True)
        if len(opened) == 1:                # the cable is pulled after 12 lines
            link = MachineLink.attach(FaultyPort(open_port(URL, timeout=0.1), die_after=12),
                                      URL)
            return GalileoMachine(link)
        return open_machine(URL, profile)

    service = MachineService(open_it)
    server = WebServer(service, "127.0.0.1", 0).start()
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{server.port}", timeout=30,
                          headers={"authorization": f"Bearer {server.token}"}) as client:
            upload = client.post("/api/uploads", content=GERBER,
                                 headers={"x-filename": "lines.gbr"}).json()["id"]
            plan_id = client.post("/api/plans", json={"upload": upload}).json()["id"]
            job = service.get_plan(plan_id).planned.job
            assert client.post("/api/jobs", json={"plan": plan_id}).status_code == 202
            lost = wait_for(client, lambda s: s["activity"] is None and s["history"])
            assert lost["state"] == "port lost"
            assert lost["history"][-1]["result"].startswith("port lost")
            assert lost["resumable"] == "lines.gbr"            # the page offers resume
            assert client.post("/api/home").status_code == 409  # nothing else meanwhile
            assert client.post("/api/resume").status_code == 202
            done = wait_for(client, lambda s: s["activity"] is None and len(s["history"]) == 2
                         and s["state"] != "port lost")
            assert wait_for(client, lambda s: s["state"] == "idle")       # polled again
    finally:
        server.shutdown()
        service.close()
    assert len(opened) == 2
    assert done["history"][-1]["result"] == "finished" and done["resumable"] is None
    assert named_machine("serve-lost").trace().same_steps(simulate(job.commands))
