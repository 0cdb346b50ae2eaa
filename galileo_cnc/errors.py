"""Error and warning types shared by the whole package.

Every error a user can cause derives from `GalileoError`, so the CLI can print it
as one line and exit non-zero instead of showing a traceback. Reader errors carry
the position in the source file and a short excerpt of the offending text.
"""

from __future__ import annotations

from dataclasses import dataclass

EXCERPT_CHARS = 60


class GalileoError(Exception):
    """Base of every error the user can cause (bad file, bad command, bad port)."""


@dataclass(frozen=True, slots=True)
class SourcePos:
    """Where something came from: 1-based line and column in a named file."""

    file: str
    line: int
    col: int

    def __str__(self) -> str:
        if self.line <= 0:          # about the whole file (a DXF header left out)
            return self.file
        return f"{self.file}:{self.line}:{self.col}"


def excerpt(text: str, limit: int = EXCERPT_CHARS) -> str:
    """A one-line, shortened copy of `text` for diagnostics."""
    text = text.replace("\r", "").replace("\n", " ").strip()
    return text if len(text) <= limit else text[: limit - 3] + "..."


class ReaderError(GalileoError):
    """A file could not be read: names file:line:col, what was expected, and the text."""

    def __init__(self, pos: SourcePos, message: str, text: str = ""):
        self.pos = pos
        self.message = message
        self.text = excerpt(text)
        super().__init__(str(self))

    def __str__(self) -> str:
        tail = f"\n    {self.text}" if self.text else ""
        return f"{self.pos}: {self.message}{tail}"


class GerberError(ReaderError):
    """Malformed RS-274X input."""


class GcodeError(ReaderError):
    """Malformed or unsupported G-code input."""


class UnknownFormatError(GalileoError):
    """A file is neither Gerber nor G-code."""


@dataclass(frozen=True, slots=True)
class ReaderWarning:
    """A tolerated oddity in the input, kept with its position so it can be shown."""

    pos: SourcePos
    message: str
    text: str = ""

    def __str__(self) -> str:
        tail = f"  [{self.text}]" if self.text else ""
        return f"{self.pos}: warning: {self.message}{tail}"
