"""A whole board milled on stock GRBL 1.1h in simavr with its probe pin (issue 35):
isolation, drilling with two bits and a bit change, the cut-out with tabs, every tool
change an M0 the operator answers and a G38.2 onto the simulated plate (the harness's
--probe, flat at work Z 0); then the same job stopped mid-way after a tool change and
resumed, and the steps of the two parts make the whole job: the first part is the whole
job's path up to the stop, the resumed part's path after its lead-in is the whole job's
tail from before the stop, the lead-in travels at the safe height, and both end on the
same step."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from galileo_cnc.backends.grbl import GrblMachine
from galileo_cnc.grbl.mill_plan import mill_program
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.travel import TravelError
from galileo_cnc.grbl.job import InterruptiblePort
from galileo_cnc.simavr.grbl_firmware import ProbeSurface

from mill_support import square_pad_board
from grbl_support import (MM, QUICK_ACCEL, SETTINGS, grbl_machine, positions_and_ticks,
                          settled_trace)

#: fast tools on a thin board: one cut-out pass, shallow drilling, high feeds
MILL = MillConfig.from_table({
    "probe": True, "safe_height_mm": 1.0, "feed_mm_min": 4000, "plunge_feed_mm_min": 2000,
    "board_thickness_mm": 0.4, "cutout_step_down_mm": 0.5, "breakthrough_mm": 0.1,
    "tabs": 2, "tab_height_mm": 0.2, "tab_width_mm": 1.0, "drills": [0.8, 1.0]})
#: the touch plate's top: where GRBL powers up, work Z 0 (G54 stays zero)
PLATE = ProbeSurface(z0=0)
SAFE_STEPS = MM                         # 1 mm


@pytest.fixture(scope="module")
def program(tmp_path_factory):
    board = square_pad_board(tmp_path_factory.mktemp("mill") / "board")
    made, notes, summary = mill_program(str(board), "all", MILL, accept_shorts=True)
    assert "3 tool changes" in summary
    # the spindle's 2 s to come up to speed is 6 s of the job's 8: 0.1 s here
    assert made.text.count("G4 P2\n") == 3
    return dataclasses.replace(made, text=made.text.replace("G4 P2\n", "G4 P0.1\n"))


class Operator:
    """Answers every pause at once; `stop_at`: stops the job once GRBL confirmed that
    G-code line (from the streaming thread, as a front end's q would)."""

    def __init__(self, machine: GrblMachine, stop_at: int | None = None):
        self.machine = machine
        self.stop_at = stop_at
        self.prompts: list[str] = []
        self.said: list[str] = []

    def say(self, text):
        self.said.append(text)

    def progress(self, p):
        if self.stop_at is not None and p.confirmed >= self.stop_at:
            self.stop_at = None
            self.machine.stop()

    def pen_change(self, change):
        self.prompts.append(change.prompt)

    def confirm(self, question):
        raise AssertionError(f"asked {question!r}: the position was kept")


def mill_machine(link) -> GrblMachine:
    link.port = InterruptiblePort(link.port)
    return GrblMachine(link, link.port, "simavr GRBL", MachineConfig(), None)


def board_kwargs():
    return {"probe": PLATE, "extra_pins": (firmware.SPINDLE_PWM_PIN,)}


def follow(a: np.ndarray, b: np.ndarray, backwards: bool = False) -> tuple[int, int]:
    """How far two step paths go together from their first rows (or back from their
    last): rows within one step on every axis, both advancing in order (GRBL may make
    a diagonal's X and Y steps in one interrupt or two: the paths are the same).
    Returns the rows of each followed together."""
    if backwards:
        a, b = a[::-1], b[::-1]
    i = j = 0
    while i < len(a) - 1 or j < len(b) - 1:
        options = [(max(abs(a[i + di] - b[j + dj])), -(di + dj), di, dj)
                   for di, dj in ((1, 1), (1, 0), (0, 1))
                   if i + di < len(a) and j + dj < len(b)]
        gap, _, di, dj = min(options)
        if gap > 1:
            break
        i, j = i + di, j + dj
    return i + 1, j + 1


def test_whole_board_then_stopped_and_resumed_make_the_same_steps(program, tmp_path,
                                                                  monkeypatch):
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    # $30: the spindle's top speed above the job's S10000, so M3 S10000 is a PWM on D11
    settings = {**SETTINGS, **QUICK_ACCEL, 30: "20000"}
    with grbl_machine(settings, **board_kwargs()) as (board, link):
        machine = mill_machine(link)
        operator = Operator(machine)
        job = machine.prepare_mill(program)
        result = machine.run_job(job, operator)
        assert result.completed, result
        whole = positions_and_ticks(settled_trace(board))[0]
        whole_prompts = operator.prompts
    # three tool changes, each asked and the probe clipped on and off
    assert [p for p in whole_prompts if p.startswith("paused for a bit change")] == [
        "paused for a bit change: put in the 0.800 mm bit",
        "paused for a bit change: put in the 1.000 mm bit",
        "paused for a bit change: put in the 0.800 mm end mill"]
    assert len(whole_prompts) == 9
    # each tool cut at its depth below the zero its probe found: the isolation
    # -0.1 mm, the drills -0.5 mm, the cut-out -0.4 mm (tabs -0.2 mm)
    assert {-16, -80, -64, -32} <= set(whole[:, 2].tolist())

    # stopped inside the cut-out, after the end mill's change: 60 lines into it
    change = max(i for i, p in job.engine.pauses.items() if p.startswith("TOOL CHANGE"))
    stop_at = change + 60
    with grbl_machine(settings, **board_kwargs()) as (board, link):
        machine = mill_machine(link)
        operator = Operator(machine, stop_at=stop_at)
        first = machine.run_job(machine.prepare_mill(program), operator)
        assert not first.completed and "the tool lifted to 1 mm" in first.held
        cut = len(positions_and_ticks(settled_trace(board))[0])
        resumption = machine.plan_mill_resume(machine.pending_mill())
        assert "a tool change: its Z re-zero is done again" in resumption.why or \
            "comes after a tool change" in resumption.why, resumption.why
        operator.prompts.clear()
        second = machine.resume(resumption, operator)
        assert second.completed
        parts = positions_and_ticks(settled_trace(board))[0]
        edges = board.trace()
    start = resumption.job.start
    assert change < start <= stop_at + 1
    # the resume asked for the tool in the spindle and re-zeroed it (the probe clip)
    assert operator.prompts[0] == ("paused for a bit change: put in the 0.800 mm end mill "
                                   "(the tool the job goes on with)")
    assert len(operator.prompts) == 3
    # the first part is the whole job's path up to the stop (the feed hold decelerates
    # on the path), then the lift: Z up only, from the cut-out's -0.4 mm to +1 mm
    together, on_whole = follow(parts[:cut], whole)
    lift = parts[together - 1:cut]
    assert np.all(lift[:, :2] == lift[0, :2]) and np.all(np.diff(lift[:, 2]) == 1)
    assert -64 <= lift[0, 2] < 0 and lift[-1, 2] == SAFE_STEPS
    # the resumed part ends as the whole job does, on the same step, and its path is
    # the whole job's from before where the first part left it: together the whole job
    resumed = parts[cut - 1:]
    assert tuple(resumed[-1]) == tuple(whole[-1])
    tail, whole_tail = follow(resumed, whole, backwards=True)
    assert len(whole) - whole_tail <= on_whole, (len(whole), whole_tail, on_whole)
    # before that tail: the lead-in, every XY move at the safe height
    lead = resumed[:len(resumed) - tail + 1]
    moves_xy = np.any(lead[1:, :2] != lead[:-1, :2], axis=1)
    assert np.all(lead[1:][moves_xy, 2] >= SAFE_STEPS), lead[1:][moves_xy, 2].min()
    # the spindle stopped with the job and turns again when the tail starts (the
    # lead-in's M3): its PWM (2 kHz) toggles in the last 10 ms before the tail's first step
    cycle, pin, level = edges
    cycle = cycle.astype(np.int64)
    pwm = cycle[pin == firmware.SPINDLE_PWM_PIN]
    tick = positions_and_ticks(edges)[1]
    tail_cycle = tick[len(parts) - tail] * 8       # Timer1 ticks are 8 cycles
    assert np.count_nonzero((pwm > tail_cycle - 160_000) & (pwm <= tail_cycle)) >= 10
    stop_cycle = tick[cut - 1] * 8
    assert not np.any((pwm > stop_cycle) & (pwm < stop_cycle + 160_000)), "spindle on"


def test_a_probe_that_touches_nothing_stops_the_job_clearly_and_loses_nothing(
        program, tmp_path, monkeypatch):
    """The plate 20 mm below the work zero: the first tool change's G38.2 (10 mm of
    reach) ends in GRBL's ALARM:5; the job stops saying so in mm, the alarm cleared
    and the position kept, and the journal resumes at that tool change."""
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    drilling = program.text[program.text.index("(galileo-cnc mill: drilling"):
                            program.text.index("(galileo-cnc mill: cut-out")]
    job_text = "G21 G90 G17 G94\nG0 Z1\n" + drilling + "M5\nM2\n"
    drill = dataclasses.replace(program, text=job_text, name="drill.nc")
    with grbl_machine({**SETTINGS, **QUICK_ACCEL}, probe=ProbeSurface(z0=-20 * MM)) \
            as (board, link):
        machine = mill_machine(link)
        job = machine.prepare_mill(drill)
        with pytest.raises(GrblStreamError) as failed:
            machine.run_job(job, Operator(machine))
        text = str(failed.value)
        probe = next(i for i, line in enumerate(job.engine.lines)
                     if line.text.startswith("G38.2"))
        place = f"drill.nc:{job.engine.lines[probe].command + 1}"
        assert text.startswith(place) and "ALARM:5" in text, text
        assert "the probe went down to Z -10.000 mm (work) and touched nothing" in text
        # (the drilling's first tool change comes before its first hole: at X0 Y0)
        assert "GRBL's alarm was cleared ($X), the tool stands at X 0.000 Y 0.000 " \
               "Z -10.000 mm (work)" in text, text
        assert link.status().state == "Idle"
        entry, kept = machine.pending_mill()
        assert entry.state == "failed" and kept.text == job_text
        assert entry.confirmed == probe - 1         # the M0 before it: the clip is on
        resumption = machine.plan_mill_resume((entry, kept))
        change = max(i for i in job.engine.pauses if i < probe
                     and "TOOL CHANGE" in job.engine.pauses[i])
        assert resumption.job.start == change, resumption.why
        assert "is a tool change: done again" in resumption.why


def test_a_mill_job_past_the_travel_is_refused_before_the_first_byte(program, tmp_path,
                                                                     monkeypatch):
    """On a homed GRBL ($20, $22) a mill job whose X or Y would leave the travel is
    refused naming the file line, the axis and the limit: no byte of it sent, no journal
    begun (nothing to resume). Z is not checked: every tool change zeroes it where the
    bit touches."""
    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    homed = {**SETTINGS, 22: "1", 20: "1", 130: "200", 131: "100", 132: "50"}
    with grbl_machine(homed, **board_kwargs()) as (board, link):
        machine = mill_machine(link)
        link.command_checked("G53 G0 X-3 Y-50 Z-10")     # work zero 3 mm from X's end
        link.command_checked("G10 L20 P0 X0 Y0 Z0")
        link.wait_idle()
        job = machine.prepare_mill(program)
        sent = []
        write = link.port.write
        link.port.write = lambda data: (sent.append(data), write(data))[1]
        with pytest.raises(TravelError) as raised:
            machine.run_job(job, Operator(machine))
        link.port.write = write
        assert sent == [b"?"]               # the status query only
        message = str(raised.value)
        assert message.startswith("job refused before sending: board (--mill all):")
        assert "takes X to" in message and "outside GRBL's travel -200..0 mm ($130=200)" \
            in message
        with pytest.raises(GalileoError, match="no interrupted mill job"):
            machine.pending_mill()
        # 30 mm further in, the same job passes the check (it is not run here)
        link.command_checked("G53 G0 X-33")
        link.command_checked("G10 L20 P0 X0")
        link.wait_idle()
        job.engine.check_travel()
