"""The generated GRBL texts match GRBL's own doc/csv, and read as GRBL words them."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from galileo_cnc.grbl import codes, firmware, gen_codes
from galileo_cnc.grbl.reports import alarm_text, error_text


def csv_dir() -> Path:
    path = firmware.source_dir() / "doc" / "csv"
    if not path.is_dir():
        message = f"GRBL 1.1h source not found at {path.parent.parent}"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return path


def test_generated_module_matches_the_csv():
    assert Path(codes.__file__).read_text(encoding="utf-8") == gen_codes.render(csv_dir())


def test_tables_cover_grbl_1_1h_codes():
    # GRBL 1.1h numbers its errors 1-17 and 20-38 (18, 19 were never used)
    assert sorted(codes.ERRORS) == [*range(1, 18), *range(20, 39)]
    assert sorted(codes.ALARMS) == list(range(1, 11))
    assert {0, 13, 20, 22, 100, 110, 120, 130} <= set(codes.SETTINGS)


def test_texts_as_grbl_words_them():
    assert error_text(20).startswith("error:20: Unsupported command (")
    assert error_text(33) == "error:33: Invalid gcode ID:33 (Motion command target is invalid.)"
    assert alarm_text(3).startswith("ALARM:3: Abort during cycle (")
    assert error_text(250) == "error:250: unknown GRBL error"
