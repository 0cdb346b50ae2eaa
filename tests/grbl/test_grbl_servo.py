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
    assert len(x_steps) == 800 + 800 + 1600                   # out pen up, the line, back
    travel, drawn, after = x_steps[:800], x_steps[800:1600], x_steps[1600:]
    assert travel[-1] < on < drawn[0] and drawn[-1] < off <= after[0]
    dwell_cycles = dwell_ms * F_CPU // 1000
    assert drawn[0] - on >= dwell_cycles                      # the servo had its time
    # M5 comes after the line's last step (GRBL waits for its moves); the pause is
    # measured from that step, as the harness may write the PWM's last edges late
    assert after[0] - drawn[-1] >= dwell_cycles, (drawn[-1], off, after[0], board.summary)
    # S500 of $30 = 1000: half duty, while the line is drawn
    starts = np.clip(pwm_cycle[:-1], drawn[0], drawn[-1])
    ends = np.clip(pwm_cycle[1:], drawn[0], drawn[-1])
    highs = (ends - starts)[pwm_level[:-1] == 1].sum()
    assert abs(highs / (drawn[-1] - drawn[0]) - 0.5) < 0.01
