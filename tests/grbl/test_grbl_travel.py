"""The travel check: a job that would leave GRBL's travel ($130-$132, negative
machine space on a homed machine) is refused before a byte is sent, naming the
file line, the axis, the value and the limit."""

from __future__ import annotations

import pytest
from grbl_support import CONFIG, SCALE, SETTINGS, grbl_machine, positions

from galileo_cnc import job as J
from galileo_cnc.grbl.gcode import job_to_gcode, pen_from_config
from galileo_cnc.grbl.reports import GrblSettings
from galileo_cnc.grbl.stream import stream
from galileo_cnc.grbl.travel import TravelError, check_travel, first_overrun

HOMED = {20: "1", 22: "1", 130: "200.000", 131: "100.000", 132: "50.000"}


def settings(**extra):
    return GrblSettings({**HOMED, **{int(k[1:]): v for k, v in extra.items()}})


def constructed_job(x_far: int):
    """Work zero 10 mm inside the corner: a square, an arc, then X to x_far."""
    job = J.Job(source="test", offset_nm=(0, 0))
    for c in [J.Rapid(-800, -800), J.PenDown(), J.SetFeed(8000), J.LineTo(-1600, -800),
              J.LineTo(-1600, -1600), J.ArcTo(-800, -1600, 400, 0, cw=True),
              J.LineTo(x_far, -800), J.EndJob()]:
        job.add(c, J.NO_OP, 0)
    return job_to_gcode(job, SCALE, pen_from_config(CONFIG), feed_steps_per_s=8000)


WHERE = lambda command: f"job.gbr:{100 + command}"


def test_inside_passes_and_outside_names_line_axis_value_limit():
    s = settings()
    lines = constructed_job(-160)                    # X back to -1 mm work: inside
    assert first_overrun(lines, s, (0, 0, -10_000_000), (0, 0, -10_000_000)) is None
    lines = constructed_job(160)                     # X to +1 mm work = +1 mm machine
    over = first_overrun(lines, s, (0, 0, -10_000_000), (0, 0, -10_000_000), where=WHERE)
    assert over is not None and over.axis == 0 and over.machine_nm == 1_000_000
    assert lines[over.index].text.startswith("G1 X1 ")
    with pytest.raises(TravelError) as raised:
        check_travel(lines, s, (0, 0, -10_000_000), (0, 0, -10_000_000), where=WHERE)
    assert (f"job.gbr:{100 + lines[over.index].command}: G-code line {over.index + 1} takes "
            f"X to 1 mm (machine), outside GRBL's travel -200..0 mm ($130=200)") \
        in str(raised.value)


def test_work_offset_and_arc_bulge_count():
    s = settings()
    # work zero at machine (-199, -99, -10): the square at -5..-10 mm work leaves X
    over = first_overrun(constructed_job(-160), s, (-199_000_000, -99_000_000, -10_000_000),
                         (-199_000_000, -99_000_000, -10_000_000))
    assert over.axis == 0 and over.machine_nm == -204_000_000 and over.low_nm == -200_000_000
    # an arc whose ends are inside but whose bulge (Y -2.5 mm below its ends) is not
    lines = ["G21 G90", "G0 X0 Y-1", "G3 X5 Y-1 I2.5 J0 F600"]     # G3 bulges to -Y
    wco = (-50_000_000, -98_000_000, 0)
    over = first_overrun(lines, s, wco, wco)
    assert over.index == 2 and over.axis == 1 and over.machine_nm == -101_500_000
    assert first_overrun(lines[:2] + ["G2 X5 Y-1 I2.5 J0 F600"], s, wco, wco) is None


def test_unhomed_machine_is_not_checked():
    # without $20/$22 machine zero is wherever GRBL powered up: nothing to check
    check_travel(constructed_job(160), settings(**{"$20": "0", "$22": "0"}), (0, 0, 0), (0, 0, 0))


def test_refused_before_the_first_byte_in_simavr():
    homed = {**SETTINGS, 22: "1", 20: "1", 130: "200", 131: "100", 132: "50"}
    with grbl_machine(homed) as (board, link):
        link.command_checked("G53 G0 X-20 Y-20 Z-10")   # inside the negative space
        link.command_checked("G10 L20 P0 X0 Y0 Z0")     # work zero there
        link.wait_idle()
        sent = []
        write = link.port.write
        link.port.write = lambda data: (sent.append(data), write(data))[1]
        with pytest.raises(TravelError) as raised:
            # X +21 mm work = +1 mm machine
            stream(link, constructed_job(160 * 21), where=WHERE, travel_check=True)
        assert sent == [b"?"]           # only the status query: no job byte
        assert "takes X to 1 mm (machine), outside GRBL's travel -200..0 mm" in str(raised.value)
        link.port.write = write
        # the same job kept inside runs, and GRBL agrees: no alarm
        result = stream(link, constructed_job(-160), where=WHERE, travel_check=True)
        assert result.errors == [] and link.alarms == []
        board.stop()
    pos = positions(board)
    assert pos[:, 0].max() <= 0 and pos[:, 0].min() >= -200 * 160


def test_a_mill_job_is_checked_in_x_and_y_past_its_probes_and_z_zeroes():
    # a tool change's probe and re-zero, then a cut: Z is zeroed where the bit touches,
    # so only X and Y can be checked; a G92 of X is still refused as unknown
    s = settings()
    wco = (-20_000_000, -20_000_000, -10_000_000)
    lines = ["G21 G90", "G0 Z2", "G0 X1 Y1", "M0 (TOOL CHANGE)", "G38.2 Z-5 F60",
             "G92 Z1.6", "G0 Z2", "G0 X19 Y5", "G1 Z-0.1 F120", "G1 X21 Y5", "G92.1"]
    with pytest.raises(TravelError, match="uses G92: not checked"):
        first_overrun(lines, s, wco, wco)
    over = first_overrun(lines, s, wco, wco, axes=(0, 1))
    assert over.index == 9 and over.axis == 0 and over.machine_nm == 1_000_000
    assert first_overrun(lines[:9], s, wco, wco, axes=(0, 1)) is None
    with pytest.raises(TravelError, match="uses G92: not checked"):
        first_overrun(lines[:5] + ["G92 X0 Z1.6"], s, wco, wco, axes=(0, 1))
