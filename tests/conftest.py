import os
import signal
import threading
from pathlib import Path

import pytest
import realtime_priority

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
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN and threading.current_thread() is threading.main_thread():
    # A run started in the background of a non-interactive shell (`pytest &` in a script) inherits
    # SIGINT ignored, and so would every command the tests start: the Ctrl-C tests would meet commands
    # deaf to it, as none started from a terminal is. Python's own Ctrl-C is put back (the commands
    # then start with the default action).
    signal.signal(signal.SIGINT, signal.default_int_handler)


# -- realtime tests on several processes ---------------------------------------------------------
# A test marked `realtime` asserts what happens at a moment of real time (a signal 50 ms into a
# command, a stream that must fall silent within 0.2 s). On several processes (pytest-xdist,
# `--dist loadgroup`) they run in their lane (a worker of its own), and from the first of them on the other
# workers run at the lowest priority (tests/realtime_priority.py). Without xdist nothing changes.


def _is_worker(config) -> bool:
    return hasattr(config, "workerinput")  # xdist's own mark of a worker (the environment is inherited)


def _workers_folder(config) -> Path:
    """A folder of this run, shared by the controller and its workers."""
    base = config._tmp_path_factory.getbasetemp()
    return (base.parent if _is_worker(config) else base) / "workers"


@pytest.hookimpl(trylast=True)  # after the tmp_path plugin's, which makes the run's folder
def pytest_configure(config):
    if _is_worker(config):
        realtime_priority.register_worker(_workers_folder(config), config.workerinput["workerid"])


def pytest_xdist_make_scheduler(config, log):
    if config.getvalue("dist") == "loadgroup":
        return realtime_priority.RealtimeFirst(config, log, _workers_folder(config))
    return None


@pytest.hookimpl(trylast=True)  # after -m and -k have chosen the tests
def pytest_collection_modifyitems(config, items):
    if _is_worker(config):
        folder, worker = _workers_folder(config), config.workerinput["workerid"]
        realtime = [item.nodeid for item in items if item.get_closest_marker("realtime") is not None]
        realtime_priority.write_collected(folder, worker, realtime)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """A realtime test runs in its turn: beside the other lane's, or alone (``realtime(alone=True)``)."""
    mark = item.get_closest_marker("realtime")
    if not _is_worker(item.config) or mark is None:
        yield
        return
    with realtime_priority.turn(_workers_folder(item.config), alone=bool(mark.kwargs.get("alone"))):
        yield


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    if not _is_worker(item.config):
        return
    folder = _workers_folder(item.config)
    if item.get_closest_marker("realtime") is not None:
        realtime_priority.lower_other_workers(folder)
    elif realtime_priority.runs_a_lane(folder, item.config.workerinput["workerid"]):
        realtime_priority.lower_myself()  # its lane is done: other lanes may still be running


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
