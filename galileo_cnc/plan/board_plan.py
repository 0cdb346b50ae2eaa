"""A board's side as one job: `plot BOARD --side top|bottom`, `getg BOARD`.

The board (readers/board/: a folder, a .zip or a .gbrjob) gives the side's copper,
every drill file's holes and slots (readers/excellon/), the outline and, asked for,
the side's silkscreen; plan_file then leaves the holes' drill marks bare in the ink,
mirrors the bottom about the axis, offsets both sides by one offset and draws the
outline and silk after the copper (pipeline.py, sides.py, drill_marks.py,
board_lines.py).
The job's source becomes the board and `job.board` the user's choices
(BoardChoice), so the journal keeps both and a resume plans the same side again.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.drill_marks import DEFAULT_DRILL_MARK_NM
from galileo_cnc.plan.pipeline import OffsetChoice, PlannedFile, PlanOptions, plan_file
from galileo_cnc.plan.transform import reach_box
from galileo_cnc.program.drills import Hole, Slot
from galileo_cnc.program.extents import union_box
from galileo_cnc.program.ops import Program
from galileo_cnc.readers import read_drill, read_file
from galileo_cnc.readers.board import Board, BoardError, is_board, open_board

#: zip boards stay unpacked while the program runs: messages, previews and a resume
#: in the same session name their files; the last KEPT_UNPACKED planned only (a
#: server plans many), and none that failed to plan
_UNPACKED: list[Board] = []
KEPT_UNPACKED = 4


def _keep_unpacked(board: Board) -> None:
    _UNPACKED.append(board)
    while len(_UNPACKED) > KEPT_UNPACKED:
        _UNPACKED.pop(0).close()


@dataclass(frozen=True)
class BoardChoice:
    """What the user chose for a board: the side, the drill marks, the mirror axis
    (("x" | "y", nm) in board coordinates; None: the default), registration
    crosses, `FILE=ROLE` overrides of the files' roles, and whether the outline and
    the side's silkscreen are drawn after the copper."""

    side: str = "top"
    drill_marks: str = "small"
    drill_mark_nm: int = DEFAULT_DRILL_MARK_NM
    mirror_axis: tuple[str, int] | None = None
    registration: bool = False
    layers: tuple[str, ...] = ()
    outline: bool = False
    silk: bool = False

    def as_dict(self) -> dict:
        """For job.board and the journal (JSON)."""
        data = dataclasses.asdict(self)
        data["mirror_axis"] = list(self.mirror_axis) if self.mirror_axis else None
        data["layers"] = list(self.layers)
        return data

    @classmethod
    def from_dict(cls, data: dict) -> "BoardChoice":
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise BoardError(f"the journal's board has unknown keys {', '.join(unknown)}")
        axis = data.get("mirror_axis")
        return cls(**{**data, "mirror_axis": (str(axis[0]), int(axis[1])) if axis else None,
                      "layers": tuple(data.get("layers") or ())})

    def other_side(self) -> "BoardChoice":
        return dataclasses.replace(self, side="bottom" if self.side == "top" else "top")


def is_board_job(job) -> bool:
    return getattr(job, "board", None) is not None


def board_holes(board: Board) -> list[Hole | Slot]:
    """Every drill file's holes and slots; a file's role says its plating when the
    file does not (drill-plated, drill-unplated)."""
    drills: list[Hole | Slot] = []
    for layer in board.drills():
        drill = read_drill(str(layer.path))
        plated = {"drill-plated": True, "drill-unplated": False}.get(layer.role)
        for item in (*drill.holes, *drill.slots):
            if item.plated is None and plated is not None:
                item = dataclasses.replace(item, plated=plated)
            drills.append(item)
    return drills


def _one(board: Board, role: str, required: bool) -> Path | None:
    files = board.files(role)
    if len(files) > 1:
        raise BoardError(f"{board.source}: {len(files)} files are {role} "
                         f"({', '.join(f.file for f in files)}): --layer FILE=other leaves "
                         f"one out")
    if not files:
        if required:
            raise BoardError(f"{board.source}: no file is {role} (info BOARD lists the "
                             f"files; --layer FILE={role} places one)")
        return None
    return files[0].path


