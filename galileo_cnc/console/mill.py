"""`getg --mill isolate|drill|cutout|all [--mill-set K=V] [--accept-shorts]
[--drill-order plated-first|unplated-first] BOARD`: a mill job (docs/mill.md) planned
as `plot --mill` plans it (grbl/mill_plan.py), its notes and summary said, confirmed,
then run on a GRBL board through the Machine under the progress bar; each M0 (a bit
change, the probe clipped on) is asked like a pen change; with the [mill] key
height_map = true the surface is probed first (mill_plan.with_height_map). On a
machine that runs no G-code (sim://, our firmware) it is a dry run, as `plot --mill`
makes it (mill_plan.DRY_RUN_NOTE): the job's G-code plotted by getg's own flow.
`resume` continues an interrupted mill job (jobs.resume: the mill journal's first)."""

from __future__ import annotations

import os

from galileo_cnc.console import jobs
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.mill_plan import (DRY_RUN_NOTE, MILL_JOBS, MillRequest,
                                        dry_run_path, profile_mill, with_height_map,
                                        write_dry_run)
from galileo_cnc.plan.board_plan import BoardChoice
from galileo_cnc.readers.board import is_board

DRILL_ORDERS = ("plated-first", "unplated-first")
USAGE = ("getg --mill isolate|drill|cutout|all [--mill-set KEY=VALUE] [--accept-shorts] "
         "[--drill-order plated-first|unplated-first] [--side top|bottom] BOARD")


def split_mill_options(arguments: list[str], switches: tuple[str, ...]
                       ) -> tuple[MillRequest | None, list[str]]:
    """The mill options among the leading options (before the file name) taken out:
    (the request, None without --mill; the other arguments in their order).
    `switches`: getg's other options that take no value."""
    rest, kept = list(arguments), []
    job, pairs, accept, order = None, [], False, "plated-first"
    while rest and rest[0].startswith("--"):
        flag = rest.pop(0)
        if flag == "--accept-shorts":
            accept = True
        elif flag in ("--mill", "--mill-set", "--drill-order"):
            value = rest.pop(0) if rest else ""
            if flag == "--mill" and value in MILL_JOBS:
                job = value
            elif flag == "--mill-set" and "=" in value:
                pairs.append(value)
            elif flag == "--drill-order" and value in DRILL_ORDERS:
                order = value
            else:
                raise GalileoError(f"getg: {flag} {value}".rstrip() + f": expected {USAGE}")
        else:
            kept.append(flag)
            if flag not in switches and rest:
                kept.append(rest.pop(0))
    mill_only = pairs or accept or order != "plated-first"
    if job is None and mill_only:
        raise GalileoError(f"getg: --mill-set, --accept-shorts and --drill-order go with "
                           f"--mill ({USAGE})")
    request = MillRequest(job, tuple(pairs), accept, order) if job is not None else None
    return request, kept + rest


def run(console, request: MillRequest, path: str, board: dict, plot_gcode) -> None:
    """The mill job on `path` (`board`: getg's board options, BoardChoice's keywords);
    `plot_gcode(path)`: getg on a G-code file, for the dry run."""
    machine = console.machine
    choice = BoardChoice(**board) if is_board(path) else None
    if choice is None and board:
        raise GalileoError(f"getg --mill: --side and the other board options are for a "
                           f"board (a folder, .zip or .gbrjob); {path} is one file")
    console.say(f"planning the mill job ({request.job}) ...")
    # a refusal (islands closer than the cut, listed in mm) is a GalileoError: said as is
    mill = request.mill(profile_mill(console.config_path))
    program, notes, summary = request.program(path, mill, choice)
    for note in notes:
        console.say(f"note: {note}")
    console.say(f"{program.name}: {summary}")
    if not machine.runs_mill:
        console.say(f"note: {machine.port_name} runs galileo-cnc firmware, not G-code: "
                    f"{DRY_RUN_NOTE}")
        gcode = dry_run_path()
        for line in write_dry_run(program, gcode):
            console.say(line)
        plot_gcode(str(gcode))
        return
    if mill.height_map:                     # probed now, before the job is confirmed
        program = with_height_map(machine, program, mill, console.confirm, console.say)
    job = machine.prepare_mill(program)
    console.say(job.estimate_line())
    if not console.confirm("run the mill job?"):
        console.say(f"not run (getg --mill {request.job} {os.path.basename(path)} asks again)")
        return
    jobs.run_mill(console, job)
