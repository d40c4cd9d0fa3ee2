import pytest

from rig.clock import ManualClock, SystemClock
from rig.sim.contact import SpringContact
from rig.sim.link import SimServer
from rig.sim.world import SimWorld


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
