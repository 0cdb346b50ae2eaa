"""The harness's probe pin (--probe) under stock GRBL 1.1h: G38.2 stops on the
surface the pin is driven from, to the step, flat and waved, and reports it in
[PRB:]; a probe that never touches ends in GRBL's ALARM:5."""

from __future__ import annotations

import math

import pytest

from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.simavr.grbl_firmware import ProbeSurface

from grbl_support import MM, QUICK_ACCEL, SETTINGS, grbl_machine

#: 0.25 mm of wave over 10 mm periods around -2 mm (machine steps from power-up)
SURFACE = ProbeSurface(z0=-2 * MM, amp=40, px=10 * MM, py=10 * MM)


def probe_at(link, x_mm: float, y_mm: float) -> tuple[float, float, float]:
    """G38.2 straight down over (x, y); the [PRB:x,y,z:1] GRBL reports, in mm."""
    link.command_checked("G0 Z-1.5")                     # 0.25 mm above the crest
    link.command_checked(f"G0 X{x_mm} Y{y_mm}")
    reply = link.command_checked("G38.2 Z-3 F1000")
    report = next(line for line in reply.lines if line.startswith("[PRB:"))
    coords, success = report[5:-1].split(":")
    assert success == "1", report
    return tuple(float(v) for v in coords.split(","))


def test_g38_2_stops_on_the_probe_surface_to_the_step():
    with grbl_machine({**SETTINGS, **QUICK_ACCEL}, probe=SURFACE) as (board, link):
        found = {}
        # the wave's crest, its trough, a slope, and flat z0 where sin(0) = 0
        for x_mm, y_mm in ((2.5, 2.5), (7.5, 2.5), (1.0, 4.0), (0.0, 3.0)):
            x, y, z = probe_at(link, x_mm, y_mm)
            assert (x, y) == (x_mm, y_mm)
            # descending one step at a time, GRBL stops on the first step at or
            # below the surface: floor of its height there
            expected = math.floor(SURFACE.height(x_mm * MM, y_mm * MM))
            found[x_mm, y_mm] = round(z * MM)
            assert found[x_mm, y_mm] == expected, (x_mm, y_mm, z * MM, expected)
        assert found[2.5, 2.5] - found[7.5, 2.5] == 80 and found[0.0, 3.0] == -2 * MM


def test_g38_2_that_never_touches_ends_in_alarm_5():
    with grbl_machine({**SETTINGS, **QUICK_ACCEL}, probe=ProbeSurface(z0=-4 * MM)) as (board, link):
        with pytest.raises(GrblError) as failed:
            link.command("G38.2 Z-1 F300")
        assert failed.value.alarm and failed.value.code == 5


def test_simavr_url_probe_option():
    from serial.serialutil import SerialException

    from galileo_cnc.simavr.protocol_simavr import parse_url
    url = parse_url("simavr://?firmware=grbl&probe=-320:40:1600:1600")
    assert url.probe == SURFACE
    assert url.probe.harness_args() == ("--probe", "19:-320:40:1600:1600",
                                        "--probe-dir-low-positive")
    assert parse_url("simavr://?firmware=grbl&probe=-320").probe.harness_args()[1] == "19:-320"
    with pytest.raises(SerialException, match="add firmware=grbl"):
        parse_url("simavr://?probe=-320")
    with pytest.raises(SerialException, match="Z0:AMP:PX:PY"):
        parse_url("simavr://?firmware=grbl&probe=-320:40")
