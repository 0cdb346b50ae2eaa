"""`resume`: continue the job the journal says was interrupted, after its last
confirmed command (the streamer replans the file and checks the machine's position)."""

from __future__ import annotations

from galileo_cnc.stream.journal import Journal
from galileo_cnc.stream.streamer import JobStreamer
from galileo_cnc.stream.resume import plan_resume
from galileo_cnc.console.job_screen import JobScreen, report


def run(console, arguments: list[str]) -> None:
    journal = Journal.default()
    entry = journal.pending()
    if entry is None:
        console.say("no interrupted job to resume")
        return
    job, program, start = plan_resume(console.link, entry)   # ResumeError says why not
    console.say(f"{entry.source}: {start} of {len(job)} commands were done"
                f"{' (' + entry.reason + ')' if entry.reason else ''}")
    if not console.confirm("continue the job?"):
        return
    streamer = JobStreamer(console.link, job, program, journal=journal, start=start)
    screen = JobScreen(console, program.source, len(job) - start)
    report(console, screen.run(streamer.run, streamer.abort))
