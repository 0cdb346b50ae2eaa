"""Write a planned job's preview, a picture or an SVG by the file's extension: the one
way the shell's `preview` and the console's `preview` make one."""

from __future__ import annotations

import os

from galileo_cnc.errors import GalileoError
from galileo_cnc.preview.formats import preview_kind


def write_preview(planned, config, output: str | os.PathLike):
    """The preview of `planned` (a PlannedFile) in `output`: its info (`.summary()`).
    GalileoError naming the file when it cannot be written."""
    output = os.fspath(output)
    kind = preview_kind(output, "--output")
    try:
        if kind == "svg":               # from the job's commands: nothing to step
            from galileo_cnc.preview.svg import render_svg
            return render_svg(planned.program, planned.job, config, planned.offset_nm,
                              output, copper=planned.copper, pen_roles=planned.pen_roles)
        # the job's path from its commands: the reference machine's steps to within
        # one, without planning or stepping them (docs/preview.md, "Cost")
        from galileo_cnc.preview.job_path import JobPath
        from galileo_cnc.preview.render import render_preview
        return render_preview(planned.program, JobPath(planned.job.commands, config), config,
                              planned.offset_nm, output, job=planned.job,
                              copper=planned.copper, marks=planned.marks,
                              pen_roles=planned.pen_roles)
    except OSError as problem:
        raise GalileoError(f"--output {output}: cannot write: {problem.strerror}") from None
