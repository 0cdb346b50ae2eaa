"""`resume`: continue the job the journal says was interrupted (a lost port) or
stopped (q, Ctrl-C) where the machine left it; the pen in force is asked for first."""

from __future__ import annotations

from galileo_cnc.console.job_screen import JobScreen, report
from galileo_cnc.stream.journal import Journal
from galileo_cnc.stream.resume import plan_resume
from galileo_cnc.stream.streamer import JobStreamer


def run(console, arguments: list[str]) -> None:
    journal = Journal.default()
    entry = journal.pending()
    if entry is None:
        console.say("no interrupted job to resume")
        return
    point = plan_resume(console.link, entry)           # ResumeError says why not
    console.say(f"{entry.source}: {point.start} of {len(point.job)} commands were done"
                f"{' (' + entry.reason + ')' if entry.reason else ''}")
    if not console.confirm("continue the job?"):
        return
    streamer = JobStreamer(console.link, point.job, point.program, journal=journal,
                           start=point.start, lead_in=point.lead_in,
                           job_start=point.job_start)
    screen = JobScreen(console, point.program.source, len(point.job) - point.start)
    report(console, screen.run(streamer.run, streamer.abort))
