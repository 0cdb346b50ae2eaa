"""Resuming an interrupted job after the last command the machine confirmed.

The journal names the file, its digest, the offset and the profile; the job is
planned again and continued only where the machine stands where the job left it.
"""

from __future__ import annotations

from pathlib import Path

from galileo_cnc.config.machine import MachineConfig, tomllib
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import Job
from galileo_cnc.machine import ReferenceMachine
from galileo_cnc.plan.pipeline import plan_file
from galileo_cnc.program.ops import Program
from galileo_cnc.stream.journal import ABORTED, Journal, JournalEntry, file_digest
from galileo_cnc.stream.streamer import JobStreamer, StreamResult
from galileo_cnc.transport.link import MachineLink

class ResumeError(GalileoError):
    """The interrupted job cannot continue exactly where it stopped."""


def position_after(job: Job, count: int, config: MachineConfig) -> tuple[int, int, int]:
    """Work position once the first `count` commands have run (from the origin)."""
    machine = ReferenceMachine(config)
    machine.plan(job.commands[:count])
    return machine.work_position


def plan_resume(link: MachineLink, entry: JournalEntry) -> tuple[Job, Program, int]:
    """Replan the journal's job and find where to continue; ResumeError if the file
    changed, the machine was reset or moved, or the job is not resumable."""
    if entry.state == ABORTED:
        raise ResumeError(f"the last job was stopped by the user ({entry.reason}); "
                          f"start it again with getg")
    if not Path(entry.source).exists():
        raise ResumeError(f"{entry.source}: the file of the interrupted job is gone")
    if file_digest(entry.source) != entry.digest:
        raise ResumeError(f"{entry.source} changed since the job was planned; "
                          f"start it again with getg")
    config = MachineConfig.from_mapping(tomllib.loads(entry.profile), "journal")
    planned = plan_file(entry.source, config, entry.offset_nm, group=entry.group)
    job, program = planned.job, planned.program
    if len(job) != entry.total:
        raise ResumeError("the replanned job differs from the interrupted one")
    status = link.wait_idle()
    here = (status.x_steps, status.y_steps, status.z_steps)
    candidates = [entry.confirmed]
    before = link.initial_status
    if before is not None and (index := entry.index_of_seq(before.last_seq)) is not None:
        candidates.insert(0, index)      # the machine accepted lines we never heard of
    for confirmed in candidates:
        if position_after(job, confirmed + 1, config) == here:
            return job, program, confirmed + 1
    expected = position_after(job, entry.confirmed + 1, config)
    raise ResumeError(
        f"the machine stands at X{here[0]} Y{here[1]} Z{here[2]} steps, but the job's last "
        f"confirmed command ({entry.confirmed + 1} of {entry.total}) ends at X{expected[0]} "
        f"Y{expected[1]} Z{expected[2]}: the board was reset or moved since; "
        f"start the job again")


def resume_job(link: MachineLink, journal: Journal, **callbacks) -> StreamResult:
    """Continue the journal's interrupted job after its last confirmed command."""
    entry = journal.pending()
    if entry is None:
        raise ResumeError("no interrupted job to resume")
    job, program, start = plan_resume(link, entry)
    return JobStreamer(link, job, program, journal=journal, start=start).run(**callbacks)
