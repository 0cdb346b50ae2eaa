"""What `galileo-cnc info BOARD` prints: every file with its role and why, the board's size,
and its holes per diameter (text, and the same as data for `--json`).

The size is the outline's extent (its centre lines: where the board is cut), else the
copper's with the apertures, read by the Gerber reader in nm, else the holes' box. Holes
are counted only when a drill reader is given (`read_drill`: path ->
program.drills.DrillFile), so this module does not depend on which one.
"""

from __future__ import annotations

from collections import Counter
from typing import Callable

from galileo_cnc.errors import GalileoError
from galileo_cnc.program.drills import DrillFile
from galileo_cnc.program.extents import extents, union_box
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.readers import read_file
from galileo_cnc.readers.board.board import Board, open_board


def _mm(nm: int) -> float:
    return round(nm / NM_PER_MM, 4)


def board_box_nm(board: Board, problems: list[str]) -> tuple[tuple[int, int, int, int] | None, str]:
    """(xmin, ymin, xmax, ymax) nm of the outline, else of the copper; and which it is."""
    for layers, with_apertures, what in ((board.outline(), False, "outline"),
                                         (board.copper("top") + board.copper("bottom"), True,
                                          "copper")):
        boxes = []
        for layer in layers:
            try:
                boxes.append(extents(read_file(layer.path), with_apertures=with_apertures))
            except GalileoError as problem:
                problems.append(str(problem))
        box = union_box(*boxes)
        if box is not None:
            return box, what
    return None, ""


def read_drills(board: Board, read_drill: Callable[[str], DrillFile],
                problems: list[str]) -> list[DrillFile]:
    """Every drill file of the board that reads (the others named in `problems`)."""
    drills = []
    for layer in board.drills():
        try:
            drills.append(read_drill(str(layer.path)))
        except GalileoError as problem:
            problems.append(str(problem))
    return drills


def hole_counts(drills: list[DrillFile]) -> tuple[Counter, Counter]:
    """Holes and slots per diameter (nm) over the drill files."""
    holes: Counter = Counter()
    slots: Counter = Counter()
    for drill in drills:
        holes.update(h.diameter_nm for h in drill.holes)
        slots.update(s.diameter_nm for s in drill.slots)
    return holes, slots


def _box_mm(box) -> dict | None:
    if box is None:
        return None
    return {"min_x": _mm(box[0]), "min_y": _mm(box[1]), "max_x": _mm(box[2]),
            "max_y": _mm(box[3])}


def board_summary(board: Board, read_drill: Callable[[str], DrillFile] | None = None) -> dict:
    """The board as plain data (lengths in mm): `info --json`'s "board"."""
    problems: list[str] = []
    box, measured = board_box_nm(board, problems)
    drills = read_drills(board, read_drill, problems) if read_drill is not None else []
    holes_box = union_box(*[drill.box_nm() for drill in drills])
    if box is None and holes_box is not None:
        box, measured = holes_box, "holes"
    summary = {
        "source": board.source,
        "job_file": board.job or None,
        "layers": [{"file": layer.file, "role": layer.role, "why": layer.why}
                   for layer in board.layers],
        "unplaced": [{"file": u.file, "why": u.why} for u in board.unplaced],
        "ignored": [{"file": u.file, "why": u.why} for u in board.ignored],
        "size_mm": None if box is None else {"x": _mm(box[2] - box[0]), "y": _mm(box[3] - box[1])},
        "size_from": measured or None,
        "bbox_mm": _box_mm(box),
        "holes_bbox_mm": _box_mm(holes_box),
        "holes": None,
    }
    if read_drill is not None:
        holes, slots = hole_counts(drills)
        summary["holes"] = [
            {"diameter_mm": _mm(d), "holes": holes.get(d, 0), "slots": slots.get(d, 0)}
            for d in sorted(set(holes) | set(slots))]
    summary["problems"] = problems
    return summary


def _count(n: int, what: str) -> str:
    return "" if not n else f"{n} {what}" + ("s" if n > 1 else "")


def board_text(summary: dict) -> str:
    """`info BOARD` as a user reads it."""
    lines = [f"board {summary['source']}"
             + (f" (job file {summary['job_file']})" if summary["job_file"] else "")]
    width = max((len(layer["file"]) for layer in summary["layers"]), default=0)
    for layer in summary["layers"]:
        lines.append(f"  {layer['file']:<{width}}  {layer['role']:<14}  {layer['why']}")
    for entry in summary["unplaced"]:
        lines.append(f"  {entry['file']}: not placed: {entry['why']}; "
                     f"--layer {entry['file']}=ROLE places it")
    if summary["ignored"]:
        lines.append("  not board files: " + ", ".join(e["file"] for e in summary["ignored"]))
    size = summary["size_mm"]
    lines.append("size: unknown (no outline, copper or holes read)" if size is None else
                 f"size: {size['x']:g} x {size['y']:g} mm (from the {summary['size_from']})")
    if summary["holes"] is not None:
        total = sum(h["holes"] for h in summary["holes"])
        slots = sum(h["slots"] for h in summary["holes"])
        lines.append(f"holes: {total}" + (f", slots: {slots}" if slots else "")
                     + (" (none)" if not summary["holes"] else ""))
        for h in summary["holes"]:
            counts = [_count(h["holes"], "hole"), _count(h["slots"], "slot")]
            lines.append(f"  {h['diameter_mm']:g} mm: " + ", ".join(c for c in counts if c))
    for problem in summary["problems"]:
        lines.append(f"warning: {problem}")
    return "\n".join(lines)


def describe_board(path, overrides=(), read_drill: Callable[[str], DrillFile] | None = None
                   ) -> tuple[str, dict]:
    """(text, {"board": summary}) of the board at `path` (folder, .zip or .gbrjob)."""
    board = open_board(path, overrides)
    try:
        summary = board_summary(board, read_drill)
    finally:
        board.close()
    return board_text(summary), {"board": summary}
