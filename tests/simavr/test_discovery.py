"""How `simavr://` finds the harness and the firmware outside a checkout (after
`pip install .`): $GALILEO_SIMAVR, PATH, the checkout; $GALILEO_FIRMWARE, the checkout.
A missing piece is named with the make command that builds it."""

from __future__ import annotations

import os
import stat

import pytest
import serial

from galileo_cnc.simavr import board


@pytest.fixture
def no_checkout(tmp_path, monkeypatch):
    """As after `pip install .`, run from a folder that is no checkout."""
    monkeypatch.setattr(board, "REPO_ROOT", tmp_path / "site-packages")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(board.HARNESS_ENV, raising=False)
    monkeypatch.delenv(board.FIRMWARE_ENV, raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    return tmp_path


def _executable(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("#!/bin/sh\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


def test_nothing_found_names_both_make_commands(no_checkout):
    assert board.checkouts() == [] and board.firmware_path() is None
    assert not board.harness_available()
    with pytest.raises(serial.SerialException) as missing:
        serial.serial_for_url("simavr://?realtime=0")
    text = str(missing.value)
    assert "no firmware ELF" in text and "`make -C firmware`" in text
    assert "galileo-simavr is not built" in text and "`make -C firmware/harness`" in text


def test_the_harness_on_path_and_the_firmware_by_environment(no_checkout, monkeypatch):
    harness = _executable(no_checkout / "bin" / board.HARNESS_NAME)
    assert board.harness_path() == harness and board.harness_available()
    elf = no_checkout / "galileo.elf"
    elf.write_bytes(b"\x7fELF")
    monkeypatch.setenv(board.FIRMWARE_ENV, str(elf))
    assert board.firmware_path() == elf
    other = _executable(no_checkout / "elsewhere" / "galileo-simavr")
    monkeypatch.setenv(board.HARNESS_ENV, str(other))        # the variable wins over PATH
    assert board.harness_path() == other


def test_a_checkout_in_the_current_folder_is_used(no_checkout):
    checkout = no_checkout
    _executable(checkout / board.HARNESS_RELATIVE)
    (checkout / board.FIRMWARE_RELATIVE).parent.mkdir(parents=True)
    (checkout / board.FIRMWARE_RELATIVE).write_bytes(b"\x7fELF")
    assert board.checkouts() == [checkout.resolve()]
    assert board.harness_path() == checkout.resolve() / board.HARNESS_RELATIVE
    assert board.firmware_path() == checkout.resolve() / board.FIRMWARE_RELATIVE
    assert os.access(board.harness_path(), os.X_OK)
