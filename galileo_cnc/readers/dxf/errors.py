"""The DXF reader's error type (a `ReaderError`: file:line:col, what, the text)."""

from __future__ import annotations

from galileo_cnc.errors import ReaderError


class DxfError(ReaderError):
    """Malformed, truncated or unreadable DXF input, or a request the file cannot meet
    (an unknown layer, an unknown unit)."""
