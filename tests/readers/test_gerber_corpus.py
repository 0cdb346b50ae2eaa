"""The Gerber reader over the corpus of real files (corpus.py), and fuzzed versions of them."""

import warnings

import numpy as np

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from corpus import CORPUS, GERBER_CURATED, corpus_paths
from galileo_cnc.cli.info import summarize
from galileo_cnc.errors import GerberError
from galileo_cnc.plan.pipeline import load_artwork
from galileo_cnc.readers.gerber import read_gerber

READABLE = corpus_paths("real", "synthetic", "derived")
INVALID = corpus_paths("invalid")


@pytest.mark.parametrize("path", READABLE)
def test_every_corpus_file_reads(path):
    program = read_gerber(CORPUS / path)
    summary = summarize(load_artwork(program))
    assert summary["line_count"] > 0
    # Every drawing op was traced back to a line of the file.
    assert program.table[:, -2].min(initial=1) >= 1
    assert program.table[:, -2].max(initial=0) <= program.line_count


@pytest.mark.parametrize("path", INVALID)
def test_every_invalid_corpus_file_gives_a_gerber_error_with_a_line(path):
    with pytest.raises(GerberError) as caught:
        read_gerber(CORPUS / path)
    assert caught.value.pos.line >= 1
    assert f":{caught.value.pos.line}:" in str(caught.value)


def test_the_corpus_is_there():
    # the full corpus holds 493 readable files, the curated one in tests/corpus 355
    assert len(READABLE) >= (355 if GERBER_CURATED else 400) and len(INVALID) >= 2


# Small real files from different tools, cheap enough to fuzz many times.
FUZZ_SOURCES = sorted((p for p in READABLE if (CORPUS / p).stat().st_size < 6000),
                      key=lambda p: (CORPUS / p).stat().st_size)[::7][:25]

_mutation = st.tuples(st.sampled_from(["delete", "insert", "replace", "duplicate"]),
                      st.floats(0, 1), st.integers(1, 40),
                      st.text(alphabet="%*XYIJDGM0123456789.,-+$()/x\n ADFSLTOCRPAB", max_size=12))


def _mutate(text: str, mutations) -> str:
    for action, where, length, payload in mutations:
        at = int(where * len(text))
        if action == "delete":
            text = text[:at] + text[at + length:]
        elif action == "insert":
            text = text[:at] + payload + text[at:]
        elif action == "replace":
            text = text[:at] + payload + text[at + len(payload):]
        else:
            text = text[:at] + text[at:at + length] + text[at:]
    return text


@pytest.mark.skipif(not FUZZ_SOURCES, reason="corpus missing")
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(source=st.sampled_from(FUZZ_SOURCES or ["-"]), mutations=st.lists(_mutation, min_size=1, max_size=4))
def test_mutated_corpus_files_raise_only_gerber_errors(source, mutations):
    text = _mutate((CORPUS / source).read_text(errors="replace"), mutations)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no Python warnings leak out either
        try:
            program = read_gerber(source, text, min_run=1)
        except GerberError as error:
            assert error.pos.line >= 1 and error.pos.col >= 1
            # The statement-by-statement reader finds the same first error.
            with pytest.raises(GerberError) as reference:
                read_gerber(source, text, min_run=10**9)
            assert str(reference.value) == str(error)
            return
    summarize(load_artwork(program))
    assert np.array_equal(program.table, read_gerber(source, text, min_run=10**9).table)


@pytest.mark.parametrize("path", READABLE)
def test_vectorised_runs_give_the_same_program_as_statement_by_statement(path):
    text = (CORPUS / path).read_text(errors="replace")
    fast, reference = read_gerber(path, text, min_run=1), read_gerber(path, text, min_run=10**9)
    assert np.array_equal(fast.table, reference.table)
    assert [str(w) for w in fast.warnings] == [str(w) for w in reference.warnings]
    assert fast.metadata == reference.metadata
    assert fast.apertures == reference.apertures
