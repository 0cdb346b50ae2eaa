"""The job journal: what was sent and confirmed, so an interrupted job can resume.

One small JSON file in the user's data directory (userdirs.data_dir:
$GALILEO_CNC_HOME, else $XDG_DATA_HOME/galileo-cnc or ~/.local/share/galileo-cnc). It records the
file (path and SHA-256), the offset, the machine profile, the number of
commands, the last command the machine confirmed (`ok`: planned into its
queue), and the sequence number the session's first line carried, so that the
machine's own "last accepted line" (its status `N`, read before a new session
restarts the count) can move the mark forward when the port died before a
reply reached us.

Resuming replans the same file with the same offset and profile (the planner is
deterministic), checks the machine stands where the confirmed commands leave
it, and sends the rest: no move is repeated and none is skipped.

A milling job cut with a height map (plan/mill/heightmap.py) keeps the map beside the
journal (journal.heightmap.json beside journal.json) and its SHA-256 in the entry: the
corrected lines are a function of the map, so a resume corrects the rest of the job by
the same map, never a new probing (`Journal.height_map`).
"""

from __future__ import annotations

import hashlib
import json
import re
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from galileo_cnc import protocol as P
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.mill.heightmap import HeightMap, HeightMapError

JOURNAL_NAME = "journal.json"
#: the height map's file: the journal's name with this suffix
HEIGHT_MAP_SUFFIX = ".heightmap.json"
#: Write at most this often while streaming (and always when the job stops).
WRITE_INTERVAL_S = 0.25

RUNNING, INTERRUPTED, FINISHED, ABORTED, FAILED, RESET = (
    "running", "interrupted", "finished", "aborted", "failed", "reset")


