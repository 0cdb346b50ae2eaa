"""The console's last plan, kept for planning the same job again in one session.

An evening at the console plans one board several times: `getg` it, `getg` it
again for a second copy, stop it with q and `resume`. Each plan is the same: the
planner is deterministic, and `resume` already relies on that (it replans the
journal's job and checks it has as many commands). On the largest layers a plan
takes 14-30 s, so the console keeps its last one and hands it out again when the
same file (by its bytes) is planned the same way for the same machine. It keeps
the job's timing too (the estimate and the ETA): stepping hellboard's job on the
reference machine for it takes longer than planning it.

"The same way" is compared in two forms. As asked: what `getg` gives plan_file
(an offset of "auto" included). As planned: the offset, mode, pens, grouping and
order the plan came out with, which is what the journal holds and `resume` asks
for. Nothing is kept across sessions, and a file that changed is planned again.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Callable

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import Job
from galileo_cnc.machine.timing import JobTiming, job_timing
from galileo_cnc.plan.pipeline import Artwork, OffsetChoice, PlannedFile, PlanOptions, plan_file
from galileo_cnc.stream.journal import file_digest


class PlanCache:
    """plan_file, with the last plan handed out again for the same request."""

    def __init__(self) -> None:
        self._keys: tuple = ()
        self._plan: PlannedFile | None = None
        self._timing: tuple[Job, MachineConfig, JobTiming] | None = None
        self.reused = 0                      # plans handed out again (for the tests)

    def timing(self, job: Job, config: MachineConfig) -> JobTiming:
        """job_timing(job.commands, config), kept for the last job it was asked for."""
        kept = self._timing
        if kept is not None and kept[0] is job and kept[1] == config:
            return kept[2]
        timing = job_timing(job.commands, config)
        self._timing = (job, config, timing)
        return timing

    def plan_file(self, source: str | os.PathLike | Artwork, config: MachineConfig,
                  offset: OffsetChoice = "auto", *, options: PlanOptions = PlanOptions(),
                  optimize: bool | None = None,
                  on_stage: Callable[[str], None] | None = None) -> PlannedFile:
        path = Path(source.program.source if isinstance(source, Artwork) else source)
        try:
            file = (str(path.resolve()), file_digest(path))
        except OSError:                      # plan_file says what is wrong with it
            return plan_file(source, config, offset, options=options, optimize=optimize,
                             on_stage=on_stage)
        asked = (file, config, offset if isinstance(offset, str) else tuple(offset),
                 options, optimize)
        as_planned = _as_planned(file, config, offset, options, optimize)
        if self._plan is not None and (asked in self._keys or as_planned in self._keys):
            self.reused += 1
            return self._plan
        planned = plan_file(source, config, offset, options=options, optimize=optimize,
                            on_stage=on_stage)
        self._plan = planned
        self._keys = (asked, _planned_key(file, config, planned))
        return planned


def _as_planned(file: tuple, config: MachineConfig, offset: OffsetChoice,
                options: PlanOptions, optimize: bool | None) -> tuple | None:
    """The key of a request that names everything a plan came out with (resume's:
    the journal's offset, mode, pens, grouping and order); None for any other."""
    if isinstance(offset, str) or options.mode == "auto" or optimize is None:
        return None
    return (file, _without_pens(config), tuple(offset), options.mode,
            tuple(options.pens_nm), not options.file_order, optimize, tuple(options.layers),
            options.units, options.transform.scale, options.transform.rotate_deg)


def _planned_key(file: tuple, config: MachineConfig, planned: PlannedFile) -> tuple:
    """What `_as_planned` makes of a request for exactly this plan."""
    job = planned.job
    return (file, _without_pens(config), tuple(planned.offset_nm), planned.mode,
            tuple(job.pens_nm), job.grouped, job.ordered, tuple(job.layers), job.units,
            job.scale, job.rotate_deg)


def _without_pens(config: MachineConfig) -> tuple:
    """The machine, but for its pens: a plan's pens are in its key on their own (the
    profile's, or --pens; resume names the ones the job was inked with)."""
    return tuple((f.name, getattr(config, f.name)) for f in dataclasses.fields(config)
                 if f.name != "pen_widths_mm")
