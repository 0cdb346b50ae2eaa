"""A noisy cable (issue 13, the link): lost replies anywhere, a lost refusal, a hold or
abort nobody sent, and a seeded sample of bench/bench_faults.py's campaign.

Against `sim://?speed=0` (the reference machine behind the protocol, instant clock) with
the link's timeouts shortened: the machine answers at once, so a reply missing for a
few tenths of a second is lost, not late.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from galileo_cnc import protocol as P
from galileo_cnc.job import Jog, SetOrigin
from galileo_cnc.machine import simulate
from galileo_cnc.plan.planner import plan_program
from galileo_cnc.readers import read_file
from galileo_cnc.sim.simulator import forget_named_machines, named_machine
from galileo_cnc.stream.journal import ABORTED, Journal
from galileo_cnc.stream.resume import resume_job
from galileo_cnc.stream.streamer import JobStreamer
from galileo_cnc.transport.link import LinkError, MachineLink, MachineStopped
from galileo_cnc.transport.port import open_port

from inked import inked_points

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))
import bench_faults as B  # noqa: E402

SAMPLE = REPO / "samples" / "led-blinker.gbr"
URL = "sim://faults?speed=0"


@pytest.fixture(autouse=True)
def fresh_machines():
    forget_named_machines()
    yield
    forget_named_machines()


@pytest.fixture(scope="module")
def planned():
    program = read_file(SAMPLE)
    from galileo_cnc.plan.offsets import proposed_offset
    return program, plan_program(program, None, proposed_offset(program))


def quick_link(port, url=URL) -> MachineLink:
    link = MachineLink.attach(port, url)
    link.status_retry_s, link.reply_s = 0.1, 0.3
    return link


def quick_streamer(link, job, program, **kwargs) -> JobStreamer:
    streamer = JobStreamer(link, job, program, **kwargs)
    streamer.stall_s = 0.3
    return streamer


class DropFirst:
    """Loses the first line from the machine that starts with `prefix`."""

    def __init__(self, port, prefix: bytes):
        self.port, self.prefix, self.dropped = port, prefix, False

    def readline(self):
        line = self.port.readline()
        if not self.dropped and line.startswith(self.prefix):
            self.dropped = True
            return b""
        return line

    def __getattr__(self, name):
        return getattr(self.port, name)


class GarbleStatusAndOk:
    """Turns every 4th `ok` and status line into a believable lie: another digit in its
    `N` (as noise could), the check left as it was."""

    def __init__(self, port):
        self.port, self.garbled, self.count = port, [], 0

    def readline(self):
        line = self.port.readline()
        if line.startswith((b"ok N", b"status:")):
            self.count += 1
            if self.count % 4 == 0:
                at = line.rindex(b"N") + 1
                digit = b"%d" % ((int(line[at:at + 1]) + 1) % 10)
                line = line[:at] + digit + line[at + 1:]
                self.garbled.append(line)
        return line

    def __getattr__(self, name):
        return getattr(self.port, name)


def test_a_garbled_ok_or_status_is_dropped_by_its_check_not_believed(planned):
    program, job = planned
    port = GarbleStatusAndOk(open_port(URL, timeout=0.1))
    link = quick_link(port)
    messages = []
    link.on_message = messages.append
    result = quick_streamer(link, job, program).run()
    link.close()
    assert result.completed and len(port.garbled) >= 10
    ignored = [m for m in messages if m.startswith("ignored from the machine")]
    assert len(ignored) == len(port.garbled)
    assert named_machine("faults").trace().same_steps(simulate(job.commands))


class LateReplies:
    """Delivers `lines` (checked, as the machine wrote them long ago) before anything else
    once `arm()` is called: replies a job's lines in flight drew after it stopped waiting."""

    def __init__(self, port):
        self.port, self.late = port, []

    def arm(self, *texts: bytes) -> None:
        self.late = [P.checked(t) for t in texts]

    def readline(self):
        return self.late.pop(0) if self.late else self.port.readline()

    def __getattr__(self, name):
        return getattr(self.port, name)


def test_a_late_rs_and_ok_for_an_old_number_do_not_pass_for_the_next_line():
    # protocol 3 renumbered a line to the number of any `rs`: a late `rs N2` made `U` go
    # out as N2, and the late `ok N2` behind it confirmed a `U` the machine never took
    port = LateReplies(open_port(URL, timeout=0.1))
    link = quick_link(port)
    for _ in range(3):
        link.send(Jog(dx_steps=10, dy_steps=0, dz_steps=0))     # N1 .. N3 accepted
    port.arm(b"rs N2", b"ok N2")
    reply = link.send_protocol(P.Unlock())
    status = link.status()
    link.close()
    assert (reply.kind, reply.seq) == ("ok", 4)
    assert status.last_seq == 4 and status.x_steps == 30


