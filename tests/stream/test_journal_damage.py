"""A damaged journal is never half-believed: resuming from it could repeat or skip
moves. Each damage is refused naming the file and the key; a good journal written by
a real interrupted job still resumes (test_stream.py, test_cli.py)."""

import json
from dataclasses import asdict
from pathlib import Path

import pytest

from galileo_cnc.cli.main import main
from galileo_cnc.stream.journal import Journal, JournalEntry, JournalError

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr"


def good_entry() -> dict:
    entry = JournalEntry(source=str(SAMPLE), digest="0" * 64, offset_nm=(5_000_000, 4_000_000),
                         profile="", group=True, total=595, confirmed=20, first_index=0,
                         first_seq=1, state="interrupted", mode="ink", pens_nm=(400_000,))
    return json.loads(json.dumps(asdict(entry)))


def test_a_good_entry_reads_back(tmp_path):
    path = tmp_path / "journal.json"
    path.write_text(json.dumps(good_entry()))
    entry = Journal(path).load()
    assert entry.offset_nm == (5_000_000, 4_000_000) and entry.pens_nm == (400_000,)
    assert entry.confirmed == 20 and entry.state == "interrupted"


def test_a_journal_from_before_homing_reads_as_not_homed_and_a_reset_is_pending(tmp_path):
    path = tmp_path / "journal.json"
    older = good_entry()
    del older["homed"]                          # written before `plot --home` existed
    path.write_text(json.dumps(older))
    assert Journal(path).load().homed is False
    path.write_text(json.dumps({**good_entry(), "state": "reset", "homed": True}))
    entry = Journal(path).pending()
    assert entry is not None and entry.state == "reset" and entry.homed is True


def test_no_journal_is_no_job(tmp_path):
    assert Journal(tmp_path / "journal.json").pending() is None


@pytest.mark.parametrize("change, expected", [
    (dict(confirmed=float("nan")), "not JSON (NaN is not a number"),
    (dict(total=float("inf")), "not JSON (Infinity is not a number"),
    (dict(confirmed="20"), "confirmed must be an integer, got \"20\""),
    (dict(confirmed=20.0), "confirmed must be an integer, got 20.0"),
    (dict(group="yes"), "group must be true or false"),
    (dict(offset_nm=[1, 2, 3]), "offset_nm must be a list of 2 integers"),
    (dict(offset_nm=[1.5, 2]), "offset_nm must be a list of 2 integers"),
    (dict(state="done"), "state must be one of running, interrupted"),
    (dict(mode="fill"), "mode must be ink or centre"),
    (dict(pens_nm=[True]), "pens_nm must be a list of integers"),
    (dict(units="cm"), "units must be null, mm or in"),
    (dict(confirmed=595), "confirmed command 595 is outside the job's 595 commands"),
    (dict(confirmed=-2), "confirmed command -2 is outside"),
    (dict(speed=3), "unknown key 'speed'"),
    (dict(source=None), "source must be text, got null"),
    (dict(homed="yes"), "homed must be true or false"),
    (dict(homed=1), "homed must be true or false"),
])
def test_damaged_fields_are_named(tmp_path, change, expected):
    data = {**good_entry(), **change}
    path = tmp_path / "journal.json"
    path.write_text(json.dumps(data))          # json writes NaN and Infinity as such
    with pytest.raises(JournalError) as refused:
        Journal(path).pending()
    assert str(refused.value).startswith(f"{path}: damaged job journal: ")
    assert expected in str(refused.value)


@pytest.mark.parametrize("raw, expected", [
    (b"\xff\xfe{}", "not UTF-8 text (byte 0xff at offset 0)"),
    (b'{"source": "x"', "not JSON"),
    (b"[1, 2]", "expected a JSON object"),
    (b'{"source": "x"}', "missing digest, offset_nm"),
])
def test_unreadable_journals_are_named(tmp_path, raw, expected):
    path = tmp_path / "journal.json"
    path.write_bytes(raw)
    with pytest.raises(JournalError, match="damaged job journal") as refused:
        Journal(path).load()
    assert expected in str(refused.value)


def test_plot_resume_from_a_damaged_journal_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    (tmp_path / "journal.json").write_text(json.dumps({**good_entry(), "confirmed": "x"}))
    assert main(["plot", str(SAMPLE), "--resume", "--yes", "--port", "sim://?speed=0"]) != 0
    err = capsys.readouterr().err
    assert "damaged job journal: confirmed must be an integer" in err
    assert "Traceback" not in err
