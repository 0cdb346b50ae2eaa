"""`getg`'s and `resume`'s job on whichever machine is connected (backends/): the
machine prepares, runs and resumes it; the console says what it will do, asks, and
lends it the progress bar (job_screen.JobScreen, an Operator)."""

from __future__ import annotations

from galileo_cnc.console.job_screen import BELL, ConsoleOperator, JobScreen
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.transport.link import PortGone


def plot(console, planned, config) -> bool:
    """getg's job: estimated, travel-checked, journalled and streamed; True when it
    ran to its end."""
    machine = console.machine
    job = machine.prepare(planned, config,
                          timing=lambda: console.plans.timing(planned.job, console.config))
    pens = len(planned.job.pen_changes)
    console.say(f"{job.remaining} {job.unit_long}, {pens} pen change{'s' * (pens != 1)}, "
                f"about {duration_text(job.estimate_s)} {job.estimate_by}")
    return _run(console, job, lambda operator: machine.run_job(job, operator))


def run_mill(console, job) -> bool:
    """getg --mill's job (console/mill.py), prepared by the machine: journalled and
    streamed, its M0 pauses asked as pen changes; True when it ran to its end."""
    return _run(console, job, lambda operator: console.machine.run_job(job, operator))


def resume(console) -> None:
    """The job the machine's journal holds (from getg or `galileo-cnc plot`), continued
    as `plot --resume` does it; on GRBL an interrupted mill job first (its own journal)."""
    machine = console.machine
    pending = machine.interrupted_mill()    # one that cannot be resumed: said as is
    if pending is not None:
        _resume_mill(console, pending)
        return
    entry = machine.pending()                      # GalileoError: none, and why
    resumption = machine.plan_resume(entry, on_stage=console.say_stage,
                                     plan=console.plans.plan_file,
                                     timing=console.plans.timing)
    if _went_on(console, entry.source, resumption, "job"):
        planned = resumption.job.planned.job
        if planned.board is not None and planned.board.get("side") == "top":
            console.say(f"the top side is done: turn the blank over and type getg --side "
                        f"bottom {planned.source} for the bottom")


def _resume_mill(console, pending) -> None:
    """The interrupted mill job (getg --mill, plot --mill) from where GRBL stopped."""
    resumption = console.machine.plan_mill_resume(pending)
    _went_on(console, pending[1].name, resumption, "mill job")


def _went_on(console, name: str, resumption, what: str) -> bool:
    """The resumption said, confirmed, its position found, the rest run; True when it
    ran to its end."""
    machine = console.machine
    console.say(f"{name}: {resumption.why}")
    if resumption.job is None:
        console.say(resumption.nothing_left)
        return False
    if not console.confirm(f"continue the {what}?"):
        return False
    if not machine.find_position(resumption, ConsoleOperator(console)):
        console.say("then move it there (setup jogs the head), and type resume again")
        return False
    job = resumption.job
    return _run(console, job, lambda operator: machine.run_job(job, operator))


def _run(console, job, run) -> bool:
    """The job under the progress bar, and how it ended (True: to its end)."""
    screen = JobScreen(console, job.source, job.total, start=job.start)
    try:
        result = screen.run(run, console.machine.stop)
    except PortGone as gone:
        runs_on = getattr(gone, "runs_on", "")
        if runs_on:
            console.say(f"{runs_on}; once the machine stands still, connect again and type "
                        f"resume")
        raise                           # the console says the port is gone
    where = f"; {result.where}" if result.where else ""
    if result.completed:
        console.say(f"{BELL}process has finished in {duration_text(result.elapsed_s)} "
                    f"({result.total} {result.unit}){where}")
        return True
    reason = f": {result.reason}" if result.reason else ""
    held = f"; {result.held}{where}" if result.held else ""
    console.say(f"job stopped after {result.confirmed} of {result.total} {result.unit}"
                f"{reason}{held}; type resume to continue it")
    return False