def side_options(board: Board, choice: BoardChoice,
                 options: PlanOptions = PlanOptions()) -> tuple[Program, PlanOptions]:
    """The side's copper, read, and the options that plan it as part of the board
    (each layer read once: the side's copper is also one of the board's box)."""
    side_path = _one(board, f"{choice.side}-copper", required=True)
    copper = None
    boxes = []
    # with --silk both sides' silk counts in the box: the one offset fits both sides
    roles = ("top-copper", "bottom-copper", "outline") + \
        (("top-silk", "bottom-silk") if choice.silk else ())
    if choice.silk and not any(board.files(role) for role in roles[3:]):
        raise BoardError(f"{board.source}: --silk: no file is top-silk or bottom-silk "
                         f"(info BOARD lists the files; --layer FILE=top-silk places one)")
    if choice.outline and not board.files("outline"):
        raise BoardError(f"{board.source}: --outline: no file is outline (info BOARD "
                         f"lists the files; --layer FILE=outline places one)")
    for role in roles:
        path = _one(board, role, required=False)
        if path is None:
            continue
        program = read_file(path)
        boxes.append(reach_box(program))
        if path == side_path:
            copper = program
        if role == "outline":
            options = dataclasses.replace(options, outline_program=program)
        if role == f"{choice.side}-silk":
            options = dataclasses.replace(options, silk_program=program)
    return copper, dataclasses.replace(
        options, holes=tuple(board_holes(board)), drill_marks=choice.drill_marks,
        drill_mark_nm=choice.drill_mark_nm, side=choice.side, mirror_axis=choice.mirror_axis,
        registration=choice.registration, board_box_nm=union_box(*boxes),
        outline=choice.outline)


def plan_board(path: str | os.PathLike, config: MachineConfig | None = None,
               offset: OffsetChoice = "auto", *, choice: BoardChoice = BoardChoice(),
               options: PlanOptions = PlanOptions(), **kwargs) -> PlannedFile:
    """The board at `path`, one side planned (plan_file's keywords pass through)."""
    board = open_board(path, choice.layers)
    planned = None
    try:
        copper, side = side_options(board, choice, options)
        planned = plan_file(copper, config, offset, options=side, **kwargs)
        if choice.silk and side.silk_program is None:
            planned = dataclasses.replace(planned, line_warnings=(
                *planned.line_warnings, f"--silk: no file is {choice.side}-silk: no silk "
                f"on the {choice.side} side"))
    finally:
        if planned is not None and Path(path).suffix.lower() == ".zip":
            _keep_unpacked(board)
        else:
            board.close()
    planned.job.source = str(Path(path).resolve())
    planned.job.board = choice.as_dict()
    return planned


def copper_sides(path: str | os.PathLike, layers: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The sides of the board at `path` that have copper: ("top", "bottom"), ("top",)
    for a one-sided board (or ("bottom",))."""
    board = open_board(path, layers)
    try:
        return tuple(side for side in ("top", "bottom") if board.copper(side))
    finally:
        board.close()


def plan_source(source: str | os.PathLike, config: MachineConfig | None = None,
                offset: OffsetChoice = "auto", *, board: BoardChoice | None = None,
                options: PlanOptions = PlanOptions(), **kwargs) -> PlannedFile:
    """plan_file for a file, plan_board for a board (a folder, .zip or .gbrjob);
    `board` None on a board: its top side with the defaults."""
    if is_board(source):
        return plan_board(source, config, offset, choice=board or BoardChoice(),
                          options=options, **kwargs)
    if board is not None:
        raise BoardError(f"{os.fsdecode(source)}: --side, --drill-marks, --mirror-axis, "
                         f"--registration, --outline, --silk and --layer are for a board "
                         f"(a folder, .zip or .gbrjob), and this is one file")
    return plan_file(source, config, offset, options=options, **kwargs)
