import os

import pytest
from hypothesis import settings

# CI runs the property tests with a fixed seed so a landing never depends on luck;
# local runs keep exploring new examples (and hypothesis remembers failures).
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session", autouse=True)
def users_home_of_the_run(tmp_path_factory):
    """No test writes into the real user's folders (profile, journals), and the
    pytest-xdist workers, each with a session of its own, share none: a test that
    sets GALILEO_CNC_HOME itself still wins."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("GALILEO_CNC_HOME", str(tmp_path_factory.mktemp("home")))
        yield


@pytest.fixture(scope="session", autouse=True)
def grbl_boards_asked_soon():
    """GRBL in simavr never resets when its port opens, so the link need not give it
    the second of silence a real board's boot loader takes before asking it (`?`,
    then a soft reset): a quarter of one, some 0.8 s less of a running simulator at
    each of the suite's three dozen re-opens. The asking itself is what is tested."""
    from galileo_cnc.grbl import link

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(link, "QUIET_BEFORE_ASKING_S", 0.25)
        yield


@pytest.fixture
def fresh_sim(tmp_path, monkeypatch):
    """A user's folders of the test's own, no port probed, and no sim:// machine
    left powered from another test (named machines live as long as the process)."""
    from galileo_cnc.sim.simulator import forget_named_machines

    monkeypatch.setenv("GALILEO_CNC_HOME", str(tmp_path))
    monkeypatch.setenv("GALILEO_CNC_NO_PROBE", "1")
    forget_named_machines()
    yield
    forget_named_machines()


# ---- the order files run in under pytest-xdist (--dist loadfile) ---------------------------
#: Seconds each slow test file took on 2 cores (whole suite, `--durations=0`, summed per
#: file; a directory stands for files of it not named). The slowest files go first, so
#: the run ends on short files and no worker idles while the other finishes a long one
#: (xdist's own order, most tests first, left the GRBL files with few long tests to the
#: end). Stale numbers only cost balance, never a test.
SLOW_FILES_S = {
    "grbl/test_grbl_resume.py": 61, "console/test_console_grbl.py": 46,
    "readers/test_peers.py": 40, "console/test_console.py": 38,
    "grbl/test_grbl_simavr.py": 38, "cli/test_grbl_cli.py": 35,
    "grbl/test_grbl_long_moves.py": 32, "serve": 28, "readers/test_gerber_corpus.py": 27,
    "firmware/test_stream_firmware.py": 27, "stream/test_link_faults.py": 24,
    "firmware/test_firmware_fitl.py": 23, "backends/test_front_ends.py": 22,
    "stream/test_stream.py": 19, "plan/test_ink_geometry.py": 19,
    "console/test_console_stop.py": 18, "readers/test_dxf.py": 15,
    "firmware/test_plot_reset_firmware.py": 14, "cli/test_cli.py": 14,
    "cli/test_plot_reset.py": 12, "grbl/test_mill_grbl.py": 11,
    "cli/test_plot_mill.py": 11, "console/test_console_board.py": 9,
    "readers/test_gcode_props.py": 8, "firmware/test_firmware_build.py": 8,
    "preview/test_render.py": 8, "firmware/test_plot_trace_firmware.py": 8,
    "cli/test_bad_options.py": 7, "console/test_console_mill.py": 7,
}
TESTS = os.path.dirname(os.path.abspath(__file__))


def _slowness(path: str) -> float:
    relative = os.path.relpath(path, TESTS).replace(os.sep, "/")
    while relative not in SLOW_FILES_S and "/" in relative:
        relative = relative.rsplit("/", 1)[0]
    return SLOW_FILES_S.get(relative, 0)


def pytest_configure(config):
    # keep the order below: xdist would sort the files by their number of tests
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(items):
    """The slowest files first (SLOW_FILES_S), then the rest with the most tests first,
    as xdist orders them; a file's own tests keep their order."""
    files: dict[str, list] = {}
    for item in items:
        files.setdefault(str(item.path), []).append(item)
    order = sorted(files, key=lambda path: (-_slowness(path), -len(files[path])))
    items[:] = [item for path in order for item in files[path]]
