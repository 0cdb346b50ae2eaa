"""The pen as a servo on GRBL's spindle output: M3 S<n> puts PWM on D11, M5
stops it, and nothing moves until the dwell after each change has passed."""

from __future__ import annotations

import numpy as np

from galileo_cnc import job as J
from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.gcode import GrblPen, job_to_gcode
from galileo_cnc.grbl.stream import stream

from grbl_support import SCALE, check_trace, grbl_machine, positions

F_CPU = 16_000_000


def test_servo_pen_pwm_and_dwells_seen_on_the_pins():
    job = J.Job(source="test", offset_nm=(0, 0))
    for c in (J.Rapid(800, 0), J.PenDown(), J.LineTo(1600, 0), J.PenUp(), J.Rapid(0, 0)):
        job.add(c, J.NO_OP, 0)
    dwell_ms = 100
    lines = job_to_gcode(job, SCALE, GrblPen(servo=True, down_s=500, servo_dwell_ms=dwell_ms),
                         feed_steps_per_s=8000)
    with grbl_machine(extra_pins=(firmware.SPINDLE_PWM_PIN,)) as (board, link):
        stream(link, lines)
        board.stop()
    check_trace(positions(board), lines)
    cycle, pin, level = board.trace()
    cycle = cycle.astype(np.int64)
    pwm = pin == firmware.SPINDLE_PWM_PIN
    pwm_cycle, pwm_level = cycle[pwm], level[pwm]
    on, off = pwm_cycle[0], pwm_cycle[-1]
    assert pwm_level[0] == 1 and pwm_level[-1] == 0          # M3 starts it, M5 ends it
    x_steps = cycle[(pin == firmware.AXIS_PINS[0][0]) & (level == 1)]
    drawn = x_steps[(x_steps > on) & (x_steps < off)]
    assert len(drawn) == 800                                  # the pen-down line, whole
    dwell_cycles = dwell_ms * F_CPU // 1000
    assert drawn[0] - on >= dwell_cycles                      # the servo had its time
    after = x_steps[x_steps > off]
    assert len(after) == 1600 and after[0] - off >= dwell_cycles
    # S500 of $30 = 1000: half duty
    highs = np.diff(pwm_cycle)[pwm_level[:-1] == 1].sum()
    assert abs(highs / (off - on) - 0.5) < 0.01
