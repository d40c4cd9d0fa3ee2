"""Wire exchanges under hostile conditions.

Late Modbus replies are never taken for another request's answer; a signal arriving
during a write does not abort it; a simulated exchange does not time out because the
machine is busy, while a dead simulator still ends in a DeviceTimeout.
"""

import os
import signal
import threading
import time

import pytest

from rig.drivers import pr_registers as reg
from rig.drivers.pr_drive import PrDriveAxis
from rig.errors import DeviceError, DeviceRejected, DeviceTimeout, FramingError
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.scripted import ScriptedDevice
from rig.transport.crc import append_crc
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink

PULSES_PER_REV = 10000


@pytest.fixture
def theta_bus(world, manual_clock, serve):
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=PULSES_PER_REV, travel_per_rev=4.0)
    server = serve(RtuServer({1: drive}), manual_clock)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.15, retries=0, device="theta bus")
    yield bus, server, drive
    bus.close()


def read_or_error(bus, address, count):
    try:
        return bus.read_holding(1, address, count, device="theta")
    except DeviceError:
        return None  # a typed error is an allowed outcome; a wrong value is not


# -- finding 5: a late reply is never the answer to the next request ----------------


def test_late_modbus_reply_is_never_taken_for_the_next_answer(theta_bus, manual_clock):
    bus, server, drive = theta_bus
    drive.stage._pos = drive.pulse * 0x12345  # a position whose two registers differ from the status word
    status = drive.read_registers(reg.PR_CONTROL, 1, 0.0)
    position = drive.read_registers(reg.COMMAND_POS_HIGH, 2, 0.0)
    # Both replies come back 0.25 s late, past the 0.15 s timeout: the status reply
    # arrives while the position read waits for its own answer (finding 5 seen on a
    # loaded machine as "ALARM 0x0001" and "expected 2, got 1").
    server.faults.delay_next(2, 0.25)
    assert read_or_error(bus, reg.PR_CONTROL, 1) in (status, None)
    assert read_or_error(bus, reg.COMMAND_POS_HIGH, 2) in (position, None)
    manual_clock.advance(0.5)  # every late reply is out on the wire by now
    for _ in range(3):  # each request gets its own answer, whatever arrived late
        assert bus.read_holding(1, reg.PR_CONTROL, 1, device="theta") == status
        assert bus.read_holding(1, reg.COMMAND_POS_HIGH, 2, device="theta") == position


def test_late_reply_to_another_register_is_skipped_on_the_same_request(serve):
    # The late status reply of an earlier read sits on the line ahead of the position
    # reply: same device, same function, another byte count. It is dropped, counted,
    # and the request's own reply read after it.
    status_reply = append_crc(bytes.fromhex("01 03 02 00 01"))
    request = append_crc(bytes.fromhex("01 03 60 2A 00 02"))
    own_reply = append_crc(bytes.fromhex("01 03 04 00 01 23 45"))
    script = ScriptedDevice([(request, status_reply + own_reply)])
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="bus")
    assert bus.read_holding(1, 0x602A, 2, device="theta") == [0x0001, 0x2345]
    assert bus.stale_frames == 1
    bus.close()
    script.check()


# One request each, and a reply that must not be used (Modbus over Serial Line v1.02 §2.5.1
# frame; Modbus Application Protocol v1.1b3 §6.3, 6.6, 6.12 replies).
READ_POS = append_crc(bytes.fromhex("01 03 60 2A 00 02"))
WRITE_CTRL = append_crc(bytes.fromhex("01 06 60 02 00 10"))
WRITE_BLOCK = append_crc(bytes.fromhex("01 10 62 00 00 02 04 00 01 00 00"))
MISMATCHES = {
    "other device id": (READ_POS, append_crc(bytes.fromhex("02 03 04 00 00 30 D4"))),
    "other function": (READ_POS, append_crc(bytes.fromhex("01 04 04 00 00 30 D4"))),
    "short byte count": (READ_POS, append_crc(bytes.fromhex("01 03 02 00 01"))),
    "bad CRC": (READ_POS, bytes.fromhex("01 03 04 00 00 30 D4 00 00")),
    "write echo of another register": (WRITE_CTRL, append_crc(bytes.fromhex("01 06 60 03 00 10"))),
    "write echo of another value": (WRITE_CTRL, append_crc(bytes.fromhex("01 06 60 02 00 40"))),
    "block echo of another quantity": (WRITE_BLOCK, append_crc(bytes.fromhex("01 10 62 00 00 06"))),
}


def _send(bus, request):
    if request == READ_POS:
        return bus.read_holding(1, 0x602A, 2, device="theta")
    if request == WRITE_CTRL:
        return bus.write_register(1, 0x6002, 0x0010, device="theta")
    return bus.write_registers(1, 0x6200, [1, 0], device="theta")


