"""`resume`: continue the job the machine's journal says was interrupted (a lost port)
or stopped (q, Ctrl-C) where the machine left it, or reset (a job planned homed: it
is homed again first); the pen in force is asked for first. Each machine resumes
from its own journal (backends/: `pending`, `plan_resume`, `find_position`)."""

from __future__ import annotations

from galileo_cnc.console import jobs


def run(console, arguments: list[str]) -> None:
    jobs.resume(console)