def file_digest(path: str | os.PathLike) -> str:
    """SHA-256 of a file; of a folder (a board), of its files' names and bytes, in
    name order, so a board changed in any file is another board."""
    digest = hashlib.sha256()
    root = Path(path)
    files = sorted(p for p in root.rglob("*") if p.is_file()) if root.is_dir() else [root]
    for file in files:
        if root.is_dir():
            digest.update(file.relative_to(root).as_posix().encode() + b"\0")
        with open(file, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


@dataclass
class JournalEntry:
    source: str                     # absolute path of the file
    digest: str                     # its SHA-256 when the job was planned
    offset_nm: tuple[int, int]
    profile: str                    # the machine profile as TOML
    group: bool                     # planned grouped by aperture
    total: int                      # commands in the job
    confirmed: int                  # last command index the machine confirmed (-1: none)
    first_index: int                # command index and sequence number of the
    first_seq: int                  # session's first job line
    state: str = RUNNING
    reason: str = ""
    updated: float = 0.0
    #: work position (steps) where the job began: its first move starts from there
    start_position: tuple[int, int, int] = (0, 0, 0)
    #: "ink" or "centre": how the artwork became pen paths (older journals: centre)
    mode: str = "centre"
    #: paths chained and ordered by the planner (older journals: not)
    ordered: bool = False
    #: ink mode: the pens (nm) the job was inked for
    pens_nm: tuple = ()
    #: DXF: the layers read (empty: all) and the units given instead of $INSUNITS
    layers: tuple = ()
    units: str | None = None
    #: the job's frame is the homed one (`plot --home` homed the machine before it,
    #: so homing again finds it after a reset); older journals: not
    homed: bool = False
    #: the drawing scaled (an exact fraction, "4/5") and turned clockwise before the
    #: offset (plan/transform.py); older journals: neither
    scale: str = "1"
    rotate_deg: int = 0
    #: a stopped job (q, Ctrl-C): the work position (steps) where the machine stood
    #: once it ramped down, before the pen was lifted there; None: not stopped so
    stopped_at: tuple | None = None
    #: a board's side (plan/board_plan.py's BoardChoice as a dict): `source` is then the
    #: board (folder, .zip or .gbrjob); None: a file alone (older journals: none)
    board: dict | None = None
    #: a milling job cut with a height map: the SHA-256 of the map's file beside the
    #: journal (Journal.height_map); None: no map (older journals: none)
    height_map: str | None = None

    def index_of_seq(self, seq: int) -> int | None:
        """The command a sequence number of this session would belong to (the
        caller confirms it by the machine's position: another session may have
        restarted the count since)."""
        if not 1 <= seq <= P.SEQ_MAX:
            return None
        index = self.first_index + (seq - self.first_seq) % P.SEQ_MAX
        return index if self.first_index <= index < self.total else None


class JournalError(GalileoError):
    """The journal file exists but cannot be read or trusted."""


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number")


# What each field must be: (check, description). Tuples are JSON lists.
def _integer(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _integers(count: int | None):
    return lambda value: (isinstance(value, list) and (count is None or len(value) == count)
                          and all(_integer(v) for v in value))


_FIELD_CHECKS = {
    "source": (lambda v: isinstance(v, str), "text"),
    "digest": (lambda v: isinstance(v, str), "text"),
    "offset_nm": (_integers(2), "a list of 2 integers"),
    "profile": (lambda v: isinstance(v, str), "text"),
    "group": (lambda v: isinstance(v, bool), "true or false"),
    "total": (_integer, "an integer"),
    "confirmed": (_integer, "an integer"),
    "first_index": (_integer, "an integer"),
    "first_seq": (_integer, "an integer"),
    "state": (lambda v: v in (RUNNING, INTERRUPTED, FINISHED, ABORTED, FAILED, RESET),
              "one of running, interrupted, finished, aborted, failed, reset"),
    "reason": (lambda v: isinstance(v, str), "text"),
    "updated": (lambda v: (_integer(v) or isinstance(v, float)), "a number"),
    "start_position": (_integers(3), "a list of 3 integers"),
    "mode": (lambda v: v in ("ink", "centre"), "ink or centre"),
    "ordered": (lambda v: isinstance(v, bool), "true or false"),
    "pens_nm": (_integers(None), "a list of integers"),
    "layers": (lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v),
               "a list of layer names"),
    "units": (lambda v: v is None or v in ("mm", "in"), "null, mm or in"),
    "homed": (lambda v: isinstance(v, bool), "true or false"),
    "scale": (lambda v: isinstance(v, str) and re.fullmatch(r"[1-9][0-9]*(/[1-9][0-9]*)?", v)
              is not None, "a fraction such as 4/5"),
    "rotate_deg": (lambda v: v in (0, 90, 180, 270), "0, 90, 180 or 270"),
    "stopped_at": (lambda v: v is None or _integers(3)(v), "null or a list of 3 integers"),
    "board": (lambda v: v is None or (isinstance(v, dict) and all(isinstance(k, str) for k in v)),
              "null or the board's side and choices"),
    "height_map": (lambda v: v is None or (isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v)
                                            is not None), "null or a SHA-256 in hex"),
}
_REQUIRED = ("source", "digest", "offset_nm", "profile", "group", "total", "confirmed",
             "first_index", "first_seq")
_TUPLES = ("offset_nm", "start_position", "pens_nm", "layers", "stopped_at")


def _checked_fields(data: dict, damaged) -> dict:
    """The journal's fields, each of the type JournalEntry needs, or damaged(what)."""
    missing = [name for name in _REQUIRED if name not in data]
    if missing:
        raise damaged(f"missing {', '.join(missing)}")
    fields = {}
    for name, value in data.items():
        check = _FIELD_CHECKS.get(name)
        if check is None:
            raise damaged(f"unknown key {name!r}")
        if not check[0](value):
            raise damaged(f"{name} must be {check[1]}, got {json.dumps(value)[:40]}")
        fields[name] = tuple(value) if name in _TUPLES and value is not None else value
    if not -1 <= fields["confirmed"] < max(fields["total"], 0) or fields["total"] < 0:
        raise damaged(f"confirmed command {fields['confirmed']} is outside the job's "
                      f"{fields['total']} commands")
    return fields


