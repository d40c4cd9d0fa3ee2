"""Zaber's official client, zaber-motion, drives the Zaber simulator over a real socket.

zaber-motion identifies a device from Zaber's device database, fetched over the
network by default. Here it reads an offline store instead: one file in
tests/data/zaber-device-db describing the X-LSM025A the simulator models
(docs/hardware.md, "Zaber", says where each number in it comes from). The web
service is pointed at a closed local port, so a miss in the store fails at once
instead of reaching the network.
"""

import shutil
import socket
from pathlib import Path

import pytest

zm = pytest.importorskip("zaber_motion", reason="zaber-motion (the dev extra) is not installed")
from zaber_motion import DeviceDbSourceType, Library, Units  # noqa: E402
from zaber_motion.ascii import Connection  # noqa: E402
from zaber_motion.exceptions import CommandFailedException  # noqa: E402

from rig.clock import ScaledClock  # noqa: E402
from rig.sim.contact import SpringContact  # noqa: E402
from rig.sim.world import SimWorld  # noqa: E402
from rig.sim.zaber_sim import X_LSM025A_DEVICE_ID, ZaberChainSim, ZaberDeviceSim  # noqa: E402

STORE = Path(__file__).parent / "data" / "zaber-device-db"
US_MM = 0.047625e-3  # X-LSM025A microstep
MM = Units.LENGTH_MILLIMETRES


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def zml(tmp_path, serve):
    # zaber-motion polls in real time, so the simulator's clock runs with real time
    # (4x faster, to keep homing short; motion is all zaber-motion waits on).
    clock = ScaledClock(4.0)
    world = SimWorld(clock, contact=SpringContact())
    sim = ZaberChainSim(
        clock, {1: ZaberDeviceSim(world.stages["x"], US_MM), 2: ZaberDeviceSim(world.stages["y"], US_MM)}
    )
    server = serve(sim, clock, transport="tcp")
    store = tmp_path / "store"
    shutil.copytree(STORE, store)  # the library may write to its store
    Library.set_device_db_source(DeviceDbSourceType.WEB_SERVICE, f"http://127.0.0.1:{_closed_port()}/device-db")
    Library.enable_device_db_store(str(store))
    port = int(server.url.rsplit(":", 1)[1])
    with Connection.open_tcp("127.0.0.1", port) as conn:
        yield conn, world, clock
    Library.disable_device_db_store()
    Library.set_device_db_source(DeviceDbSourceType.WEB_SERVICE, "https://api.zaber.io/device-db/master")


def test_detect_devices_identifies_the_simulated_stages(zml):
    conn, _, _ = zml
    devices = conn.detect_devices()
    assert [d.device_address for d in devices] == [1, 2]
    ident = devices[0].identity
    assert (ident.device_id, ident.name, ident.axis_count) == (X_LSM025A_DEVICE_ID, "X-LSM025A", 1)
    assert (ident.firmware_version.major, ident.firmware_version.minor) == (7, 33)
    assert devices[0].serial_number != devices[1].serial_number
    axis = devices[0].get_axis(1)
    assert axis.axis_type == zm.ascii.AxisType.LINEAR and axis.identity.resolution == 64


def test_positions_and_moves_in_millimetres(zml):
    conn, world, clock = zml
    x = conn.detect_devices()[0].get_axis(1)
    assert x.get_position(MM) == pytest.approx(12.5, abs=US_MM)  # the world starts mid-travel
    x.move_absolute(14.0, MM)  # waits until idle
    assert world.stages["x"].position(clock.now()) == pytest.approx(14.0, abs=US_MM)
    x.move_relative(-1.5, MM)
    assert x.get_position(MM) == pytest.approx(12.5, abs=US_MM)
    x.settings.set("pos", 2.0, MM)  # re-reference without moving
    assert x.get_position(MM) == pytest.approx(2.0, abs=US_MM)
    assert world.stages["x"].position(clock.now()) == pytest.approx(12.5, abs=US_MM)


def test_velocity_move_stop_and_home(zml):
    conn, world, clock = zml
    x = conn.detect_devices()[0].get_axis(1)
    start = x.get_position(MM)
    x.move_velocity(2.0, Units.VELOCITY_MILLIMETRES_PER_SECOND)
    assert x.is_busy()
    clock_s = clock.now()
    while clock.now() - clock_s < 0.3:  # let it run a little (real time: zaber-motion polls it)
        x.get_position(MM)
    x.stop()  # waits until idle
    stopped = x.get_position(MM)
    assert 0.1 < stopped - start < 12.0  # moved, and stopped short of the travel's end
    assert not x.is_busy() and x.get_position(MM) == stopped
    x.home()  # waits until idle, at up to the stage's 5 mm/s
    assert x.get_position(MM) == pytest.approx(0.0, abs=US_MM)
    assert world.stages["x"].position(clock.now()) == pytest.approx(0.0, abs=US_MM)


def test_settings_in_physical_units(zml):
    conn, _, _ = zml
    x = conn.detect_devices()[0].get_axis(1)
    # 153600 native = 153600 / 1.6384 µsteps/s × 0.047625 µm (manual, "maxspeed")
    assert x.settings.get("maxspeed", Units.VELOCITY_MILLIMETRES_PER_SECOND) == pytest.approx(4.46484375)
    x.settings.set("maxspeed", 2.0, Units.VELOCITY_MILLIMETRES_PER_SECOND)
    assert x.settings.get("maxspeed") == round(2.0 / US_MM * 1.6384)
    assert x.settings.get("limit.max", MM) == pytest.approx(25.0, abs=US_MM)  # the simulated travel


def test_out_of_range_move_is_rejected(zml):
    conn, world, clock = zml
    x = conn.detect_devices()[0].get_axis(1)
    with pytest.raises(CommandFailedException) as err:
        x.move_absolute(40.0, MM)  # beyond the 25 mm travel
    assert err.value.details.response_data == "BADDATA"
    assert world.stages["x"].position(clock.now()) == pytest.approx(12.5, abs=US_MM)


def test_travel_limits_set_and_read_back_by_zaber_motion_are_enforced(zml):
    """The rig keeps its depth floor in the controller (rig/device_floor.py): Zaber's own client
    sets limit.min/limit.max on the simulator, reads them back, and a move beyond is refused as
    the manual says; a velocity move stops at the limit."""
    conn, world, clock = zml
    x = conn.detect_devices()[0].get_axis(1)
    x.settings.set("limit.max", 14.0, MM)
    x.settings.set("limit.min", 11.0, MM)
    assert x.settings.get("limit.max", MM) == pytest.approx(14.0, abs=US_MM)
    assert x.settings.get("limit.min", MM) == pytest.approx(11.0, abs=US_MM)
    with pytest.raises(CommandFailedException) as err:
        x.move_absolute(15.0, MM)
    assert err.value.details.response_data == "BADDATA"
    with pytest.raises(CommandFailedException):
        x.move_absolute(10.0, MM)
    assert world.stages["x"].position(clock.now()) == pytest.approx(12.5, abs=US_MM)  # nothing moved
    x.move_velocity(3.0, Units.VELOCITY_MILLIMETRES_PER_SECOND)
    x.wait_until_idle()
    assert x.get_position(MM) == pytest.approx(14.0, abs=US_MM)  # stopped at limit.max
    x.move_absolute(12.0, MM)
    assert x.get_position(MM) == pytest.approx(12.0, abs=US_MM)
