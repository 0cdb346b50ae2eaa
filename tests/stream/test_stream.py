"""Streaming jobs over a real pyserial port to the simulated machine (galileo_cnc.stream).

The port is `sim://` (the reference machine behind the wire protocol). Faults are
made by `FaultyPort`, a pass-through around that port which corrupts, drops or
cuts what crosses it, as a noisy cable or a pulled USB plug would.
"""

from __future__ import annotations

import re

import threading
from pathlib import Path

import pytest

from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import Jog, Rapid, SetOrigin
from galileo_cnc.machine import simulate
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.planner import PlanError, plan_program
from galileo_cnc.readers import read_file
from galileo_cnc.stream.journal import ABORTED, FINISHED, INTERRUPTED, Journal
from galileo_cnc.stream.resume import ResumeError, plan_resume, resume_job
from galileo_cnc.stream.streamer import JobStreamer
from galileo_cnc.transport.link import ConfigMismatch, LinkError, MachineLink, PortGone
from galileo_cnc.transport.port import open_port

from corpus import CORPUS, corpus_paths
from faults import FaultyPort
from inked import inked_points

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "samples" / "led-blinker.gbr"
INSTANT = "sim://?speed=0"


def sample_job(config: MachineConfig | None = None):
    program = read_file(SAMPLE)
    return program, plan_program(program, config, proposed_offset(program))


def faulty_link(url: str = INSTANT, **faults) -> tuple[MachineLink, FaultyPort]:
    port = FaultyPort(open_port(url, timeout=0.1), **faults)
    return MachineLink.attach(port, url), port


def machine_trace(port):
    return port.port.trace() if isinstance(port, FaultyPort) else port.trace()


@pytest.fixture
def journal(tmp_path):
    return Journal(tmp_path / "journal.json")


def test_the_sample_board_streams_with_pen_changes_and_steps_as_the_reference(journal):
    program, job = sample_job()
    link, port = faulty_link()
    changes, progress = [], []
    result = JobStreamer(link, job, program, journal=journal).run(
        on_pen_change=changes.append, on_progress=progress.append)
    link.close()
    assert result.completed and result.confirmed == result.total == len(job)
    assert machine_trace(port).same_steps(simulate(job.commands))
    # grouped by aperture: one change per aperture, each described for the user
    assert [c.aperture for c in changes] == [11, 10, 12, 15, 13, 14]
    assert changes[0].description == "pen for aperture D11 (1.7 x 1.7 mm rectangle)"
    assert changes[1].description == "pen for aperture D10 (1.6 mm round)"
    assert [c.command_index for c in changes] == sorted(job.pen_changes)
    assert progress[-1].confirmed == len(job)
    assert {p.eta_s for p in progress} == {0.0}      # an instant machine
    assert journal.load().state == FINISHED and journal.pending() is None


def test_character_counting_keeps_unanswered_lines_within_the_receive_buffer(journal):
    program, job = sample_job()
    link, port = faulty_link()
    link.hold()                     # a held machine fills its queue: lines wait unanswered
    streamer = JobStreamer(link, job, program)
    done = threading.Event()
    thread = threading.Thread(target=lambda: (streamer.run(), done.set()))
    thread.start()
    assert not done.wait(1.0)       # held: the job cannot finish
    assert port.port.machine.rx_overflows == 0
    link.resume()
    thread.join(30)
    assert done.is_set()
    link.close()
    assert 0 < port.max_unanswered_bytes <= P.RX_BUFFER_BYTES
    assert port.port.machine.rx_overflows == 0
    assert machine_trace(port).same_steps(simulate(job.commands))


@pytest.mark.parametrize("fault", [
    {"corrupt_line": 6},            # checksum fails: rs, resend from there
    {"corrupt_line": 2},            # the first job line
    {"drop_line": 9},               # never arrives: stall, settled by the status
    {"drop_reply": 12},             # ok lost: the next ok confirms it
    {"garbage_after": 4},           # noise from the machine's side is reported, ignored
])
def test_a_noisy_link_loses_no_move_and_repeats_none(fault):
    program, job = sample_job()
    link, port = faulty_link(**fault)
    messages = []
    link.on_message = messages.append
    result = JobStreamer(link, job, program).run()
    link.close()
    assert result.completed
    assert machine_trace(port).same_steps(simulate(job.commands))
    if "garbage_after" in fault:
        assert any("ignored from the machine" in m and "garbage" in m for m in messages)