class Journal:
    """Reads and writes the journal file (atomically: write a copy, then rename)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self.entry: JournalEntry | None = None
        self._written = 0.0

    @classmethod
    def default(cls) -> "Journal":
        return cls(data_dir() / JOURNAL_NAME)

    def pending(self) -> JournalEntry | None:
        """The last job if it did not finish (running when the port or host died,
        interrupted, failed, aborted or reset), else None."""
        entry = self.load()
        return entry if entry is not None and entry.state != FINISHED else None

    def load(self) -> JournalEntry | None:
        """The entry, None when there is no journal; JournalError naming the file
        and the key when there is one that cannot be trusted (a resume from a damaged
        journal could repeat or skip moves)."""
        try:
            raw = self.path.read_bytes()
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise JournalError(f"{self.path}: cannot read the job journal: {exc.strerror}") \
                from None
        try:
            data = json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
        except UnicodeDecodeError as exc:
            raise self._damaged(f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset "
                                f"{exc.start})") from None
        except ValueError as exc:
            raise self._damaged(f"not JSON ({exc})") from None
        if not isinstance(data, dict):
            raise self._damaged("expected a JSON object")
        return JournalEntry(**_checked_fields(data, self._damaged))

    def _damaged(self, what: str) -> "JournalError":
        return JournalError(f"{self.path}: damaged job journal: {what} (delete it to start "
                            "afresh; the interrupted job then cannot be resumed)")

    def begin(self, entry: JournalEntry, height_map: HeightMap | None = None) -> None:
        """A job's session: its entry, and for a new job the height map its lines were
        corrected by (kept beside the journal, its digest in the entry). An interrupted
        job going on keeps its map (its entry names it); a job without one removes a
        stale map."""
        self.entry = entry
        if height_map is not None:
            entry.height_map = self._write_height_map(height_map)
        elif entry.height_map is None:
            self.height_map_path.unlink(missing_ok=True)
        self.write()

    @property
    def height_map_path(self) -> Path:
        return self.path.with_suffix(HEIGHT_MAP_SUFFIX)

    def _write_height_map(self, height_map: HeightMap) -> str:
        text = json.dumps(height_map.to_json())
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temp = self.height_map_path.with_suffix(".tmp")
        temp.write_text(text)
        os.replace(temp, self.height_map_path)
        return hashlib.sha256(text.encode()).hexdigest()

    def height_map(self, entry: JournalEntry) -> HeightMap | None:
        """The height map `entry`'s job was corrected by, None when it had none;
        JournalError when the map's file is gone, changed or damaged: the job cannot
        resume by another map (its depths would jump where the old one left off)."""
        if entry.height_map is None:
            return None
        path = self.height_map_path
        refuse = (f"the job was cut with a height map kept in {path}, which is "
                  f"{{}}: it cannot resume by another map (the depths would jump where it "
                  f"left off); delete the journal to start afresh, probing again")
        try:
            raw = path.read_bytes()
        except FileNotFoundError:
            raise JournalError(refuse.format("missing")) from None
        except OSError as exc:
            raise JournalError(refuse.format(f"unreadable ({exc.strerror})")) from None
        if hashlib.sha256(raw).hexdigest() != entry.height_map:
            raise JournalError(refuse.format("not the one the journal names (changed since)"))
        try:
            return HeightMap.from_json(json.loads(raw.decode("utf-8")))
        except (ValueError, HeightMapError) as exc:
            raise JournalError(refuse.format(f"damaged ({exc})")) from None

    def confirm(self, index: int) -> None:
        self.entry.confirmed = index
        if time.monotonic() - self._written >= WRITE_INTERVAL_S:
            self.write()

    def end(self, state: str, reason: str = "") -> None:
        self.entry.state = state
        self.entry.reason = reason
        self.write()

    def write(self) -> None:
        self.entry.updated = time.time()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temp = self.path.with_suffix(".tmp")
        temp.write_text(json.dumps(asdict(self.entry), indent=1))
        os.replace(temp, self.path)
        self._written = time.monotonic()
