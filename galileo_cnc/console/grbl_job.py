"""`getg` on GRBL: the planned file as GRBL G-code, streamed under the console's
progress bar, the way `galileo-cnc plot` does it on a GRBL board (cli/plot_grbl.py).

G-code from `job_to_gcode` (the pen as the profile's Z heights), GRBL's own time
estimate, the travel check on a homed machine before the first byte, then the
job in pieces that end at the pen changes (`pen_pieces`/`stream_piece` of
grbl/session.py, as plot does: each piece runs to a stop, a refusal or an alarm is named with GRBL's
text, the file line and its G-code line in the whole job). The bar, Enter at a
pen change and q/Ctrl-C are job_screen.JobScreen's, as on our firmware. A stop
holds the feed (GRBL decelerates on its path) and then soft-resets GRBL: its
queue is dropped, its position kept.
"""

from __future__ import annotations

import time

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.console.grbl_backend import JobInterrupted
from galileo_cnc.console.job_screen import BELL, JobScreen
from galileo_cnc.grbl.estimate import Machine, estimate
from galileo_cnc.grbl.gcode import AxisScale, job_to_gcode, pen_from_config, source_of
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.session import (
    hold_and_reset,
    pen_pieces,
    position_text,
    source_line,
    stream_piece,
)
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.travel import applies, check_travel
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.stream.streamer import (
    PenChange,
    Progress,
    StreamAborted,
    StreamResult,
    describe_aperture,
)

STOPPED = "stopped by the user"


class GrblJob:
    """One planned file as G-code lines, streamed by `run` (in the console's thread)
    and stopped by `abort` (from the progress bar's key thread)."""

    def __init__(self, backend, planned, config: MachineConfig):
        self.backend = backend
        self.link = backend.link
        self.planned = planned
        settings = self.link.settings
        scale = AxisScale.from_texts([settings.steps_per_mm_text(a) for a in range(3)])
        self.lines = job_to_gcode(planned.job, scale, pen_from_config(config),
                                  feed_steps_per_s=config.feed_steps_per_s,
                                  flash_dwell_ms=config.flash_dwell_ms)
        self.where = lambda command: source_of(planned.plotted, planned.job, command)
        machine = Machine.from_settings(settings, self.link.build.planner_blocks)
        self.estimate_s = estimate(self.lines, machine).seconds

    def check_travel(self) -> None:
        """TravelError (the file line, the axis, the limit) before the first byte, when
        GRBL knows where its travel is ($20 or $22): nothing is sent then."""
        settings = self.link.settings
        if applies(settings):
            now = self.link.status()
            check_travel(self.lines, settings, self.link.tracker.wco_nm, now.mpos_nm,
                         where=self.where)

    def abort(self) -> None:
        self.backend.stop_job()

    def run(self, on_progress, on_pen_change) -> StreamResult:
        job, lines, total = self.planned.job, self.lines, len(self.lines)
        began = time.monotonic()
        done = 0

        def show(count: int) -> None:
            nonlocal done
            done = count
            elapsed = time.monotonic() - began
            on_progress(Progress(count, total, elapsed, max(0.0, self.estimate_s - elapsed),
                                 source_line(self.planned, lines[count - 1].command)))

        port = self.backend.port
        port.arm()
        try:
            position = 0
            for first, aperture in pen_pieces(lines, job.pen_changes):
                if first > position:
                    stream_piece(self.link, lines[position:first],
                                  list(range(position, first)), self.where, show)
                    position = first
                label = job.pen_labels.get(aperture) or \
                    f"pen for aperture {describe_aperture(self.planned.program, aperture)}"
                on_pen_change(PenChange(aperture, label, lines[first].command))
            stream_piece(self.link, lines[position:], list(range(position, total)),
                          self.where, show)
        except (JobInterrupted, StreamAborted):
            port.disarm()
            hold_and_reset(self.link)      # decelerate, then drop GRBL's queue
            return StreamResult(False, done, total, time.monotonic() - began, STOPPED)
        finally:
            port.disarm()
        return StreamResult(True, total, total, time.monotonic() - began)


def plot_on_grbl(console, backend, planned, config: MachineConfig) -> None:
    job = GrblJob(backend, planned, config)
    pens = len(planned.job.pen_changes)
    console.say(f"{len(job.lines)} G-code lines, {pens} pen change{'s' * (pens != 1)}, "
                f"about {duration_text(job.estimate_s)} on GRBL (its planner's estimate)")
    job.check_travel()
    screen = JobScreen(console, planned.program.source, len(job.lines))
    try:
        result = screen.run(job.run, job.abort)
    except GrblStreamError as stopped:
        backend.news()                  # the alarm is in this message, with its file line
        console.say(str(stopped))
        return                          # the console adds the unlock hint when locked
    link = backend.link
    if result.completed:
        console.say(f"{BELL}process has finished in {duration_text(result.elapsed_s)} "
                    f"({result.total} G-code lines); {position_text(link.tracker.last)}")
        return
    try:
        where = position_text(link.status())
    except GrblError:
        where = "GRBL's position was not reported"
    console.say(f"job stopped after {result.confirmed} of {result.total} G-code lines: "
                f"{result.reason}; GRBL held the feed and was reset (its queue dropped, "
                f"the position kept); {where}")
