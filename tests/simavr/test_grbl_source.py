"""simavr://?firmware=grbl after `pip install .`: the package runs from a venv's
site-packages, which holds no GRBL source; it is found in the checkout the user works
in, else the message names what is needed (issue 31, item 17)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

ASK = """
from galileo_cnc.errors import GalileoError
from galileo_cnc.simavr import grbl_firmware
try:
    print("found", grbl_firmware.source_dir())
except GalileoError as error:
    print("error", error)
"""


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The package copied as `pip install .` lays it out: site-packages/galileo_cnc,
    far from any checkout, and the script asking for the GRBL source beside it."""
    site = tmp_path_factory.mktemp("venv") / "lib" / "python3" / "site-packages"
    shutil.copytree(REPO / "galileo_cnc", site / "galileo_cnc",
                    ignore=shutil.ignore_patterns("__pycache__"))
    (site / "ask_grbl_source.py").write_text(ASK)
    return site


def _ask(site: Path, cwd: Path) -> str:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "GALILEO_GRBL_SOURCE")}
    # the script's folder, not the current one, goes on sys.path: the copy is imported
    result = subprocess.run([sys.executable, str(site / "ask_grbl_source.py")], cwd=cwd,
                            env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


def test_installed_package_finds_the_source_of_the_clone_it_runs_in(installed):
    assert (REPO / "third_party" / "grbl-1.1h" / "Makefile").is_file()
    answer = _ask(installed, REPO)
    assert answer == f"found {REPO / 'third_party' / 'grbl-1.1h'}"


def test_installed_package_run_elsewhere_says_what_it_needs(installed, tmp_path):
    answer = _ask(installed, tmp_path)
    assert answer.startswith("error simavr://?firmware=grbl builds stock GRBL 1.1h")
    assert "site-packages" in answer                # where it looked, said
    assert "GALILEO_GRBL_SOURCE" in answer and "third_party/grbl-1.1h" in answer
    assert "gcc-avr" in answer and "harness" in answer
