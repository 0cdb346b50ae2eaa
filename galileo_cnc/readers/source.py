"""Opening a file to read: only regular files, of a bounded size, holding text.

`/dev/zero` would be read until memory runs out and a FIFO would block forever, so
anything but a regular file is refused before it is opened (and checked again on
the open handle, which is opened non-blocking). A file bigger than the limit
(limits.MAX_FILE_MB, $GALILEO_MAX_FILE_MB) is refused before it is read. Bytes that
no text file holds (NUL and the other C0 controls but tab, line feed, vertical tab,
form feed and carriage return) make a positioned error at the first of them; a
trailing run of NUL or Ctrl-Z padding, which old CAD and DOS tools write after the
end, is text.
"""

from __future__ import annotations

import os
import re
import stat

from galileo_cnc.errors import GalileoError, ReaderError, SourcePos, UnknownFormatError
from galileo_cnc.readers import limits


class FileAccessError(GalileoError):
    """A path that cannot be read as a file: missing, not a regular file, too big."""

    def __init__(self, name: str, why: str):
        self.name, self.why = name, why
        super().__init__(f"{name}: cannot read: {why}")


class BinaryFileError(ReaderError):
    """The file holds bytes that are not text (the position points at the first)."""


class UnrecognisedFileError(ReaderError, UnknownFormatError):
    """Text that is none of the formats read here (positioned at its first line)."""


_NOT_TEXT = re.compile(rb"[\x00-\x08\x0e-\x1f]")
_NOT_TEXT_BYTES = bytes(b for b in range(0x20) if b not in b"\t\n\x0b\x0c\r")
_PADDING = b"\x00\x1a \t\r\n\x0b\x0c"
_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def _kind(mode: int) -> str:
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def _refuse(name: str, why: str) -> FileAccessError:
    return FileAccessError(name, why)


def read_bytes(path: str | os.PathLike) -> bytes:
    """The bytes of a regular file, or FileAccessError ('<path>: cannot read: why')."""
    name = os.fsdecode(path)
    try:
        mode = os.stat(name).st_mode
    except OSError as problem:
        raise _refuse(name, problem.strerror or str(problem)) from None
    if not stat.S_ISREG(mode):
        raise _refuse(name, f"it is {_kind(mode)}; only regular files are read")
    limit = limits.max_file_bytes()
    try:
        fd = os.open(name, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as problem:
        raise _refuse(name, problem.strerror or str(problem)) from None
    with os.fdopen(fd, "rb") as handle:
        info = os.fstat(handle.fileno())
        if not stat.S_ISREG(info.st_mode):  # replaced between the stat and the open
            raise _refuse(name, f"it is {_kind(info.st_mode)}; only regular files are read")
        if info.st_size > limit:
            raise _refuse(name, f"it has {info.st_size / 2**20:,.0f} MB, more than the "
                          f"{limit // 2**20:,} MB limit (set {limits.MAX_FILE_MB_ENV}=<MB> "
                          "to raise it)")
        data = handle.read(limit + 1)
    if len(data) > limit:  # grew while read
        raise _refuse(name, f"it has more than the {limit // 2**20:,} MB limit (set "
                      f"{limits.MAX_FILE_MB_ENV}=<MB> to raise it)")
    return data


def first_binary_byte(data: bytes) -> int | None:
    """Offset of the first byte that is not text, or None (trailing padding is text)."""
    if len(data.translate(None, _NOT_TEXT_BYTES)) == len(data):
        return None  # the common case, at memory speed (a regex search is ten times slower)
    found = _NOT_TEXT.search(data)
    if found is None:
        return None
    if not data[found.start():].strip(_PADDING):
        return None
    return found.start()


def binary_error(name: str, data: bytes, at: int, cls: type = BinaryFileError) -> ReaderError:
    """The error for a byte that is not text: `cls` (a ReaderError) at its line and column."""
    line = data.count(b"\n", 0, at) + 1
    col = at - (data.rfind(b"\n", 0, at) + 1) + 1
    return cls(SourcePos(name, line, col),
                           f"binary data: byte 0x{data[at]:02x} at offset {at} is not text "
                           "(Gerber, G-code and ASCII DXF files are text)")


def check_text(name: str, data: bytes, cls: type = BinaryFileError) -> None:
    """Raise `cls` at the first byte of `data` that is not text."""
    at = first_binary_byte(data)
    if at is not None:
        raise binary_error(name, data, at, cls)


def decode(data: bytes) -> str:
    """Text of a file: UTF-8, undecodable bytes as U+FFFD (harmless in comments)."""
    return data.decode("utf-8", errors="replace")


def read_text(path: str | os.PathLike, cls: type = BinaryFileError) -> str:
    """A regular text file's contents (checked as above; binary data raises `cls`)."""
    name = os.fsdecode(path)
    data = read_bytes(name)
    check_text(name, data, cls)
    return decode(data)
