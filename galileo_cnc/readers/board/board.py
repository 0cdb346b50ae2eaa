"""A board: the files that make it (a folder, a .zip or a Gerber job file) and each one's role.

Files are found in the folder and its subfolders (MAX_DEPTH deep, MAX_FILES at most).
A .zip is read member by member: a name that climbs out (`../`, an absolute path, a
drive) is refused, and each member is bounded like a file (readers/limits.py,
$GALILEO_MAX_FILE_MB), the whole archive by MAX_ZIP_FACTOR times that. Its members
are written to a private temporary folder that lives as long as the Board.

Each file's role comes from roles.place (X2, job file, header, name); a numbered copper
layer (`L02`, `Layer3`) is inner unless it is layer 1 or the board has no bottom copper
to tell it from. Files that are neither Gerber nor Excellon (read-me, job file) are
`ignored`; Gerber or Excellon files that nothing places are `unplaced`, by name, until
an override `FILE=ROLE` (the command line's `--layer`) places them.
"""

from __future__ import annotations

import json
import os
import stat
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from galileo_cnc.errors import GalileoError
from galileo_cnc.readers import limits
from galileo_cnc.readers.board.names import Placement
from galileo_cnc.readers.board.roles import DRILL_ROLES, HEAD_BYTES, ROLES, file_kind, place
from galileo_cnc.readers.source import decode, first_binary_byte

MAX_DEPTH = 3
MAX_FILES = 500
MAX_ZIP_FACTOR = 4


class BoardError(GalileoError):
    """A board that cannot be opened, or an override that names no file or no role."""


@dataclass(frozen=True, slots=True)
class Layer:
    """One file of the board: its name inside the board, where it is, role and why."""

    file: str
    path: Path
    role: str
    why: str
    kind: str          # "gerber" or "excellon"


@dataclass(frozen=True, slots=True)
class Unplaced:
    file: str
    path: Path
    kind: str          # "gerber", "excellon", or "" when neither
    why: str


@dataclass
class Board:
    source: str
    root: Path
    layers: list[Layer] = field(default_factory=list)
    unplaced: list[Unplaced] = field(default_factory=list)   # Gerber/Excellon, no role
    ignored: list[Unplaced] = field(default_factory=list)    # neither Gerber nor Excellon
    job: str = ""                                            # the job file used, if any
    _keep: object = None                                     # a zip's temporary folder

    def files(self, role: str) -> list[Layer]:
        _check_role(role, "")
        return [layer for layer in self.layers if layer.role == role]

    def copper(self, side: str) -> list[Layer]:
        """The copper of a side: 'top', 'bottom' or 'inner'."""
        if side not in ("top", "bottom", "inner"):
            raise BoardError(f"no side '{side}': top, bottom or inner")
        return self.files(f"{side}-copper")

    def drills(self) -> list[Layer]:
        return [layer for layer in self.layers if layer.role in DRILL_ROLES]

    def outline(self) -> list[Layer]:
        return self.files("outline")

    def close(self) -> None:
        if self._keep is not None:
            self._keep.cleanup()
            self._keep = None


def _check_role(role: str, file: str) -> None:
    if role not in ROLES:
        what = f"--layer {file}={role}: " if file else ""
        raise BoardError(f"{what}no role '{role}'; the roles are {', '.join(ROLES)}")


def is_board(path: str | os.PathLike) -> bool:
    """A folder, a .zip or a .gbrjob: what open_board opens (a file is read alone)."""
    where = Path(os.fsdecode(path))
    return where.is_dir() or (where.is_file() and where.suffix.lower() in (".zip", ".gbrjob"))


def open_board(path: str | os.PathLike, overrides: tuple[str, ...] | list[str] = ()) -> Board:
    """The board in a folder, a .zip or beside a .gbrjob, with `FILE=ROLE` overrides applied."""
    source = os.fsdecode(path)
    where = Path(source)
    keep = None
    job_file = None
    if where.is_dir():
        root = where
    elif where.is_file() and where.suffix.lower() == ".zip":
        keep = tempfile.TemporaryDirectory(prefix="galileo-board-")
        root = Path(keep.name)
        _unzip(where, root)
    elif where.is_file() and where.suffix.lower() == ".gbrjob":
        root, job_file = where.parent, where
    elif where.exists():
        raise BoardError(f"{source}: a board is a folder, a .zip or a .gbrjob file")
    else:
        raise BoardError(f"{source}: no such folder or file")
    names = _board_files(root)
    if job_file is None:
        jobs = [n for n in names if n.lower().endswith(".gbrjob")]
        job_file = root / jobs[0] if len(jobs) == 1 else None
    job = _job_functions(job_file, source) if job_file else {}
    board = Board(source, root, job=job_file.name if job_file else "", _keep=keep)
    placed: list[tuple[str, Placement, str]] = []
    for name in names:
        if name.lower().endswith(".gbrjob"):
            continue
        head = _head(root / name, name)
        kind = file_kind(head) if head is not None else None
        if kind is None:
            board.ignored.append(Unplaced(name, root / name, "", "neither Gerber nor Excellon"))
            continue
        found = place(name, head, kind, job)
        if found is None:
            board.unplaced.append(Unplaced(name, root / name, kind,
                                           "no X2 attribute, header or name tells its role"))
        else:
            placed.append((name, found, kind))
    _settle_numbered(board, placed)
    _apply_overrides(board, overrides)
    return board


