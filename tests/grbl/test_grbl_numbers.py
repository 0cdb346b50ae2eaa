"""GRBL's number arithmetic mirrored: the mm text we send lands on the job's step."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st

from galileo_cnc.grbl.numbers import (
    GrblNumberError, decimal_text_to_nm, grbl_steps, lround_f32, mm_text, read_float,
    steps_per_mm_f32,
)


def test_read_float_is_grbls_float32_scaling():
    # digits as an integer, then *0.01 and *0.1 in float32 (nuts_bolts.c)
    assert read_float("1.005") == np.float32(np.float32(np.float32(1005) * np.float32(0.01))
                                             * np.float32(0.1))
    assert read_float("-12.5") == np.float32(-12.5)
    assert read_float("+3") == np.float32(3)
    # more than 8 digits: the rest are dropped, not rounded
    assert read_float("1.23456789") == read_float("1.2345678")
    assert read_float("123456789") == np.float32(123456780)
    with pytest.raises(ValueError):
        read_float("X")


def test_lround_halves_away_from_zero():
    assert [lround_f32(np.float32(v)) for v in (0.5, 1.5, 2.5, -0.5, -2.5, 2.49)] == \
        [1, 2, 3, -1, -3, 2]


@pytest.mark.parametrize("steps_per_mm", ["160", "250", "80", "78.740", "100.5", "3200"])
@given(steps=st.integers(-400_000, 400_000))
def test_mm_text_lands_on_the_step(steps_per_mm, steps):
    spm = steps_per_mm_f32(steps_per_mm)
    text = mm_text(steps, spm)
    assert grbl_steps(text, spm) == steps
    assert len(text.lstrip("-").replace(".", "").lstrip("0")) <= 8
    assert not text.startswith("-0") or steps < 0


def test_mm_text_is_short_and_exact_for_the_seed_machine():
    spm = steps_per_mm_f32("160")
    assert [mm_text(s, spm) for s in (0, 1, -1, 160, 1601, -32000)] == \
        ["0", "0.006", "-0.006", "1", "10.006", "-200"]


def test_a_step_no_text_can_reach_is_refused():
    # 10^8 steps at 1000 steps/mm needs 9 significant digits
    with pytest.raises(GrblNumberError, match="8 significant digits"):
        mm_text(123_456_789, steps_per_mm_f32("1000"))


def test_reported_mm_as_exact_nm():
    assert [decimal_text_to_nm(t) for t in ("-2.500", "1.551", "0.0006", "12", ".5")] == \
        [-2_500_000, 1_551_000, 600, 12_000_000, 500_000]
    with pytest.raises(ValueError):
        decimal_text_to_nm("1.2.3")