@pytest.mark.parametrize("position", range(1, 60, 3))
def test_a_lost_reply_anywhere_is_settled_and_the_trace_is_the_reference(planned, position):
    # every 3rd reply position of the job (pen changes at 1, 3, 9...; the last
    # replies are EndJob's and the closing U's)
    program, job = planned
    port = B.NoisyPort(open_port(URL, timeout=0.1), B.Fault(lose_reply=position), 0)
    link = quick_link(port)
    port.enabled = True
    result = quick_streamer(link, job, program).run()
    link.close()
    assert port.replies_read >= min(position, 50)
    assert result.completed
    assert named_machine("faults").trace().same_steps(simulate(job.commands))


def test_a_refusal_whose_reply_is_lost_still_stops_the_job_and_nothing_behind_runs(
        planned, tmp_path):
    program = read_file(SAMPLE)
    job = plan_program(program, None, (0, 0))
    port = DropFirst(open_port(URL, timeout=0.1), b"error:")
    link = quick_link(port)
    link.send(Jog(dx_steps=31_000))         # near the end of X: a soft limit refuses a line
    link.send(SetOrigin())
    before = named_machine("faults").trace()
    with pytest.raises(LinkError, match="error:5 soft limit") as refused:
        quick_streamer(link, job, program, journal=Journal(tmp_path / "j.json")).run()
    assert port.dropped                     # its first error reply never arrived
    assert f"{SAMPLE}:" in str(refused.value)
    status = link.status()
    link.close()
    # the refused line and every line behind it were never counted (never ran): the
    # stop's `U` took the refused number, and the head never left where the job began
    assert status.last_seq == refused.value.reply.seq
    assert (status.x_steps, status.y_steps) == (0, 0)
    assert len(named_machine("faults").trace().tick) > len(before.tick)   # the pen moved


def test_the_same_refusal_is_answered_again_so_a_lost_error_cannot_pass_for_success():
    link = quick_link(open_port(URL, timeout=0.1))
    seq = link.next_seq()
    line = P.encode_command(Jog(dx_steps=-5, dy_steps=0, dz_steps=0), seq)
    for _ in range(2):                      # the refused number is expected again
        link.write(line)
        reply = link.next_reply(1.0)
        assert (reply.kind, reply.code, reply.seq) == ("error", 5, seq)
    behind = P.encode_command(Jog(dx_steps=5, dy_steps=0, dz_steps=0), P.next_seq(seq))
    link.write(behind)
    assert link.next_reply(1.0) == P.Reply("rs", seq)    # never runs
    assert link.status().last_seq == seq - 1 and link.status().x_steps == 0
    link.close()


@pytest.mark.parametrize("byte", [P.RT_HOLD, P.RT_ABORT])
def test_a_hold_or_abort_nobody_sent_stops_with_a_message_and_resumes(planned, tmp_path, byte):
    program, job = planned
    journal = Journal(tmp_path / "journal.json")
    url = "sim://unasked?speed=50"
    port = open_port(url, timeout=0.1)
    link = quick_link(port, url)
    streamer = quick_streamer(link, job, program, journal=journal)
    sent = []

    def noise(progress):                    # as if the cable made the byte mid-job
        if progress.confirmed >= len(job) // 2 and not sent:
            sent.append(port.write(byte))

    with pytest.raises(MachineStopped, match="although the host did not ask"):
        streamer.run(on_progress=noise)
    link.close()
    assert journal.load().state == ABORTED
    link = quick_link(open_port(url, timeout=0.1), url)
    result = resume_job(link, journal)
    link.close()
    assert result.completed
    trace, whole = named_machine("unasked").trace(), simulate(job.commands)
    assert inked_points(trace) == inked_points(whole)
    assert trace.final_position == whole.final_position


def test_a_seeded_sample_of_the_fault_campaign_has_no_hang_no_wrong_trace(tmp_path):
    table = B.campaign(B.SimTarget(), 40, seed=2024, tmp=tmp_path, progress=False)
    bad = {key: n for key, n in table.items() if key[1] in ("hang", "wrong", "crash")}
    assert not bad, bad
    assert sum(table.values()) == 40
    assert sum(n for (_, outcome), n in table.items() if outcome == "finished") >= 30