def _settle_numbered(board: Board, placed: list[tuple[str, Placement, str]]) -> None:
    """Numbered copper (layer n > 1 by name) is inner when the board names its bottom."""
    has_bottom = any(p.role == "bottom-copper" for _, p, _ in placed)
    highest = max((p.layer for _, p, _ in placed if p.layer > 1), default=0)
    for name, found, kind in placed:
        if found.layer > 1 and not has_bottom and found.layer == highest:
            board.unplaced.append(Unplaced(
                name, board.root / name, kind, f"copper layer {found.layer} by its name, and "
                "no file is the bottom copper: the bottom, or an inner layer?"))
            continue
        board.layers.append(Layer(name, board.root / name, found.role, found.why, kind))


def _apply_overrides(board: Board, overrides) -> None:
    for text in overrides:
        file, equals, role = text.partition("=")
        file, role = file.strip(), role.strip()
        if not equals or not file:
            raise BoardError(f"--layer {text}: write FILE=ROLE, e.g. board.gbl=bottom-copper")
        _check_role(role, file)
        everything = ([(layer.file, layer.path, layer.kind) for layer in board.layers]
                      + [(u.file, u.path, u.kind) for u in board.unplaced + board.ignored])
        matches = [entry for entry in everything
                   if entry[0] == file or PurePosixPath(entry[0]).name == file]
        if len(matches) != 1:
            known = ", ".join(sorted(entry[0] for entry in everything)) or "none"
            how = "no file" if not matches else "more than one file"
            raise BoardError(f"--layer {file}={role}: {how} of the board {board.source} is "
                             f"named '{file}' (its files: {known})")
        name, path, kind = matches[0]
        board.layers = [layer for layer in board.layers if layer.file != name]
        board.unplaced = [u for u in board.unplaced if u.file != name]
        board.ignored = [u for u in board.ignored if u.file != name]
        board.layers.append(Layer(name, path, role, f"--layer {name}={role}", kind))
    board.layers.sort(key=lambda layer: (ROLES.index(layer.role), layer.file))


def _board_files(root: Path) -> list[str]:
    names: list[str] = []
    base = len(root.parts)
    for folder, dirs, files in os.walk(root):
        depth = len(Path(folder).parts) - base
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and depth < MAX_DEPTH)
        for file in sorted(files):
            if file.startswith("."):
                continue
            names.append(Path(folder, file).relative_to(root).as_posix())
            if len(names) > MAX_FILES:
                raise BoardError(f"{root}: more than {MAX_FILES} files; a board has a few dozen")
    return names


def _head(path: Path, name: str) -> str | None:
    """The first HEAD_BYTES of a regular text file, or None for anything else."""
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            return None
        with open(path, "rb") as handle:
            data = handle.read(HEAD_BYTES)
    except OSError as problem:
        raise BoardError(f"{name}: cannot read: {problem.strerror or problem}") from None
    if first_binary_byte(data) is not None:
        return None   # a picture, a PDF, an archive: not a layer
    return decode(data)


def _job_functions(job_file: Path, source: str) -> dict[str, str]:
    """File name -> FileFunction, from a Gerber job file's FilesAttributes."""
    try:
        with open(job_file, "rb") as handle:
            data = handle.read(limits.max_file_bytes() + 1)
        job = json.loads(decode(data))
    except (OSError, ValueError) as problem:
        raise BoardError(f"{job_file.name}: not a Gerber job file (JSON): {problem}") from None
    result = {}
    entries = job.get("FilesAttributes", []) if isinstance(job, dict) else []
    for entry in entries if isinstance(entries, list) else []:
        if isinstance(entry, dict) and isinstance(entry.get("Path"), str) \
                and isinstance(entry.get("FileFunction"), str):
            result[entry["Path"].replace("\\", "/")] = entry["FileFunction"]
    return result


def _unzip(archive: Path, into: Path) -> None:
    """Write a zip's members under `into`, refusing names that climb out and oversized members."""
    per_file = limits.max_file_bytes()
    total_limit = per_file * MAX_ZIP_FACTOR
    total = 0
    try:
        with zipfile.ZipFile(archive) as zipped:
            members = [m for m in zipped.infolist() if not m.is_dir()]
            if len(members) > MAX_FILES:
                raise BoardError(f"{archive}: more than {MAX_FILES} members; a board has a "
                                 "few dozen")
            for member in members:
                name = member.filename.replace("\\", "/")
                parts = PurePosixPath(name).parts
                if (name.startswith("/") or ".." in parts or (parts and ":" in parts[0])
                        or not parts):
                    raise BoardError(f"{archive}: member '{member.filename}' would be written "
                                     "outside the board's folder; refused")
                if member.file_size > per_file:
                    size_mb = member.file_size / 2**20
                    raise BoardError(f"{archive}: member '{name}' has {size_mb:,.0f} MB, more "
                                     f"than the {per_file // 2**20:,} MB limit (set "
                                     f"{limits.MAX_FILE_MB_ENV}=<MB> to raise it)")
                with zipped.open(member) as handle:
                    data = handle.read(per_file + 1)
                total += len(data)
                if len(data) > per_file or total > total_limit:
                    raise BoardError(f"{archive}: member '{name}' unpacks to more than the "
                                     "limit; refused")
                target = into.joinpath(*parts)
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(data)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, RuntimeError,
            NotImplementedError) as problem:
        raise BoardError(f"{archive}: cannot read the zip: {problem}") from None
