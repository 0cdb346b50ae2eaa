"""One build at a time in a folder: two galileo-cnc processes (or two test workers)
that both find the firmware out of date would otherwise run make over the same files,
or copy an ELF while the other reads it.

`with build_lock(folder):` holds an exclusive lock on folder/.build.lock until the
block ends; the next process waits, then finds the build done. Where fcntl is
missing (Windows), the block runs unlocked: a single user there builds one at a time.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

try:
    import fcntl
except ImportError:             # Windows
    fcntl = None

LOCK_NAME = ".build.lock"


@contextmanager
def build_lock(folder: str | Path) -> Iterator[None]:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if fcntl is None:
        yield
        return
    descriptor = os.open(folder / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)      # released when closed
        yield
    finally:
        os.close(descriptor)