def test_a_refused_line_stops_the_job_naming_the_file_line(journal):
    program = read_file(SAMPLE)
    job = plan_program(program, None, (0, 0))                  # fits the planner's travel
    link = MachineLink.open(INSTANT)
    # the user set the origin near the end of X: the machine's soft limit refuses the line
    link.send(Jog(dx_steps=31_000))
    link.send(SetOrigin())
    messages = []
    link.on_message = messages.append
    with pytest.raises(LinkError) as refused:
        JobStreamer(link, job, program, journal=journal).run()
    assert messages == []           # the stop that follows is ours: no "alarm:14 aborted"
    assert f"{SAMPLE}:" in str(refused.value) and "error:5" in str(refused.value)
    assert "X would reach 205.750 mm, beyond the travel's end at 200.000 mm [32920 steps] " \
        "(machine coordinates); the origin was set at X 193.750 mm on the machine, so in " \
        "work coordinates the travel ends at X 6.250 mm" in str(refused.value)
    # in mm, work coordinates, the wire's line only in brackets (issue 31, item 14)
    assert re.search(r"the machine refused \w+ to X -?\d+\.\d{3} mm .*\(work\) \[\w ",
                     str(refused.value)), str(refused.value)
    status = link.status()
    assert status.state == "idle" and status.queue_blocks == 0
    link.close()
    assert journal.load().state == "failed"


def test_abort_ramps_down_and_a_reset_machine_cannot_resume(journal):
    program, job = sample_job()
    link = MachineLink.open("sim://?speed=20")
    streamer = JobStreamer(link, job, program, journal=journal)
    stop_at = len(job) // 3
    etas = []

    def watch(progress):
        etas.append(progress.eta_s)
        if progress.confirmed >= stop_at:
            streamer.abort()

    result = streamer.run(on_progress=watch)
    # the ETA is the reference's 88 s of machine time at 20 times real time
    assert 4.0 < etas[0] < 4.41 and etas == sorted(etas, reverse=True)
    assert not result.completed and result.reason == "stopped by the user"
    status = link.status()
    assert status.state == "idle" and status.queue_blocks == 0     # unlocked, standing
    link.close()
    assert journal.load().state == ABORTED
    with pytest.raises(ResumeError, match="the board was reset or moved since"):
        resume_job(MachineLink.open(INSTANT), journal)          # a fresh power-on


def test_a_port_that_dies_resumes_to_the_same_total_trace(journal):
    from galileo_cnc.sim.simulator import forget_named_machines, named_machine

    program, job = sample_job()
    forget_named_machines()
    url = "sim://bench?speed=0"
    link, port = faulty_link(url, die_after=25)
    with pytest.raises(PortGone):
        JobStreamer(link, job, program, journal=journal).run()
    link.close()
    entry = journal.pending()
    assert entry.state == INTERRUPTED and 0 < entry.confirmed < len(job) - 1

    link = MachineLink.open(url)                    # the plug is back; the board kept power
    changes = []
    result = resume_job(link, journal, on_pen_change=changes.append)
    link.close()
    start = len(job) - result.total
    # first the pen in force where the job continues, then the changes still ahead
    in_force = job.pen_changes[max(k for k in job.pen_changes if k <= start)]
    assert changes[0].command_index == start and changes[0].aperture == in_force
    assert [c.command_index for c in changes[1:]] == [k for k in job.pen_changes if k > start]
    # lines in flight when the port died were accepted: the machine's own count
    # (its status N, read before the new session) moves the start past them
    assert result.completed and result.total < len(job) - entry.confirmed - 1
    assert named_machine("bench").trace().same_steps(simulate(job.commands))
    assert journal.pending() is None
    forget_named_machines()


def test_resume_refuses_a_machine_that_was_reset(journal):
    program, job = sample_job()
    link, port = faulty_link(die_after=25)
    with pytest.raises(PortGone):
        JobStreamer(link, job, program, journal=journal).run()
    link.close()
    fresh = MachineLink.open(INSTANT)               # a new power-on: position lost
    with pytest.raises(ResumeError, match="reset or moved"):
        resume_job(fresh, journal)
    fresh.close()
    assert journal.pending().state == INTERRUPTED   # still there for a later try


def test_a_silent_port_is_noticed(journal, monkeypatch):
    from galileo_cnc.transport import link as link_module

    monkeypatch.setattr(link_module, "SILENT_S", 0.5)
    monkeypatch.setattr(link_module, "POLL_S", 0.2)
    program, job = sample_job()
    link, port = faulty_link()
    port.readline = lambda: b""                     # the machine stops talking
    with pytest.raises(PortGone, match="no status reply"):
        JobStreamer(link, job, program, journal=journal).run()
    link.close()
    assert journal.pending().state == INTERRUPTED


