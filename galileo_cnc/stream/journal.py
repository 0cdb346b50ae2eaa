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
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from galileo_cnc import protocol as P
from galileo_cnc.config.userdirs import data_dir

JOURNAL_NAME = "journal.json"
#: Write at most this often while streaming (and always when the job stops).
WRITE_INTERVAL_S = 0.25

RUNNING, INTERRUPTED, FINISHED, ABORTED, FAILED = (
    "running", "interrupted", "finished", "aborted", "failed")


def file_digest(path: str | os.PathLike) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
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

    def index_of_seq(self, seq: int) -> int | None:
        """The command a sequence number of this session would belong to (the
        caller confirms it by the machine's position: another session may have
        restarted the count since)."""
        if not 1 <= seq <= P.SEQ_MAX:
            return None
        index = self.first_index + (seq - self.first_seq) % P.SEQ_MAX
        return index if self.first_index <= index < self.total else None


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
        interrupted, failed or aborted), else None."""
        entry = self.load()
        return entry if entry is not None and entry.state != FINISHED else None

    def load(self) -> JournalEntry | None:
        try:
            data = json.loads(self.path.read_text())
            data["offset_nm"] = tuple(data["offset_nm"])
            data["start_position"] = tuple(data.get("start_position", (0, 0, 0)))
            return JournalEntry(**data)
        except (OSError, ValueError, TypeError, KeyError):
            return None

    def begin(self, entry: JournalEntry) -> None:
        self.entry = entry
        self.write()

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
