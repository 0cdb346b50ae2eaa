"""Our streaming host against the real firmware in simavr, through a pseudo-terminal.

The job is streamed by `galileo_cnc.stream.JobStreamer` over a `MachineLink`,
exactly as `getg` and `plot` do, once to the firmware in simavr and once to
`sim://`. The firmware's trace must have the same steps in the same order, and
every step edge within LATENCY_JITTER_TICKS of the reference tick plus an offset
that is constant between the points where the machine stands still on purpose
(pen changes and a resumed connection): the host keeps the firmware's queue
full in between, so no gap may open inside a run of moves.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import NO_OP, ArcTo, EndJob, Flash, Job, PenUp, Rapid
from galileo_cnc.machine import simulate
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.readers import read_file
from galileo_cnc.simavr.board import SimulatedBoard, step_trace
from galileo_cnc.stream.journal import INTERRUPTED, Journal
from galileo_cnc.stream.resume import resume_job
from galileo_cnc.stream.streamer import JobStreamer
from galileo_cnc.transport.link import MachineLink, PortGone
from galileo_cnc.transport.port import open_port

from faults import FaultyPort
from firmware_support import ELF, build_firmware, build_harness
from test_firmware_fitl import LATENCY_JITTER_TICKS

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def firmware():
    build_firmware()
    build_harness()
    return ELF


def planned(name: str):
    program = read_file(REPO / "samples" / name)
    return program, plan_program(program, None, proposed_offset(program))


def steps_before(job, command_index: int) -> int:
    return len(simulate(job.commands[:command_index]).tick)


def assert_same_trace_in_pieces(fw, ref, cuts):
    """Same steps; ticks equal to the reference's up to one offset per piece."""
    tick, axis, direction = fw
    assert len(tick) == len(ref.tick), f"{len(tick)} firmware steps, {len(ref.tick)} reference"
    assert np.array_equal(axis, ref.axis) and np.array_equal(direction, ref.dir)
    bounds = sorted({0, *cuts, len(tick)})
    for lo, hi in zip(bounds, bounds[1:]):
        if hi > lo:
            delay = tick[lo:hi] - ref.tick[lo:hi]
            spread = int(delay.max() - delay.min())
            assert spread <= LATENCY_JITTER_TICKS, (
                f"steps {lo}..{hi}: edges spread over {spread} ticks (a gap in the stream?)")


def cut_to_paths(job: Job, keep) -> Job:
    """`job` with the paths (a Rapid and what follows, up to the next Rapid) for which
    `keep(rapid, nth)` holds, `nth` counting the paths of that path's pen from 0, in
    the job's order: what comes before the first path, each pen's change before its
    first path kept, then the job's ending."""
    starts = [k for k, c in enumerate(job.commands) if isinstance(c, Rapid)]
    kept = replace(job, commands=job.commands[:starts[0]], op_index=job.op_index[:starts[0]],
                   aperture=job.aperture[:starts[0]], pen_changes={})
    pen, nth = None, 0
    for start, end in zip(starts, starts[1:] + [len(job)]):
        change = next((k for k in range(start, end) if k in job.pen_changes), None)
        pen, nth = (job.pen_changes[change], 0) if change is not None else (pen, nth + 1)
        if not keep(job.commands[start], nth):
            continue
        for k in range(start, end):
            if pen not in kept.pen_changes.values() and (k == change or change is None
                                                         and k == start + 1):
                kept.pen_changes[len(kept)] = pen
            kept.add(job.commands[k], job.op_index[k], job.aperture[k])
    if not isinstance(kept.commands[-1], EndJob):       # the job's own ending was left out
        kept.add(PenUp(), NO_OP, kept.aperture[-1])
        kept.add(EndJob(), NO_OP, kept.aperture[-1])
    return kept


def stream_to_sim(job, program):
    link = MachineLink.open("sim://?speed=0")
    result = JobStreamer(link, job, program).run()
    trace = link._port.trace()
    link.close()
    assert result.completed
    return trace


def test_the_sample_board_streamed_to_the_firmware_steps_as_on_sim(firmware):
    # the first path of each of its six pens (flashes, lines and an arc, every pen
    # change): 28 s of machine time where the whole board takes 86 s
    program, whole = planned("led-blinker.gbr")
    job = cut_to_paths(whole, lambda rapid, nth: nth == 0)
    assert list(job.pen_changes.values()) == list(whole.pen_changes.values())
    assert all(any(isinstance(c, kind) for c in job.commands) for kind in (Flash, ArcTo))
    sim_trace = stream_to_sim(job, program)
    assert sim_trace.same_steps(simulate(job.commands))
    changes = []
    with SimulatedBoard(firmware) as board:
        link = MachineLink.open(board.port)
        messages = []
        link.on_message = messages.append
        result = JobStreamer(link, job, program).run(on_pen_change=changes.append)
        final = link.status()
        link.close()
        board.stop()
        fw = step_trace(board.trace())
    assert result.completed and not messages, messages
    assert [c.aperture for c in changes] == list(job.pen_changes.values())
    assert (final.x_steps, final.y_steps, final.z_steps) == sim_trace.final_position
    assert_same_trace_in_pieces(fw, sim_trace, [steps_before(job, k) for k in job.pen_changes])


