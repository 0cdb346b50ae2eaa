"""Uploaded files, kept in the user's data folder under names the server chooses.

A client sends the bytes and, for the page's eyes only, the name it had; nothing it
sends names a path here. What the bytes are is read from them, not from the name:
a .zip must be a board (readers/board/: its files' roles, some copper), anything else
Gerber, G-code or DXF as readers.detect_format finds it. Too large a file is refused
before it is all read.
"""

from __future__ import annotations

import json
import re
import secrets
from dataclasses import asdict, dataclass
from pathlib import Path
from urllib.parse import unquote

from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.errors import GalileoError
from galileo_cnc.readers import detect_format
from galileo_cnc.readers.source import decode, first_binary_byte

#: the largest upload taken (a whole board's Gerber files zipped are a few MB)
MAX_UPLOAD_BYTES = 32 * 1024 * 1024
ZIP_MAGIC = b"PK\x03\x04"
EXTENSION = {"gerber": "gbr", "gcode": "nc", "dxf": "dxf", "board": "zip"}


class UploadRefused(GalileoError):
    """Why an upload was not kept (the HTTP status to answer with)."""

    def __init__(self, text: str, status: int = 415):
        super().__init__(text)
        self.status = status


@dataclass
class Upload:
    id: str
    name: str               # what the client called it (shown, never opened)
    kind: str               # "gerber", "gcode", "dxf" or "board"
    size: int
    sides: tuple[str, ...] = ()     # a board's sides with copper

    def public(self) -> dict:
        return asdict(self)


def display_name(name: str | None) -> str:
    """The client's name for a file, as text to show: its last part, printable. A
    header carries bytes, which Starlette reads as Latin-1: a client's UTF-8 (curl's
    `café.gbr`) is read back as UTF-8, the page's percent-escapes are undone."""
    name = name or ""
    try:
        name = name.encode("latin-1").decode("utf-8")
    except UnicodeError:
        pass                            # Latin-1 it was
    last = re.split(r"[\\/]", unquote(name))[-1]
    shown = re.sub(r"[^\w .,+()-]", "_", last)[:80].strip()
    return shown or "upload"


class UploadStore:
    """The uploads folder (data_dir()/uploads): `<id>.<ext>` and `<id>.json`."""

    def __init__(self, folder: Path | None = None, max_bytes: int = MAX_UPLOAD_BYTES):
        self.folder = folder if folder is not None else data_dir() / "uploads"
        self.max_bytes = max_bytes

    def path(self, upload: Upload) -> Path:
        return self.folder / f"{upload.id}.{EXTENSION[upload.kind]}"

    def get(self, upload_id: str) -> Upload:
        """UploadRefused (404) for an id that is not one of ours."""
        if not re.fullmatch(r"[0-9a-f]{16}", upload_id or ""):
            raise UploadRefused(f"no upload {upload_id!r}", 404)
        meta = self.folder / f"{upload_id}.json"
        if not meta.is_file():
            raise UploadRefused(f"no upload {upload_id!r}", 404)
        data = json.loads(meta.read_text())
        return Upload(**{**data, "sides": tuple(data.get("sides", ()))})

    def keep(self, data: bytes, name: str | None) -> Upload:
        """Check `data` and keep it; UploadRefused says why not."""
        if len(data) > self.max_bytes:
            raise too_large(self.max_bytes)
        if not data:
            raise UploadRefused("the file is empty", 400)
        shown = display_name(name)
        kind = "board" if data.startswith(ZIP_MAGIC) else _kind_of_text(data, shown)
        self.folder.mkdir(parents=True, exist_ok=True)
        upload = Upload(secrets.token_hex(8), shown, kind, len(data))
        path = self.path(upload)
        path.write_bytes(data)
        if kind == "board":
            try:
                upload.sides = _board_sides(path)
            except GalileoError as refused:
                path.unlink()
                raise UploadRefused(f"{shown}: {str(refused).replace(str(path), shown)}")
        (self.folder / f"{upload.id}.json").write_text(json.dumps(upload.public()))
        return upload


def too_large(max_bytes: int) -> UploadRefused:
    return UploadRefused(f"the file is larger than {max_bytes // (1024 * 1024)} MB", 413)


def _kind_of_text(data: bytes, shown: str) -> str:
    if first_binary_byte(data[:65_536]) is not None:
        raise UploadRefused(f"{shown}: not a Gerber, G-code or DXF file, nor a board (.zip): "
                            f"it holds binary data")
    kind = detect_format(decode(data[:65_536]))
    if kind == "excellon":
        raise UploadRefused(f"{shown}: a drill file alone draws nothing: upload the whole "
                            f"board as a .zip (its copper, outline and drill files)")
    if kind not in ("gerber", "gcode", "dxf"):
        raise UploadRefused(f"{shown}: not a Gerber, G-code or DXF file, nor a board (.zip)")
    return kind


def _board_sides(path: Path) -> tuple[str, ...]:
    from galileo_cnc.plan.board_plan import copper_sides

    sides = copper_sides(path)
    if not sides:
        raise UploadRefused("the .zip holds no copper layer (is it a board's Gerber files?)")
    return sides
