"""build_lock: a second process that wants to build in the same folder waits until
the first is done (two test workers, or two galileo-cnc processes, never run make
over the same files)."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from galileo_cnc.simavr.build_lock import build_lock

CHILD = """
import sys
from galileo_cnc.simavr.build_lock import build_lock
print("waiting", flush=True)
with build_lock(sys.argv[1]):
    print("building", flush=True)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="no fcntl: the lock is a no-op there")
def test_a_second_process_builds_only_after_the_first_is_done(tmp_path):
    with build_lock(tmp_path):
        child = subprocess.Popen([sys.executable, "-c", CHILD, str(tmp_path)],
                                 stdout=subprocess.PIPE, text=True)
        try:
            assert child.stdout.readline() == "waiting\n"
            time.sleep(0.5)                    # time to take a lock that did not hold
            assert child.poll() is None        # still waiting for ours
        except BaseException:
            child.kill()
            raise
    out, _err = child.communicate(timeout=60)
    assert out == "building\n" and child.returncode == 0
    assert (tmp_path / ".build.lock").exists()
