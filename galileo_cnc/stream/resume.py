"""Resuming an interrupted or stopped job where the machine left it.

The journal names the file, its digest, the offset and the profile; the job is
planned again and continued only if the machine stands where the job could have
left it:

- after a lost port the machine ran what it had queued, so it stands at the end
  of a command: the job continues with the next one;
- after the user stopped it (q, Ctrl-C) the machine ramped down, usually inside a
  command. The reference trace (the path is the same, only the timing differs)
  finds that command; the job continues from its beginning, after a lead-in that
  travels there pen up, restores the feed, and lowers the pen if it was down.
  The part of the command drawn before the stop is drawn again, which a pen
  does not mind.

  The stop lifted the pen where the machine stood (stream/streamer.py, journal
  `stopped_at`): standing there pen up is standing where the job stopped, and the
  lead-in lowers the pen again.

- after a reset (journal `reset`) the position is lost. A job whose frame is the
  homed one (`plot --home`) is found again by homing; which commands ran is not
  exactly known (lines confirmed by `ok` may still have been queued), so it
  continues from the earliest command that may not have finished, after the same
  kind of lead-in. A job without a homed frame is refused: it must start again.
- a homed job whose machine stands nowhere near where it stopped (reset since the
  stop or the lost port: a new process opening an Uno's port resets it, and sim://
  or simavr:// start a fresh machine) is found again by homing too: a stopped one
  continues exactly at the command it stopped in, a lost one as after a reset.

A changed file, another profile or a machine that was moved (it stands nowhere on
the job's path near where it stopped) is refused, saying why.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Callable

import numpy as np

from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig, tomllib
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import Command, Job, LineTo, PenDown, Rapid, SetFeed
from galileo_cnc.machine import ReferenceMachine
from galileo_cnc.plan.board_plan import BoardChoice, plan_board
from galileo_cnc.plan.pipeline import Artwork, PlannedFile, PlanOptions, plan_file
from galileo_cnc.plan.transform import Transform
from galileo_cnc.program.ops import Program
from galileo_cnc.stream.homing import home_after_reset
from galileo_cnc.stream.journal import ABORTED, RESET, Journal, JournalEntry, file_digest
from galileo_cnc.stream.streamer import JobStreamer, StreamResult, after_reset_text
from galileo_cnc.transport.link import MachineLink

#: lines that can be accepted but not yet confirmed when a job stops (the receive
#: buffer holds this many of the shortest command lines)
_IN_FLIGHT_LINES = P.RX_BUFFER_BYTES // 8
#: commands with steps that can be confirmed but unfinished when the machine is reset:
#: one per queue block at least, and the one the stepper runs
_UNFINISHED_COMMANDS = P.QUEUE_BLOCKS + 1


class ResumeError(GalileoError):
    """The interrupted job cannot continue exactly where it stopped."""


@dataclass(frozen=True)
class ResumePoint:
    """Where a job continues: command `start`, after the `lead_in` commands."""

    job: Job
    artwork: Artwork             # the file as read, with where it sits
    start: int
    lead_in: tuple[Command, ...] = ()
    job_start: tuple[int, int, int] = (0, 0, 0)    # where the job's first move began
    plotted: Program | None = None     # what the job was planned from (the ink, in ink mode)
    #: the machine was reset: home it (home_after_reset) before the lead-in
    home: bool = False
    homed: bool = False                # the job's frame is the homed one
    #: home: why the position was lost, as the user is told it
    lost: str = ""
    #: home: confirmed commands that may not have run (drawn again)
    unsure: int = 0

    @property
    def program(self) -> Program:
        return self.plotted if self.plotted is not None else self.artwork.program


def position_after(job: Job, count: int, config: MachineConfig,
                   job_start: tuple[int, int, int] = (0, 0, 0)) -> tuple[int, int, int]:
    """Work position once the first `count` commands have run from `job_start`."""
    machine = ReferenceMachine(config, job_start)
    machine.plan(job.commands[:count])
    return machine.work_position


def stopped_inside(job: Job, config: MachineConfig, here: tuple[int, int, int],
                   first: int, last: int, job_start: tuple[int, int, int] = (0, 0, 0)
                   ) -> tuple[int, tuple[Command, ...]] | None:
    """The earliest command among first..last whose path passes through `here` (work
    steps, at the end of a step event), and the lead-in that restarts it; None if the
    machine stands nowhere on that stretch of the job."""
    machine = ReferenceMachine(config, job_start)
    machine.plan(job.commands[:first])
    for k in range(first, min(last, len(job) - 1) + 1):
        begin = machine.work_position
        feed = machine.feed_steps_per_s
        trace = machine.run([job.commands[k]])
        if here == begin or _passes_through(trace, begin, here):
            return k, _lead_in(begin, feed, config)
    return None


def _lead_in(begin: tuple[int, int, int], feed: int, config: MachineConfig
             ) -> tuple[Command, ...]:
    """Back to where a command begins: travel there pen up, the feed in force, and the
    pen down again if it was."""
    lead_in: list[Command] = [Rapid(begin[0], begin[1]), SetFeed(feed)]
    if begin[2] == config.pen_down_z_steps:
        lead_in.append(PenDown())
    return tuple(lead_in)


def first_unfinished(job: Job, config: MachineConfig, confirmed: int, floor: int,
                     job_start: tuple[int, int, int] = (0, 0, 0)) -> int:
    """The earliest command that may not have finished when the machine was reset after
    confirming command `confirmed`: the machine queues what it confirms, and its queue
    can hold the last commands with steps (one block each at least) and the one
    running. Before a pen change the machine stood still with every line run, so
    never before the last one up to `confirmed`, nor before `floor` (the session's
    first command)."""
    changes = [k for k in job.pen_changes if k <= confirmed + 1]
    floor = max(floor, max(changes, default=0), 0)
    machine = ReferenceMachine(config, job_start)
    machine.plan(job.commands[:floor])
    steps = [bool(machine.plan([command])) for command in job.commands[floor:confirmed + 1]]
    start, counted = confirmed + 1, 0
    while start > floor and counted < _UNFINISHED_COMMANDS:
        start -= 1
        counted += steps[start - floor]
    return start


#: why a reset job's position is lost
RESET_DURING_JOB = "the machine was reset during the job"
#: why a homed job whose machine stands elsewhere is homed again
NOT_WHERE_IT_STOPPED = ("the machine does not stand where the job stopped (it was reset "
                        "or moved since: opening an Uno's port anew resets it)")


def _after_reset(job: Job, artwork: Artwork, entry: JournalEntry, config: MachineConfig,
                 plotted: Program | None, lost: str = RESET_DURING_JOB) -> ResumePoint:
    """A reset job continues, homed, from the first command that may not have finished."""
    if not entry.homed:
        raise ResumeError(f"the machine was reset during the job, and its frame was not the "
                          f"homed one: {after_reset_text(False)}")
    begun = entry.start_position
    start = first_unfinished(job, config, entry.confirmed, entry.first_index, begun)
    machine = ReferenceMachine(config, begun)
    machine.plan(job.commands[:start])
    lead_in = _lead_in(machine.work_position, machine.feed_steps_per_s, config)
    return ResumePoint(job, artwork, start, lead_in, begun, plotted, home=True, homed=True,
                       lost=lost, unsure=entry.confirmed + 1 - start)


def _passes_through(trace, begin: tuple[int, int, int], here: tuple[int, int, int]) -> bool:
    """Does the head stand at `here` after some step event of `trace`?"""
    if not len(trace.tick):
        return False
    where = trace.positions(begin)
    event_ends = np.r_[trace.tick[1:] != trace.tick[:-1], True]   # a stop falls between events
    return bool(np.all(where[event_ends] == np.asarray(here), axis=1).any())


def replan(entry: JournalEntry, config: MachineConfig,
           on_stage: Callable[[str], None] | None = None,
           plan: Callable[..., PlannedFile] = plan_file) -> PlannedFile:
    """The journal's job planned again exactly as it was (file, offset, mode, order,
    pens, layers, units, scale and rotation; the planner is deterministic), for our
    firmware's resume and GRBL's. `on_stage`: see plan_file; `plan`: plan_file, or one
    that keeps plans (the console's PlanCache). A board's side (`entry.board`) is
    planned from the board again, the same side with the same choices."""
    options = PlanOptions(mode=entry.mode, file_order=not entry.group,
                          pens_nm=tuple(entry.pens_nm), layers=tuple(entry.layers),
                          units=entry.units,
                          transform=Transform(Fraction(entry.scale), entry.rotate_deg))
    if entry.board is not None:
        return plan_board(entry.source, config, tuple(entry.offset_nm),
                          choice=BoardChoice.from_dict(entry.board), options=options,
                          optimize=entry.ordered, on_stage=on_stage)
    return plan(entry.source, config, tuple(entry.offset_nm), options=options,
                optimize=entry.ordered, on_stage=on_stage)


def plan_resume(link: MachineLink, entry: JournalEntry,
                on_stage: Callable[[str], None] | None = None,
                plan: Callable[..., PlannedFile] = plan_file) -> ResumePoint:
    """Replan the journal's job and find where to continue; ResumeError if the file
    changed or the machine was reset or moved since. `on_stage`, `plan`: see replan."""
    if not Path(entry.source).exists():
        raise ResumeError(f"{entry.source}: the file of the interrupted job is gone")
    if file_digest(entry.source) != entry.digest:
        raise ResumeError(f"{entry.source} changed since the job was planned; "
                          f"start it again with getg")
    config = MachineConfig.from_mapping(tomllib.loads(entry.profile), "journal")
    planned = replan(entry, config, on_stage, plan)
    job, artwork = planned.job, planned.artwork
    if len(job) != entry.total:
        raise ResumeError("the replanned job differs from the interrupted one")
    if entry.state == RESET:                # where the machine stands means nothing now
        return _after_reset(job, artwork, entry, config, planned.plotted)
    status = link.wait_idle()
    here = (status.x_steps, status.y_steps, status.z_steps)
    stopped_at = tuple(entry.stopped_at) if entry.stopped_at is not None else None
    lifted = stopped_at is not None and here == lifted_position(stopped_at, config)
    if stopped_at is not None and not lifted:
        return _moved_since_stop(job, artwork, entry, config, planned.plotted, here)
    if lifted:
        here = stopped_at                   # where it stopped, before the pen was lifted
    candidates = [entry.confirmed]
    before = link.initial_status
    if before is not None and (index := entry.index_of_seq(before.last_seq)) is not None:
        candidates.insert(0, index)      # the machine accepted lines we never heard of
    begun = entry.start_position
    for confirmed in candidates:
        if position_after(job, confirmed + 1, config, begun) == here:
            lead_in = _lower_again(here, config) if lifted else ()
            return ResumePoint(job, artwork, confirmed + 1, lead_in, begun, planned.plotted,
                               homed=entry.homed)
    if entry.state == ABORTED:
        found = _stopped_in(job, config, entry, here)
        if found is not None:
            return ResumePoint(job, artwork, found[0], found[1], begun, planned.plotted,
                               homed=entry.homed)
    if entry.homed:                         # homing finds the job's frame again
        return _after_reset(job, artwork, entry, config, planned.plotted, NOT_WHERE_IT_STOPPED)
    expected = position_after(job, entry.confirmed + 1, config, begun)
    raise _moved(here, expected, entry, config)


def _moved(here, expected, entry: JournalEntry, config: MachineConfig) -> ResumeError:
    return ResumeError(
        f"the machine stands at {_mm_text(here, config)}, but the job stopped at "
        f"{_mm_text(expected, config)} (after command {entry.confirmed + 1} of "
        f"{entry.total}): the board was reset or moved since; start the job again")


def _moved_since_stop(job: Job, artwork: Artwork, entry: JournalEntry, config: MachineConfig,
                      plotted: Program | None, here: tuple[int, int, int]) -> ResumePoint:
    """A stopped job whose machine no longer stands where the stop lifted the pen: a
    homed one is homed and continues in the command it stopped in; others are refused."""
    stopped_at = tuple(entry.stopped_at)
    if not entry.homed:
        raise _moved(here, lifted_position(stopped_at, config), entry, config)
    found = _stopped_in(job, config, entry, stopped_at)
    if found is None:
        return _after_reset(job, artwork, entry, config, plotted, NOT_WHERE_IT_STOPPED)
    return ResumePoint(job, artwork, found[0], found[1], entry.start_position, plotted,
                       home=True, homed=True, lost=NOT_WHERE_IT_STOPPED)


def lifted_position(stopped_at, config: MachineConfig) -> tuple[int, int, int]:
    """Where a stop that lifted the pen at `stopped_at` leaves the machine."""
    x, y, z = stopped_at
    return (x, y, max(z, config.pen_up_z_steps))


def _lower_again(here: tuple[int, int, int], config: MachineConfig) -> tuple[Command, ...]:
    """The lead-in where the stop lifted the pen at the end of a command: Z back."""
    if here[2] >= config.pen_up_z_steps:
        return ()
    if here[2] == config.pen_down_z_steps:
        return (PenDown(),)
    return (LineTo(here[0], here[1], here[2]),)


def _stopped_in(job: Job, config: MachineConfig, entry: JournalEntry,
                here: tuple[int, int, int]) -> tuple[int, tuple[Command, ...]] | None:
    """The command a stopped job's machine ramped down in, standing at `here`."""
    first = max(entry.first_index, entry.confirmed - P.QUEUE_BLOCKS)
    return stopped_inside(job, config, here, first, entry.confirmed + _IN_FLIGHT_LINES,
                          entry.start_position)


def _mm_text(position: tuple[int, int, int], config: MachineConfig) -> str:
    x, y, z = (v / config.steps_per_mm for v in position)
    return f"X {x:.3f} Y {y:.3f} Z {z:.3f} mm"


def resume_job(link: MachineLink, journal: Journal, **callbacks) -> StreamResult:
    """Continue the journal's interrupted or stopped job where the machine left it (a
    reset one after homing: without a Z end stop, the pen must stand at its Z origin)."""
    entry = journal.pending()
    if entry is None:
        raise ResumeError("no interrupted job to resume")
    point = plan_resume(link, entry)
    if point.home:
        home_after_reset(link)
    return JobStreamer(link, point.job, point.program, journal=journal, start=point.start,
                       lead_in=point.lead_in, job_start=point.job_start,
                       homed=point.homed).run(**callbacks)
