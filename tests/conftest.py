import fcntl
import os

import pytest

from common.blas_threads import one_blas_thread
from rig.clock import ManualClock, SystemClock
from rig.sim.contact import SpringContact
from rig.sim.link import SimServer
from rig.sim.world import SimWorld

one_blas_thread()  # as every command does (cli/__init__.py): the simulators in this process run on threads
if os.environ.get("PYTEST_XDIST_WORKER"):
    # Several test processes share the cores: torch's default of one thread per core in each of
    # them oversubscribes them (a 3 s training test took 58 s under four workers). One thread per
    # worker, in this process (before torch is imported) and in the commands it starts.
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("TACTILE_TORCH_THREADS", "1")


# -- tests that run alone -------------------------------------------------------------------------
# The suite runs on several processes (pytest-xdist, `-n` in pyproject.toml). A test marked
# `realtime` asserts what happens at a moment of real time (a signal 50 ms into a command, a stream
# that must fall silent within 0.2 s), so it runs with no other test running: every other test holds
# a shared lock on a file of this run while it runs (set-up and teardown included), a realtime test
# an exclusive one; whoever waits for the exclusive lock holds the turnstile, so that no new test
# starts meanwhile. Without xdist nothing is locked.


def _run_lock_paths(config) -> tuple[str, str] | None:
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return None
    root = config._tmp_path_factory.getbasetemp().parent  # shared by the run's workers
    return str(root / "realtime.turnstile"), str(root / "realtime.lock")


@pytest.hookimpl(hookwrapper=True, tryfirst=True)  # outside pytest-timeout's: waiting is not the test's time
def pytest_runtest_protocol(item, nextitem):
    paths = _run_lock_paths(item.config)
    if paths is None:
        yield
        return
    alone = item.get_closest_marker("realtime") is not None
    with open(paths[0], "a") as turnstile, open(paths[1], "a") as lock:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        fcntl.flock(lock, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        if not alone:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
            fcntl.flock(turnstile, fcntl.LOCK_UN)


@pytest.fixture(autouse=True)
def rig_state_dir(tmp_path_factory, monkeypatch):
    """Each test keeps its rigs' persisted state (tare, gel surface: rig/rig_state.py) in a
    folder of its own, never a real user's; subprocesses inherit it through the environment."""
    folder = tmp_path_factory.mktemp("rig-state")
    monkeypatch.setenv("TACTILE_STATE_DIR", str(folder))
    return folder


@pytest.fixture(scope="session", autouse=True)
def runtime_dir(tmp_path_factory):
    """Device claims (rig/ownership.py) go to a folder of this test session, never a real
    user's; set for the session so that module-scoped rigs and subprocesses use it too."""
    with pytest.MonkeyPatch.context() as patch:
        folder = tmp_path_factory.mktemp("runtime")
        patch.setenv("TACTILE_RUNTIME_DIR", str(folder))
        yield folder


@pytest.fixture
def manual_clock():
    return ManualClock()


@pytest.fixture
def world(manual_clock):
    return SimWorld(manual_clock, contact=SpringContact())


@pytest.fixture
def serve():
    """serve(model, clock, transport='pty') -> SimServer, closed after the test."""
    servers = []

    def _serve(model, clock=None, transport="pty"):
        server = SimServer(model, clock or SystemClock(), transport=transport)
        servers.append(server)
        return server

    yield _serve
    for s in servers:
        s.close()