@pytest.mark.parametrize("case", sorted(MISMATCHES))
def test_mismatched_reply_is_an_error_never_a_value(serve, case):
    request, wrong = MISMATCHES[case]
    script = ScriptedDevice([(request, wrong)])
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.2, retries=0, device="bus")
    with pytest.raises((FramingError, DeviceTimeout), match="theta"):
        _send(bus, request)
    bus.close()
    script.check()


@pytest.mark.parametrize("case", sorted(MISMATCHES))
def test_mismatched_reply_is_retried_then_the_right_one_used(serve, case):
    request, wrong = MISMATCHES[case]
    right = {
        READ_POS: append_crc(bytes.fromhex("01 03 04 00 00 30 D4")),
        WRITE_CTRL: WRITE_CTRL,
        WRITE_BLOCK: append_crc(bytes.fromhex("01 10 62 00 00 02")),
    }[request]
    script = ScriptedDevice([(request, wrong), (request, right)])
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.2, retries=1, device="bus")
    result = _send(bus, request)
    assert result == ([0x0000, 0x30D4] if request == READ_POS else None)
    bus.close()
    script.check()


def test_exception_reply_is_a_rejection_naming_the_device(serve):
    script = ScriptedDevice([(READ_POS, append_crc(bytes.fromhex("01 83 02")))])
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.2, retries=2, device="bus")
    with pytest.raises(DeviceRejected, match="theta.*ILLEGAL DATA ADDRESS"):
        _send(bus, READ_POS)
    bus.close()
    script.check()  # not retried: the drive answered


# -- finding 9: EINTR during write and flush ------------------------------------------


# a real-time reader on the other side / a stream that must stop within 0.2 s; alone: beside another
# realtime test (two lanes) its reader thread fell behind once
@pytest.mark.realtime(alone=True)
def test_write_and_flush_complete_while_signals_arrive():
    import pty
    import tty

    master, slave = pty.openpty()
    tty.setraw(slave)
    received = bytearray()

    def reader():  # the far end, reading as a device would, until everything arrived
        while len(received) < total:
            try:
                received.extend(os.read(master, 65536))
            except OSError:
                return

    block = bytes(range(256)) * 256  # 64 KiB, more than a pty buffers
    rounds = 40
    total = len(block) * rounds
    link = SerialLink(os.ttyname(slave), baudrate=115200, timeout_s=0.5, device="test port")
    fired = []
    previous = signal.signal(signal.SIGALRM, lambda *_: fired.append(1))
    thread = threading.Thread(target=reader, daemon=True)
    thread.start()
    signal.setitimer(signal.ITIMER_REAL, 0.0001, 0.0001)
    try:
        for _ in range(rounds):
            link.write(block, "bulk")  # write + flush (tcdrain), interrupted many times
            for _ in range(500):  # ~1 in 1000 tcdrain calls sees a signal arrive (measured)
                link.port.flush()  # tcdrain alone, the call seen failing in finding 9
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0, 0)
        signal.signal(signal.SIGALRM, previous)
    thread.join(timeout=5.0)
    link.close()
    os.close(master)
    os.close(slave)
    assert len(fired) > 100, "the timer did not interrupt the writes; the test proves nothing"
    assert bytes(received) == block * rounds


def test_an_exception_raised_by_a_signal_handler_still_propagates():
    import pty

    master, slave = pty.openpty()
    link = SerialLink(os.ttyname(slave), baudrate=115200, timeout_s=5.0, device="test port")

    class Stop(Exception):
        pass

    def handler(*_):
        raise Stop()

    previous = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, 0.05)
    started = time.monotonic()
    try:
        with pytest.raises(Stop):
            link.read_exact(10, "wait")  # nothing ever arrives; only the handler ends the wait
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0, 0)
        signal.signal(signal.SIGALRM, previous)
        link.close()
        os.close(master)
        os.close(slave)
    assert time.monotonic() - started < 2.0


# -- finding 7: simulated timeouts immune to real-time load ---------------------------


class StallingModel:
    """A device model whose next ``feed`` waits ``stall_s`` of real time before answering,
    as a simulator thread starved of CPU would; no simulated time passes meanwhile."""

    def __init__(self, model, stall_s: float):
        self.model = model
        self.stall_s = stall_s
        self.released = threading.Event()

    def feed(self, data, now_s):
        if self.stall_s:
            stall, self.stall_s = self.stall_s, 0.0
            self.released.wait(stall)
        return self.model.feed(data, now_s)

    def tick(self, now_s):
        return self.model.tick(now_s)

    def tick_interval_s(self):
        return self.model.tick_interval_s()


def test_simulated_exchange_survives_a_real_time_stall(world, manual_clock, serve):
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=PULSES_PER_REV, travel_per_rev=4.0)
    model = StallingModel(RtuServer({1: drive}), stall_s=0.8)  # longer than the old 0.3 s timeout
    server = serve(model, manual_clock)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="theta bus")
    axis = PrDriveAxis(
        bus, name="theta", device_id=1, pulses_per_rev=PULSES_PER_REV, travel_per_rev=4.0, offset=-180.0
    )  # the world's theta origin is at 180 deg
    t_sim = manual_clock.now()
    assert axis.position() == pytest.approx(0.0)
    assert manual_clock.now() == t_sim  # the exchange took no simulated time
    bus.close()