def test_a_pulled_cable_then_resume_gives_the_uninterrupted_trace(firmware, tmp_path):
    program, job = planned("square-and-circle.nc")
    journal = Journal(tmp_path / "journal.json")
    with SimulatedBoard(firmware) as board:
        port = FaultyPort(open_port(board.port, timeout=0.1), die_after=9)
        link = MachineLink.attach(port, board.port)
        with pytest.raises(PortGone):
            JobStreamer(link, job, program, journal=journal).run()
        link.close()
        entry = journal.pending()
        assert entry.state == INTERRUPTED and entry.confirmed < len(job) - 2

        link = MachineLink.open(board.port)        # plugged in again; the board kept going
        result = resume_job(link, journal)
        link.close()
        board.stop()
        fw = step_trace(board.trace())
    assert result.completed and journal.pending() is None
    resumed_at = len(job) - result.total
    assert 0 < resumed_at < len(job)           # some lines ran before the cut, some after
    assert_same_trace_in_pieces(fw, simulate(job.commands), [steps_before(job, resumed_at)])


def test_the_simulated_board_has_its_own_session(firmware):
    # Ctrl-C at the console sends SIGINT to the terminal's process group: the board
    # (a child process) must not be in it, or a stopped `home` kills it
    with SimulatedBoard(firmware, trace=False) as board:
        assert os.getsid(board._process.pid) != os.getsid(0)
        assert os.getpgid(board._process.pid) != os.getpgid(0)


