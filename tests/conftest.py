import pytest

from common.blas_threads import one_blas_thread
from rig.clock import ManualClock, SystemClock
from rig.sim.contact import SpringContact
from rig.sim.link import SimServer
from rig.sim.world import SimWorld

one_blas_thread()  # as every command does (cli/__init__.py): the simulators in this process run on threads


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