# Every 12th real board under 60 kB (~20 files, some 15 s; the larger ones take seconds
# each and prove nothing the smaller do not); tests run in CI with the corpus beside
# the checkout. A sweep of all 406 that fit the travel streamed equal to the
# reference too (docs/streaming.md).
CORPUS_SAMPLE = [path for path in corpus_paths("real")
                 if (CORPUS / path).stat().st_size < 60_000][::12]


@pytest.mark.parametrize("path", CORPUS_SAMPLE)
def test_real_boards_stream_to_the_simulated_machine_as_the_reference_steps(path):
    program = read_file(CORPUS / path)
    try:
        job = plan_program(program, None, proposed_offset(program))
    except PlanError as too_big:                    # larger than the 200 mm travel
        assert "travel" in str(too_big)
        return
    link = MachineLink.open(INSTANT)
    changes = []
    result = JobStreamer(link, job, program).run(on_pen_change=changes.append)
    trace = link._port.trace()
    link.close()
    assert result.completed
    assert trace.same_steps(simulate(job.commands))
    assert [c.aperture for c in changes] == list(job.pen_changes.values())


def test_a_profile_that_differs_from_the_machine_is_refused_naming_the_fields(journal):
    program, job = sample_job()
    config_file = journal.path.parent / "small.toml"       # the machine was built for this
    config_file.write_text("[machine]\nx_travel_mm = 20.0\npen_lift_steps = 250\n")
    link = MachineLink.open(f"{INSTANT}&config={config_file}")   # the host plans for the seed
    assert [name for name, _, _ in link.config_differences] == [
        "PEN_UP_Z_STEPS", "X_TRAVEL_MAX_STEPS"]
    assert "warning: the firmware was built for another machine" in link.describe()
    with pytest.raises(ConfigMismatch) as refused:
        JobStreamer(link, job, program, journal=journal).run()
    text = str(refused.value)
    assert "X_TRAVEL_MAX_STEPS 3200 in the firmware, 32000 in the profile" in text
    assert "PEN_UP_Z_STEPS 250 in the firmware, 300 in the profile" in text
    assert "python -m galileo_cnc.firmware_headers --config" in text
    assert link.status().queue_blocks == 0 and link.status().x_steps == 0   # nothing ran
    link.close()
    agreeing = MachineLink.open(f"{INSTANT}&config={config_file}",
                                config=MachineConfig.from_toml(config_file))
    assert agreeing.config_differences == ()
    agreeing.close()


@pytest.mark.parametrize("fraction", [0.2, 0.5, 0.8])
def test_a_job_stopped_mid_move_resumes_and_inks_what_the_whole_job_inks(journal, fraction):
    """q in the middle of a move: the machine ramps down inside a command; resume
    travels back to that command's start pen up and draws on; together the two
    sessions ink exactly the points of an uninterrupted run and end where it ends."""
    program, job = sample_job()
    whole = simulate(job.commands)
    link = MachineLink.open("sim://?speed=40")
    streamer = JobStreamer(link, job, program, journal=journal)
    stop_at = int(len(job) * fraction)

    def stop_soon(progress):
        if progress.confirmed >= stop_at:
            streamer.abort()

    assert not streamer.run(on_progress=stop_soon).completed
    stopped = link.status()
    point = plan_resume(link, journal.pending())
    # The stop usually lands inside a move (then resume travels back to its start);
    # on a loaded machine it may land between commands or in a flash's dwell, where
    # there is nothing to travel back to, or just where a stroke begins, where the
    # lead-in only lowers the pen. Either way the ink below must be whole.
    if point.lead_in and not isinstance(point.lead_in[0], Rapid):
        assert not any(isinstance(c, Rapid) for c in point.lead_in)
        before = simulate(job.commands[:point.start]).final_position[:2]
        assert (stopped.x_steps, stopped.y_steps) == before
    result = resume_job(link, journal)
    trace = link._port.trace()
    final = link.status()
    link.close()
    assert result.completed and journal.pending() is None
    assert (final.x_steps, final.y_steps, final.z_steps) == whole.final_position
    assert inked_points(trace) == inked_points(whole)
    assert (stopped.x_steps, stopped.y_steps) != whole.final_position[:2]


def test_the_eta_of_a_machine_of_unknown_pace_is_measured(journal):
    # simavr://?realtime=0 runs as fast as simavr can: no speed is known beforehand
    program, job = sample_job()
    link = MachineLink.open("sim://?speed=50")
    link.speed = None
    etas = []
    result = JobStreamer(link, job, program).run(on_progress=lambda p: etas.append(p.eta_s))
    link.close()
    assert result.completed
    measured = [eta for eta in etas if eta is not None]
    assert etas[0] is None and measured        # nothing to measure before the first move
    # 88 s of machine time at 50 x: the measured ETAs are a few seconds, not 88
    assert max(measured[len(measured) // 2:]) < 10
