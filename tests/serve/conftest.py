"""The `served` fixture: a server on the instant sim:// (serve_support.py)."""

from __future__ import annotations

import pytest

from serve_support import serving


@pytest.fixture
def served(fresh_sim):
    with serving("sim://?speed=0") as running:
        yield running
