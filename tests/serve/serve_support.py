"""A `galileo-cnc serve` server in the test's thread: the real service over a real
machine (sim:// unless a test names another port), the real uvicorn on a free port
(`serving`, and conftest.py's `served` fixture on the instant sim://)."""

from __future__ import annotations

import shutil
import time
from contextlib import contextmanager
from pathlib import Path

import httpx

from galileo_cnc.backends import open_machine
from galileo_cnc.config.profile import load_profile
from galileo_cnc.serve.server import WebServer
from galileo_cnc.serve.service import MachineService

from boards import make_board

GERBER = (b"%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.500000*%\nD10*\nX0Y0D02*\n"
          b"X5000000Y0D01*\nX5000000Y3000000D01*\nM02*\n")


@contextmanager
def serving(port: str, config=None, kind: str | None = None):
    """(server, service, client with the token) on `port`; `kind`: what answers
    there, known (not probed: seconds saved on a GRBL board)."""
    profile = load_profile(None, port=port)
    if config is not None:
        import dataclasses
        profile = dataclasses.replace(profile, config=config)
    service = MachineService(lambda: open_machine(port, profile, kind=kind))
    server = WebServer(service, "127.0.0.1", 0)
    try:
        server.start()
        client = httpx.Client(base_url=f"http://127.0.0.1:{server.port}", timeout=60,
                              headers={"authorization": f"Bearer {server.token}"})
        with client:
            yield server, service, client
    finally:
        server.shutdown()
        service.close()


def board_zip(tmp_path: Path) -> bytes:
    """tests/boards.py's board, zipped as a user uploads it."""
    folder = make_board(tmp_path / "board")
    return Path(shutil.make_archive(str(tmp_path / "board"), "zip", folder)).read_bytes()


def wait_for(client, ready, timeout_s: float = 30.0) -> dict:
    """The state once `ready(state)` holds (asked every 20 ms)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        state = client.get("/api/state").json()
        if ready(state):
            return state
        time.sleep(0.02)
    raise AssertionError(f"not reached: {state}")
