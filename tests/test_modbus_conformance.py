"""A plain pymodbus client, not the project's driver, reads the simulators over a real pty.

The registers are read as the vendors list them, so a simulator that only agrees with
the project's own driver fails here:
- Robotiq FT300: the FT 300 manual's register table, decoded as Robotiq's C driver
  ``rq_sensor_com.c`` does (180-185 int16, forces /100 N, torques /1000 N·m; 500-502
  firmware "%c%c%c-%u.%u.%u"; 510-513 serial, number = 513 << 16 | 512; 514 year).
- Leadshine PR-mode drive: the CS2RS manual's "Immediate Trigger" PR0 frame (fc 16,
  eight registers from 0x6200, Pr9.07 = 0x0010 runs it) and the "Status Monitoring
  Parameters" 0x1003 (motion state) and 0x1012/0x1013 (profile position).
- Modbus over Serial Line v1.02 §2.1: a request to an absent device id gets no answer.
"""

import numpy as np
import pytest
from pymodbus.client import ModbusSerialClient
from pymodbus.exceptions import ModbusIOException

from rig.clock import SystemClock
from rig.sim.contact import SpringContact
from rig.sim.ft300_sim import Ft300Sim
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.world import SimWorld


def client_for(url: str, baudrate: int) -> ModbusSerialClient:
    client = ModbusSerialClient(port=url, baudrate=baudrate, timeout=0.3, retries=0)
    assert client.connect()
    return client


def signed(value: int) -> int:
    return value - 0x10000 if value & 0x8000 else value


@pytest.fixture
def ft300_client(serve):
    world = SimWorld(SystemClock(), contact=SpringContact())
    server = serve(Ft300Sim(world), world.clock)
    client = client_for(server.url, 19200)
    yield client, world
    client.close()


def test_pymodbus_reads_ft300_wrench_registers_with_the_manuals_scaling(ft300_client):
    client, world = ft300_client
    world.stages["z"]._pos = world.spec.geometry["z"].origin + 1.0  # 1 mm into the gel
    rr = client.read_holding_registers(180, count=6, device_id=9)
    assert not rr.isError()
    counts = np.array([signed(r) for r in rr.registers], dtype=float)
    wrench = counts * np.array([1 / 100] * 3 + [1 / 1000] * 3)  # N, N·m
    expected = world.true_wrench() + np.array(world.spec.gauge_offset)  # N, N·mm
    np.testing.assert_allclose(wrench[:3], expected[:3], atol=0.6)
    np.testing.assert_allclose(wrench[3:] * 1000, expected[3:], atol=600)
    assert wrench[2] == pytest.approx(6.0 + 0.35, abs=0.05)  # a press reads +Fz


def test_pymodbus_reads_ft300_identification_as_robotiqs_driver_prints_it(ft300_client):
    client, _ = ft300_client
    fw = client.read_holding_registers(500, count=3, device_id=9).registers
    firmware = "%c%c%c-%u.%u.%u" % (fw[0] >> 8, fw[0] & 0xFF, fw[1] >> 8, fw[1] & 0xFF, fw[2] >> 8, fw[2] & 0xFF)
    assert firmware == "FTS-1.0.3"
    sn = client.read_holding_registers(510, count=4, device_id=9).registers
    number = (sn[3] << 16) | sn[2]
    assert "%c%c%c-%.4u" % (sn[0] >> 8, sn[0] & 0xFF, sn[1] >> 8, number) == "FTS-100001"
    assert client.read_holding_registers(514, count=1, device_id=9).registers == [2024]
    # rq_com_tentative_connexion's probe: one register from 500, first character 'F'
    assert client.read_holding_registers(500, count=1, device_id=9).registers[0] >> 8 == ord("F")


def test_pymodbus_gets_illegal_address_for_an_unlisted_ft300_register(ft300_client):
    client, _ = ft300_client
    rr = client.read_holding_registers(503, count=1, device_id=9)
    assert rr.isError() and rr.exception_code == 2


def test_pymodbus_starts_the_ft300_stream_as_the_manual_says(ft300_client):
    client, _ = ft300_client
    rr = client.write_registers(410, [0x0200], device_id=9)
    assert not rr.isError() and rr.address == 410 and rr.count == 1


def test_an_absent_device_id_gets_no_answer_at_all(ft300_client):
    # A serial slave answers only its own address (Modbus over Serial Line §2.1); the
    # client times out. (pymodbus's own server would answer exception 11 here.)
    client, _ = ft300_client
    with pytest.raises(ModbusIOException):
        client.read_holding_registers(180, count=6, device_id=10)
    assert not client.read_holding_registers(180, count=6, device_id=9).isError()  # the line recovers


@pytest.fixture
def drive_client(world, manual_clock, serve):
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    server = serve(RtuServer({1: drive}), manual_clock)
    client = client_for(server.url, 38400)
    yield client, drive
    client.close()


def test_pymodbus_pr0_frame_moves_the_stage_and_status_registers_follow(drive_client, world, manual_clock):
    client, _ = drive_client
    assert client.read_holding_registers(0x0001, count=1, device_id=1).registers == [10000]  # Pr0.00 pulses/rev
    start = world.pose().theta_deg
    high, low = client.read_holding_registers(0x1012, count=2, device_id=1).registers
    target = ((high << 16) | low) + 5000  # +2 deg at 4 deg / 10000 pulses
    # Pr9.00..Pr9.07: absolute, target high/low, 30 rpm, 100 ms ramps, no delay, trigger
    values = [0x0001, target >> 16, target & 0xFFFF, 30, 100, 100, 0, 0x0010]
    rr = client.write_registers(0x6200, values, device_id=1)
    assert not rr.isError() and rr.address == 0x6200 and rr.count == 8
    state = client.read_holding_registers(0x1003, count=1, device_id=1).registers[0]
    assert state & 0x0004  # bit2 running
    manual_clock.advance(10)
    state = client.read_holding_registers(0x1003, count=1, device_id=1).registers[0]
    assert not state & 0x0004 and state & 0x0020  # stopped, bit5 path completed
    high, low = client.read_holding_registers(0x1012, count=2, device_id=1).registers
    assert (high << 16) | low == target
    assert world.pose().theta_deg - start == pytest.approx(2.0)
    assert client.read_holding_registers(0x6200, count=8, device_id=1).registers == values


def test_pymodbus_position_is_two_words_high_first(drive_client, world):
    client, _ = drive_client
    assert world.pose().theta_deg == pytest.approx(0.0)  # the stage's 180 deg mark: 450000 pulses from its zero
    assert client.read_holding_registers(0x1012, count=2, device_id=1).registers == [0x0006, 0xDDD0]
    assert client.read_holding_registers(0x1014, count=2, device_id=1).registers == [0x0006, 0xDDD0]


def test_pymodbus_gets_illegal_address_for_undocumented_drive_registers(drive_client):
    client, _ = drive_client
    for address in (0x602A, 0x602C):  # old assumption; a third-party driver's choice
        rr = client.read_holding_registers(address, count=2, device_id=1)
        assert rr.isError() and rr.exception_code == 2