def test_plot_on_the_simavr_port_runs_the_real_firmware(firmware, tmp_path):
    env = dict(os.environ, GALILEO_CNC_HOME=str(tmp_path), GALILEO_CNC_NO_PROBE="1")
    result = subprocess.run(
        [sys.executable, "-m", "galileo_cnc", "plot", "samples/square-and-circle.nc",
         "--port", "simavr://?realtime=0", "--yes"],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "connected to simavr://?realtime=0 (the firmware running in simavr), " \
        "firmware 0.1.0" in result.stdout
    assert "process has finished" in result.stdout
    missing = subprocess.run(
        [sys.executable, "-m", "galileo_cnc", "plot", "samples/square-and-circle.nc",
         "--port", f"simavr://?elf={tmp_path}/none.elf", "--yes"],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=60)
    assert missing.returncode == 1
    assert f"no firmware at {tmp_path}/none.elf: build it with `make -C firmware`" \
        in missing.stderr


def test_a_profile_other_than_the_flashed_one_is_refused_by_plot(firmware, tmp_path):
    # the firmware in simavr is built from the default config.h; the user's profile
    # says the machine is 150 mm wide: the banner's digest differs, the `C` list names
    # the field, and no line of the job is sent
    env = dict(os.environ, GALILEO_CNC_HOME=str(tmp_path), GALILEO_CNC_NO_PROBE="1")
    profile = tmp_path / "profile.toml"
    profile.write_text("[machine]\nx_travel_mm = 150.0\n")
    result = subprocess.run(
        [sys.executable, "-m", "galileo_cnc", "plot", "samples/square-and-circle.nc",
         "--port", "simavr://?realtime=0", "--yes", "--profile", str(profile)],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 1, result.stdout
    assert "warning: the firmware was built for another machine (X_TRAVEL_MAX_STEPS" \
        in result.stdout
    assert ("X_TRAVEL_MAX_STEPS 32000 in the firmware, 24000 in the profile"
            in result.stderr), result.stderr
    assert f"python -m galileo_cnc.firmware_headers --config {profile}" in result.stderr
    assert "process has finished" not in result.stdout
    assert "commands, about" not in result.stdout       # refused before the plan is shown


def test_the_firmware_reports_the_config_it_was_built_with(firmware):
    with SimulatedBoard(firmware, trace=False) as board:
        link = MachineLink.open(board.port)
        assert link.banner.config_digest == MachineConfig().firmware_digest()
        assert link.config_differences == ()
        reply = link.send_protocol(P.QueryConfig())
        link.close()
    assert reply.text == "config " + MachineConfig().firmware_text()


def test_a_real_copper_layer_inked_with_two_pens_steps_as_the_reference(firmware):
    # a real Altium copper layer: pads and pours filled with the 0.8 mm pen, what it
    # cannot reach with the 0.3 mm pen, traces too narrow for either as centre lines;
    # the paths at its right edge (both pens, fills, lines and arcs: 10 of the layer's
    # 55 paths) step as the reference in a sixth of the layer's 113 s of machine time
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file
    from corpus import CORPUS

    layer = plan_file(CORPUS / "altium" / "pcb1-x2" / "PCB1_Copper_Signal_Top.gbr",
                      options=PlanOptions(mode="ink", pens_nm=(800_000, 300_000)))
    job = cut_to_paths(layer.job, lambda rapid, nth: rapid.x_steps >= 3400)
    program = layer.plotted
    assert sum(isinstance(c, ArcTo) for c in job.commands) >= 5
    assert [job.pen_labels[k] for k in job.pen_changes.values()] == \
        ["the 0.8 mm pen", "the 0.3 mm pen"]
    sim_trace = stream_to_sim(job, program)
    assert sim_trace.same_steps(simulate(job.commands))
    changes = []
    with SimulatedBoard(firmware) as board:
        link = MachineLink.open(board.port)
        result = JobStreamer(link, job, program).run(on_pen_change=changes.append)
        link.close()
        board.stop()
        fw = step_trace(board.trace())
    assert result.completed
    assert [c.prompt for c in changes] == ["insert the 0.8 mm pen", "insert the 0.3 mm pen"]
    assert_same_trace_in_pieces(fw, sim_trace, [steps_before(job, k) for k in job.pen_changes])


# ---- junction speeds (docs/motion.md §5.7) on the firmware --------------------------------
JUNCTIONS_ON = MachineConfig(junction_deviation_mm=0.05, vertex_speed_change_mm_s=3.0)


def stream_with_junctions(elf, job, program, config=JUNCTIONS_ON):
    """The job streamed by JobStreamer to the firmware, planned with junction speeds."""
    with SimulatedBoard(elf) as board:
        link = MachineLink.open(board.port, config=config)
        messages = []
        link.on_message = messages.append
        result = JobStreamer(link, job, program).run()
        final = link.status()
        link.close()
        board.stop()
        fw = step_trace(board.trace())
    assert result.completed and not messages, messages
    return fw, final


def vertex_axis_changes(tick, commands, config):
    """Per blended vertex, the largest change of one axis's speed (steps/s) measured on
    `tick` (a trace of the commands): the last event of the move before and the first of
    the move after, each at its interval from the trace and along its move's direction."""
    from galileo_cnc.config.hardware import TICKS_PER_S
    from galileo_cnc.machine import ReferenceMachine
    from galileo_cnc.machine.blocks import Pause
    from galileo_cnc.machine.junctions import move_ends
    machine = ReferenceMachine(config)
    items = machine.plan_speeds(machine.plan(list(commands)))
    events = tick[np.r_[True, np.diff(tick) != 0]]
    changes, k, before = [], 0, None
    for item in items:
        if isinstance(item, Pause):
            before = None
            continue
        if item.n == 0:
            continue
        start, end = move_ends(item)
        if before is not None and before[0].exit > 0:
            prev_end, last = before[1], k - 1
            v_in = prev_end.rho * TICKS_PER_S / (events[last] - events[last - 1])
            v_out = start.rho * TICKS_PER_S / (events[k] - events[last])
            changes.append(max(abs(v_in * a - v_out * b)
                               for a, b in zip(prev_end.direction, start.direction)))
        before = (item, end)
        k += item.n
    return np.array(changes)


def check_blended(fw, job, config=JUNCTIONS_ON):
    """Blended vertices exist, and none changes an axis's speed by more than the bound
    (1 % for the trace's whole-tick intervals)."""
    changes = vertex_axis_changes(fw[0], job.commands, config)
    assert len(changes) >= 8, len(changes)
    assert changes.max() <= 1.01 * config.vertex_speed_change_steps_per_s, changes.max()


def test_an_ink_job_with_junction_speeds_steps_as_the_reference(firmware):
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file
    layer = plan_file(REPO / "samples" / "led-blinker.gbr", options=PlanOptions(mode="ink"))
    job = cut_to_paths(layer.job, lambda rapid, nth: nth < 2)
    ref = simulate(job.commands, JUNCTIONS_ON)
    assert ref.total_ticks < simulate(job.commands).total_ticks
    fw, final = stream_with_junctions(firmware, job, layer.plotted)
    assert_same_trace_in_pieces(fw, ref, [steps_before(job, k) for k in job.pen_changes])
    assert (final.x_steps, final.y_steps, final.z_steps) == ref.final_position
    check_blended(fw, job)


def test_an_arc_heavy_gcode_with_junction_speeds_steps_as_the_reference(firmware, tmp_path):
    # A wave of tangent semicircles, both ways round, between two lines: the pen
    # keeps its speed along the whole wave (the tangent is continuous at every joint).
    text = ["G21 G90 G17", "F600", "G00 X2 Y10", "M03", "G01 X6 Y10"]
    for k in range(8):
        text.append(f"{'G02' if k % 2 == 0 else 'G03'} X{10 + 4 * k} Y10 I2 J0")
    text += ["G01 X40 Y14", "M05", "M02"]
    path = tmp_path / "wave.nc"
    path.write_text("\n".join(text) + "\n")
    program = read_file(path)
    job = plan_program(program, None, proposed_offset(program))
    assert sum(isinstance(c, ArcTo) for c in job.commands) >= 8
    ref = simulate(job.commands, JUNCTIONS_ON)
    fw, final = stream_with_junctions(firmware, job, program)
    assert_same_trace_in_pieces(fw, ref, [steps_before(job, k) for k in job.pen_changes])
    check_blended(fw, job)
