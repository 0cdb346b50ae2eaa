"""ezdxf parses the file: `ezdxf.readfile`, and `ezdxf.recover.readfile` for damaged
files that the structural scan (scan.py) let through. ezdxf's log messages are
collected here instead of going to stderr."""

from __future__ import annotations

import logging
import re
from contextlib import contextmanager

import ezdxf
from ezdxf import recover

from galileo_cnc.errors import SourcePos
from galileo_cnc.readers.dxf.errors import DxfError

_LINE = re.compile(r"line:? (\d+)", re.IGNORECASE)


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.messages.append(record.getMessage())
        except Exception:  # a broken log record must not break the read
            pass


@contextmanager
def _quiet_ezdxf():
    logger = logging.getLogger("ezdxf")
    handler = _Collect()
    propagate = logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield handler.messages
    finally:
        logger.removeHandler(handler)
        logger.propagate = propagate


def line_in(message: str) -> int:
    """The line number an ezdxf message names ('... at line 273', 'near line: 60'), or 0."""
    found = _LINE.search(message)
    return int(found.group(1)) if found else 0


def load(path: str) -> tuple[object, list[tuple[int, str]], bool]:
    """(drawing, [(line, warning)], recovered). Raises DxfError when ezdxf cannot read
    the file even in recover mode, or recovers it only by changing its values."""
    warnings: list[tuple[int, str]] = []
    with _quiet_ezdxf() as log:
        try:
            return ezdxf.readfile(path), _log_warnings(log), False
        except OSError as problem:
            raise DxfError(SourcePos(path, 0, 0),
                           f"cannot read the file: {problem.strerror or problem}") from None
        except Exception as problem:  # ezdxf raises many kinds for bad input
            first = _describe(problem)
        try:
            doc, auditor = recover.readfile(path)
        except Exception as problem:
            message = _describe(problem)
            line = line_in(message) or line_in(first)
            raise DxfError(SourcePos(path, max(line, 1), 1),
                           f"not a readable DXF file: {message}") from None
    if auditor.has_errors:
        error = auditor.errors[0]
        raise DxfError(SourcePos(path, max(line_in(error.message), 1), 1),
                       f"damaged DXF file: {error.message} ({len(auditor.errors)} such errors)")
    warnings.append((line_in(first), f"damaged DXF file read in ezdxf's recover mode "
                     f"({first}; {len(auditor.fixes)} fixes)"))
    return doc, warnings + _log_warnings(log), True


def _describe(problem: Exception) -> str:
    text = str(problem).replace("\n", " ").strip()
    text = text.removeprefix("DXFStructureError: ")
    return f"{type(problem).__name__}: {text}" if not text.startswith(type(problem).__name__) \
        else text


def _log_warnings(messages: list[str]) -> list[tuple[int, str]]:
    seen: dict[str, int] = {}
    for message in messages:
        key = re.sub(r"#[0-9A-Fa-f]+", "#…", message)
        seen[key] = seen.get(key, 0) + 1
    return [(0, f"ezdxf: {key}" + (f" ({count} times)" if count > 1 else ""))
            for key, count in seen.items()]