def test_dead_simulator_is_a_timeout_in_bounded_time(world, manual_clock, serve):
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=PULSES_PER_REV, travel_per_rev=4.0)
    model = StallingModel(RtuServer({1: drive}), stall_s=60.0)  # hung: never answers
    server = serve(model, manual_clock)
    server.stall_limit_s = 1.0  # real seconds a simulator may take to read a request
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=1, device="theta bus")
    started = time.monotonic()
    try:
        with pytest.raises(DeviceTimeout, match="theta"):
            bus.read_holding(1, reg.COMMAND_POS_HIGH, 2, device="theta")
        assert time.monotonic() - started < 4.0
    finally:
        model.released.set()
        bus.close()


def test_dropped_simulated_reply_times_out_on_simulated_time(world, manual_clock, serve):
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=PULSES_PER_REV, travel_per_rev=4.0)
    server = serve(RtuServer({1: drive}), manual_clock)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=2, device="theta bus")
    server.faults.drop_next(3)
    t_sim = manual_clock.now()
    with pytest.raises(DeviceTimeout, match="theta"):
        bus.read_holding(1, reg.COMMAND_POS_HIGH, 2, device="theta")
    assert manual_clock.now() - t_sim == pytest.approx(3 * 0.3)  # three tries, each a device timeout
    bus.close()


def test_on_a_discrete_clock_every_advance_ends_with_a_sample_at_the_new_time():
    from rig.sim.stream_clock import SampleSchedule

    schedule = SampleSchedule(10.0, report_on_advance=True)
    schedule.start(0.05)
    assert schedule.due(0.05) == [0.05]
    times = schedule.due(1.0)
    assert times[:-1] == pytest.approx([0.15 + 0.1 * i for i in range(9)]) and times[-1] == 1.0
    assert schedule.due(1.0) == []  # time stood still: nothing new
    assert schedule.due(1.02) == [1.02]  # a short advance still reports its own instant


def test_the_ft300_stream_costs_one_contact_solve_per_clock_advance(world, manual_clock):
    """A whole second of the 100 Hz stream is one solve at the new time, the samples
    before it interpolated; its bytes are still every frame the driver parses."""
    from rig.drivers import ft300 as ft
    from rig.sim.ft300_sim import Ft300Sim

    calls = []
    wrench = world.contact.wrench
    world.contact.wrench = lambda pose: calls.append(pose) or wrench(pose)
    sim = Ft300Sim(world, rate_hz=100.0, streaming=True)
    sim.schedule.report_on_advance = True
    assert len(sim.tick(manual_clock.now())) == 1 and len(calls) == 1
    manual_clock.advance(1.0)
    frames = sim.tick(manual_clock.now())
    assert len(frames) == 100 and len(calls) == 2  # 0.01 .. 1.00 s: one solve
    assert all(len(f) == len(ft.encode_stream_frame([0.0] * 6)) for f in frames)


def test_a_socket_port_closes_at_once_and_waits_only_before_reopening_the_same_address(monkeypatch):
    """pyserial pauses 0.3 s after closing a socket:// port; a command paid it per link at its exit. The
    port closes without it (the peer sees the end at once), and only a reopen of that address by this
    process waits out the rest of the pause, as pyserial meant it (a serial server may take one client)."""
    import socket
    import types

    import serial.urlhandler.protocol_socket as pyserial_socket

    from rig.transport import serial_link

    slept: list[float] = []

    class Clock:
        t = 100.0

        def now(self):
            return self.t

        def sleep(self, dt_s):
            slept.append(dt_s)

    def no_sleep(dt_s):
        raise AssertionError(f"pyserial's own pause ({dt_s} s) was taken")

    monkeypatch.setattr(serial_link, "_REAL", Clock())
    monkeypatch.setattr(serial_link, "_socket_closed_at", {})
    monkeypatch.setattr(pyserial_socket, "time", types.SimpleNamespace(sleep=no_sleep))  # pyserial's module only
    with socket.create_server(("127.0.0.1", 0)) as server:
        url = f"socket://127.0.0.1:{server.getsockname()[1]}"
        port = serial_link.open_port(url, baudrate=9600, timeout_s=0.5, device="test")
        peer, _ = server.accept()
        with peer:
            port.close()
            assert not port.is_open and slept == []
            peer.settimeout(5)
            assert peer.recv(1) == b""  # the peer sees the end
        serial_link._REAL.t += 0.1
        again = serial_link.open_port(url, baudrate=9600, timeout_s=0.5, device="test")
        assert slept == [pytest.approx(0.2)]  # the rest of the pause, before the same address again
        again.close()
        server.accept()[0].close()
        other = serial_link.open_port(url.replace("127.0.0.1", "localhost"), baudrate=9600, timeout_s=0.5, device="t")
        assert slept == [pytest.approx(0.2)]  # another address: no wait
        other.close()
