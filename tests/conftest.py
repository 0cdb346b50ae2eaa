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
