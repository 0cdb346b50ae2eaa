"""A `galileo-cnc serve` server in the test's thread: the real service over a real
machine (sim:// unless a test names another port), the real uvicorn on a free port."""

from __future__ import annotations

import shutil
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

from galileo_cnc.backends import open_machine
from galileo_cnc.config.profile import load_profile
from galileo_cnc.serve.server import WebServer
from galileo_cnc.serve.service import MachineService

from boards import make_board


@contextmanager
def serving(port: str, config=None):
    """(server, service, client with the token) on `port`."""
    profile = load_profile(None, port=port)
    if config is not None:
        import dataclasses
        profile = dataclasses.replace(profile, config=config)
    service = MachineService(lambda: open_machine(port, profile))
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


@pytest.fixture
def served(fresh_sim):
    with serving("sim://?speed=0") as running:
        yield running


def board_zip(tmp_path: Path) -> bytes:
    """tests/boards.py's board, zipped as a user uploads it."""
    folder = make_board(tmp_path / "board")
    return Path(shutil.make_archive(str(tmp_path / "board"), "zip", folder)).read_bytes()
