"""`resume`: continue the job the journal says was interrupted (a lost port) or
stopped (q, Ctrl-C) where the machine left it, or reset (a job planned homed: it is
homed again first); the pen in force is asked for first. Each backend resumes from
its own journal (`Backend.resume`): our firmware's is here, GRBL's in grbl_job.py."""

from __future__ import annotations

from galileo_cnc.console.job_screen import JobScreen, report
from galileo_cnc.stream.homing import home_after_reset, z_has_end_stop
from galileo_cnc.stream.journal import Journal
from galileo_cnc.stream.resume import plan_resume
from galileo_cnc.stream.streamer import JobStreamer


def run(console, arguments: list[str]) -> None:
    console.backend.resume(console)


def resume_job(console) -> None:
    """Our firmware's: the job in journal.json, from its line numbers and position."""
    journal = Journal.default()
    entry = journal.pending()
    if entry is None:
        console.say("no interrupted job to resume")
        return
    point = plan_resume(console.link, entry,           # ResumeError says why not
                        on_stage=console.say_stage, plan=console.plans.plan_file)
    console.say(f"{entry.source}: {point.start} of {len(point.job)} commands were done"
                f"{' (' + entry.reason + ')' if entry.reason else ''}")
    if point.home:
        console.say("the machine was reset during the job: it is homed first, and the "
                    "commands it may not have finished are drawn again")
        if not z_has_end_stop(console.config):
            console.say("Z has no end stop: put the pen at its Z origin (where Z 0 was set) "
                        "before you continue")
    if not console.confirm("continue the job?"):
        return
    if point.home:
        home_after_reset(console.link)
    streamer = JobStreamer(console.link, point.job, point.program, journal=journal,
                           start=point.start, lead_in=point.lead_in,
                           job_start=point.job_start, homed=point.homed,
                           timing=console.plans.timing(point.job, console.link.config))
    screen = JobScreen(console, point.program.source, len(point.job) - point.start)
    report(console, screen.run(streamer.run, streamer.abort))
