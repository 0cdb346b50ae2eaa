"""Excellon drill and route files (NC drill), read into a DrillFile in integer nm."""

from __future__ import annotations

from galileo_cnc.readers.excellon.reader import ExcellonError, looks_like_excellon, read_excellon

__all__ = ["ExcellonError", "looks_like_excellon", "read_excellon"]
