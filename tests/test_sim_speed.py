"""The simulated run's fast paths (issue 17) give what the plain paths give.

Each shortcut is checked against the plain computation or shown to work where the
plain path cannot: the gauge buffer's scans from the newest end, stream frames encoded
together, rows and stream rows written through h5py's low-level API (read back by plain
h5py), the solvers' direct transforms, a simulator answering in the thread that waits
for its reply, and a stream taken inline on the discrete clock. Inline serving is only
for the built-in (non-blocking) models on in-process ptys: a model that may stall keeps
the simulator's own thread, and a dead simulator is still a timeout in bounded time.
"""

import bisect
import time

import h5py
import numpy as np
import pytest

from acquisition import schema as S
from acquisition.run_file import ROW_BLOCK, RunHeader, RunWriter
from rig.clock import ManualClock, SystemClock
from rig.drivers import ft300 as ft
from rig.drivers.ft300 import FT300
from rig.drivers.wrench_stream import WrenchBuffer
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.errors import DeviceTimeout
from rig.sim.contact import SpringContact
from rig.sim.ft300_sim import Ft300Sim
from rig.sim.m8128_sim import M8128Sim
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.world import SimWorld
from rig.sim.zaber_sim import ZaberChainSim, ZaberDeviceSim
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink
from rig.types import Wrench

US = 0.047625e-3


def test_buffer_scans_from_the_newest_end_give_what_a_full_scan_gives():
    rng = np.random.default_rng(3)
    # bursts: several samples share one arrival stamp, as one read of a stream does
    stamps = np.repeat(np.cumsum(rng.uniform(0.01, 0.2, 300)), rng.integers(1, 5, 300))
    buffer = WrenchBuffer(capacity=500)
    samples = [Wrench.from_array(float(t), rng.normal(0, 1, 6)) for t in stamps]
    for s in samples:
        buffer.push(s)
    kept = samples[-500:]
    times = [s.t_s for s in kept]
    probes = [times[0] - 1.0, times[-1] + 1.0, *times[::7], *(rng.uniform(times[0], times[-1], 50))]
    for t in probes:
        assert buffer.since(t) == [s for s in kept if s.t_s > t]
        i = bisect.bisect_right(times, t)
        if i in (0, len(kept)):
            s = kept[0] if i == 0 else kept[-1]
            expected, skew = s.as_array(), abs(s.t_s - t)
        else:
            a, b = kept[i - 1], kept[i]
            w = (t - a.t_s) / (b.t_s - a.t_s)
            expected, skew = a.as_array() * (1 - w) + b.as_array() * w, min(t - a.t_s, b.t_s - t)
        values, got_skew = buffer.at(t)
        np.testing.assert_array_equal(values, expected)
        assert got_skew == skew


def test_stream_frames_encoded_together_are_the_single_frames_byte_for_byte():
    rng = np.random.default_rng(5)
    values = rng.normal(0, 40, (300, 6))
    values[0] = [1e9, -1e9, 0.005, -0.005, 0.5, -0.5]  # clipped, and rounded half to even
    values[1] = [0.015, -0.015, 0.025, 327.675, 2.5, -3.5]
    assert ft.encode_stream_frames(values) == [ft.encode_stream_frame(v) for v in values]


def test_rows_written_low_level_read_back_exactly_with_plain_h5py(tmp_path):
    """More rows than one block (the datasets grow mid-run), every field's dtype, and the
    full-rate stream's rows past one chunk."""
    n = ROW_BLOCK + 7
    path = tmp_path / "run.h5"
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, n, (0, 0, 0, 0), ("press", "shear"))
    image = np.zeros((8, 8, 3), np.uint8)
    w = RunWriter.create(path, header, (8, 8, 3), image, image)
    rng = np.random.default_rng(1)
    rows = []
    streams = []
    for i in range(n):
        stream = np.column_stack([i + np.arange(i % 9) / 10, rng.normal(0, 5, (i % 9, 6))])  # 0..8 rows a frame
        streams.append(stream)
        row = {
            S.WRENCH: rng.normal(0, 5, 6),
            S.POSE_COMMANDED: rng.normal(0, 1, 4),
            S.POSE_MEASURED: rng.normal(0, 1, 4),
            S.T_FRAME: float(i) + 0.25,
            S.T_CAPTURE: float(i),
            S.WRENCH_SKEW: float(rng.uniform(0, 0.01)),
            S.CAPTURE_INDEX: i,
            S.STEP_INDEX: i // 10,
            S.PHASE_INDEX: i % 2,
            S.LEVEL: i % 4,
            S.RETAKE: 0,
        }
        rows.append(row)
        w.append(np.full((8, 8, 3), i % 256, np.uint8), stream=stream if len(stream) else None, **row)
    with pytest.raises(ValueError, match="wrench"):  # a wrong shape is refused, nothing counted
        w.append(image, **(rows[0] | {S.WRENCH: np.zeros(4)}))
    assert w.n == n
    w.set_status("complete")
    w.close()
    with h5py.File(path, "r") as f:
        for name in rows[0]:
            got = f[name][:n]
            expected = np.array([r[name] for r in rows]).astype(f[name].dtype)
            np.testing.assert_array_equal(got, expected, err_msg=name)
        assert [int(f[S.FRAMES][i][0, 0, 0]) for i in range(n)] == [i % 256 for i in range(n)]
        np.testing.assert_array_equal(f[S.WRENCH_STREAM][:], np.concatenate(streams))  # past one stream chunk


@pytest.fixture
def chain_on_manual_clock(serve):
    clock = ManualClock()
    world = SimWorld(clock, contact=SpringContact())
    sim = ZaberChainSim(clock, {1: ZaberDeviceSim(world.stages["x"], US)})
    server = serve(sim, clock)
    chain = ZaberChain(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="chain"))
    yield chain, server, clock
    chain.close()


def test_a_request_is_answered_in_the_thread_waiting_for_it_on_the_discrete_clock(chain_on_manual_clock):
    """With the simulator's own thread stopped, its port still answers: the driver's
    thread served the request (the same bytes through the same pty)."""
    chain, server, clock = chain_on_manual_clock
    x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
    server._stop.set()
    server._thread.join(timeout=5.0)
    assert not server._thread.is_alive()
    before = server.bytes_in
    x.move_to(1.0, 1.0)
    clock.advance(2.0)
    assert x.position() == pytest.approx(1.0, abs=US)
    assert server.bytes_in > before


def test_an_armed_stall_is_left_to_the_simulators_thread(chain_on_manual_clock):
    chain, server, _ = chain_on_manual_clock
    server.faults.stall_next(1, 0.0)
    assert not server.serve_now()  # a stall is the simulator thread's: never served inline
    x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
    assert x.position() == pytest.approx(0.0, abs=US)  # its thread took the stall and answered
    assert server.faults.counts.stalled == 1


def test_stream_taken_inline_on_the_discrete_clock_without_the_reader_thread(serve):
    """The sample at a capture comes from the bytes the clock's advance put on the line,
    taken by the caller itself: with the reader thread stopped, and without moving the clock."""
    clock = ManualClock()
    world = SimWorld(clock, contact=SpringContact())
    world.spec.gauge_noise = (0.0,) * 6
    sim = Ft300Sim(world, rate_hz=10.0)
    sim.schedule.report_on_advance = True  # as the simulated rig serves it (rig/sim/served.py)
    server = serve(sim, clock)
    g = FT300(ModbusBus(server.url, baudrate=19200, timeout_s=0.3, retries=0, device="ft300"), clock)
    try:
        g.start_stream()
        reader = g._reader
        assert reader is not None and reader.inline
        reader._stop.set()
        reader._thread.join(timeout=5.0)
        assert not reader._thread.is_alive()
        world.stages["z"]._pos = world.spec.geometry["z"].origin + 0.5  # pressed 0.5 mm
        clock.advance(1.0)
        t = clock.now()
        values, skew = g.sample_at(t)
        assert clock.now() == t and skew == 0.0  # no clock step was needed
        expected = np.round((world.true_wrench(t) + world.spec.gauge_offset) / ft.COUNTS_TO_UNITS) * ft.COUNTS_TO_UNITS
        np.testing.assert_allclose(values, expected, atol=1e-9)
        assert values[2] > 1.0
    finally:
        g.close()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_direct_transforms_are_scipy_fft_bit_for_bit(dtype):
    """The contact solvers call pocketfft directly (sensor_sim/kernels.py): the same numbers
    as scipy.fft's rfft2/irfft2 with zero padding, one field or a stack of them."""
    import scipy.fft as sfft

    from sensor_sim.kernels import irfft2_full, rfft2_padded

    rng = np.random.default_rng(2)
    shape = (96, 90)
    for field in (rng.normal(0, 1, (48, 41)).astype(dtype), rng.normal(0, 1, (2, 37, 45)).astype(dtype)):
        spectrum = rfft2_padded(field, shape)
        expected = sfft.rfft2(field, s=shape, axes=(-2, -1))
        assert spectrum.dtype == expected.dtype
        np.testing.assert_array_equal(spectrum, expected)
        kernel = rng.normal(0, 1, expected.shape[-2:]).astype(expected.dtype)
        np.testing.assert_array_equal(
            irfft2_full(spectrum * kernel, shape), sfft.irfft2(expected * kernel, s=shape, axes=(-2, -1))
        )


def test_triggered_simulated_camera_renders_in_the_triggering_thread_at_that_instant():
    """On the discrete clock the frame is made by trigger() itself: with the grabber thread
    stopped after the dropped first frames, frames still come, stamped at their trigger."""
    from rig.drivers.camera import Camera
    from rig.sim.rig_sim import SimulatedRig

    clock = ManualClock()
    with SimulatedRig(clock) as sim:
        source = sim.camera_source(height=64, width=64, triggered=True)
        assert source.renders_on_trigger
        cam = Camera(source, clock, discard_frames=2)
        try:
            assert cam.wait_arrived(2, timeout_s=30.0)
            cam._stop.set()
            cam._thread.join(timeout=5.0)
            assert not cam._thread.is_alive()
            frames = []
            for _ in range(3):
                clock.advance(0.5)
                cam.trigger()
                frames.append(cam.read(timeout_s=1.0))
            assert [f.t_s for f in frames] == [0.5, 1.0, 1.5]
            assert [f.index for f in frames] == [0, 1, 2] and frames[0].image.shape == (64, 64, 3)
        finally:
            cam.close()


# -- which links are served inline ---------------------------------------------------------


class UndeclaredModel:
    """A device model that says nothing about blocking (as a test's fault wrapper)."""

    def __init__(self, model):
        self.model = model

    def feed(self, data, now_s):
        return self.model.feed(data, now_s)

    def tick(self, now_s):
        return self.model.tick(now_s)

    def tick_interval_s(self):
        return self.model.tick_interval_s()


def test_only_declared_models_on_in_process_ptys_on_the_discrete_clock_are_served_inline(serve):
    clock = ManualClock()
    world = SimWorld(clock, contact=SpringContact())
    zaber = ZaberChainSim(clock, {1: ZaberDeviceSim(world.stages["x"], US)})
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    assert serve(zaber, clock).inline
    assert serve(RtuServer({1: drive}), clock).inline
    assert serve(Ft300Sim(world), clock).inline
    assert serve(M8128Sim(world), clock).inline
    assert not serve(zaber, clock, transport="tcp").inline  # `rig sim serve`: another process's driver
    assert not serve(zaber, SystemClock()).inline  # real time: the simulator's thread answers
    assert not serve(UndeclaredModel(zaber), clock).inline
    assert not serve(RtuServer({1: drive, 2: UndeclaredModel(drive)}), clock).inline  # one undeclared device


def test_a_stalling_model_keeps_the_threaded_path_and_a_dead_one_times_out_in_bounded_time(serve):
    """The driver never runs an undeclared model in its own thread: with the simulator's
    model hung for a minute, the driver's request times out within the stall limit."""
    import threading

    from test_wire_robustness import StallingModel

    clock = ManualClock()
    world = SimWorld(clock, contact=SpringContact())
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    model = StallingModel(RtuServer({1: drive}), stall_s=60.0)
    server = serve(model, clock)
    assert not server.inline and not server.serve_now()
    server.stall_limit_s = 1.0
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="theta bus")
    fed_in = []
    real_feed = model.feed
    model.feed = lambda data, now_s: fed_in.append(threading.current_thread().name) or real_feed(data, now_s)
    started = time.monotonic()
    try:
        with pytest.raises(DeviceTimeout, match="theta"):
            bus.read_holding(1, 0, 2, device="theta")
        assert time.monotonic() - started < 4.0
        assert fed_in and all(name.startswith("sim-") for name in fed_in)  # the simulator's thread, never the driver's
    finally:
        model.released.set()
        bus.close()


def test_an_armed_stall_on_an_inline_model_is_still_a_bounded_timeout(chain_on_manual_clock):
    chain, server, _ = chain_on_manual_clock
    assert server.inline
    server.stall_limit_s = 1.0
    server.faults.stall_next(1, 60.0)  # the simulator's thread, starved for a minute
    x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
    started = time.monotonic()
    with pytest.raises(DeviceTimeout):
        x.position()
    assert time.monotonic() - started < 4.0


def test_tangential_displacement_through_buffers_is_the_plain_calls_bit_for_bit(monkeypatch):
    from sensor_sim import kernels as K
    from sensor_sim import tangential_contact as tc
    from sensor_sim.elastomer import Elastomer

    k = K.kernels_for(37, 45, 0.146, Elastomer())
    rng = np.random.default_rng(4)
    fields = [(rng.normal(0, 1, (37, 45)), rng.normal(0, 1, (37, 45))) for _ in range(3)]
    for precise in (False, True):
        fast = tc._displacement(k, precise)
        with monkeypatch.context() as m:
            m.setattr(K, "_pocketfft", None)  # scipy.fft's public calls
            plain = tc._displacement(k, precise)
            expected = [plain(np.stack((qx, qy))) for qx, qy in fields]
        for (qx, qy), u_plain in zip(fields, expected):
            u = fast(np.stack((qx, qy)))
            np.testing.assert_array_equal(u, u_plain)
            ux, uy = k.tangential_displacement(qx, qy, precise=precise)  # the kernels' own two calls
            np.testing.assert_array_equal(u[0], ux)
            np.testing.assert_array_equal(u[1], uy)


@pytest.mark.realtime  # the threaded half serves on real time: load ages a gauge sample past the run's limit
def test_inline_and_threaded_serving_write_the_same_run_file(tmp_path, monkeypatch):
    """A short protocol on the simulated rig, served inline (drivers serve their own
    requests, take their own stream, render their own frames) and through the simulators'
    threads: the same frames, wrenches, poses and times."""
    from test_acquisition import QUICK

    from acquisition.executor import Acquisition
    from cli.simulated import monitor_interval_s, simulated_rig_for
    from protocols.plan import Plan
    from protocols.spec import load_protocol
    from rig.sim import ft300_sim, modbus_rtu, pr_drive_sim, zaber_sim
    from rig.sim.camera_sim import SimCameraSource

    proto_path = tmp_path / "quick.toml"
    proto_path.write_text(QUICK.replace("shear_mm = 0.3", "shear_mm = 0.1"))
    proto = load_protocol(proto_path)

    def run(out):
        with simulated_rig_for(proto) as (rig, sim, header):
            sim.world.spec.gauge_noise = (0.0,) * 6
            rig.camera.source.renderer._noise = None
            served = {name: server.inline for name, server in sim.servers.items()}
            result = Acquisition(rig, Plan.of(proto), monitor_interval_s=monitor_interval_s(proto)).run(
                out, header=header
            )
        assert result.status == "complete", result
        with h5py.File(out, "r") as f:
            data = {name: f[name][:] for name in (S.FRAMES, S.WRENCH, S.POSE_COMMANDED, S.T_FRAME, S.CAPTURE_INDEX)}
        return served, data

    inline_served, inline = run(tmp_path / "inline.h5")
    assert all(inline_served.values())
    with monkeypatch.context() as m:
        for cls in (zaber_sim.ZaberChainSim, pr_drive_sim.PrDriveSim, ft300_sim._Registers):
            m.setattr(cls, "serves_inline", False)
        m.setattr(modbus_rtu.RtuServer, "serves_inline", property(lambda self: False))
        m.setattr(SimCameraSource, "renders_on_trigger", property(lambda self: False))
        threaded_served, threaded = run(tmp_path / "threaded.h5")
    assert not any(threaded_served.values())
    np.testing.assert_array_equal(inline[S.CAPTURE_INDEX], threaded[S.CAPTURE_INDEX])
    np.testing.assert_array_equal(inline[S.POSE_COMMANDED], threaded[S.POSE_COMMANDED])
    # When the first capture comes depends, on the threaded path, on how the simulators' threads
    # were scheduled against the drivers' polls (a loaded machine shifts it by a poll or two);
    # from there on the captures keep the protocol's own rhythm.
    np.testing.assert_allclose(np.diff(inline[S.T_FRAME]), np.diff(threaded[S.T_FRAME]), atol=1e-9)
    np.testing.assert_array_equal(inline[S.WRENCH], threaded[S.WRENCH])
    np.testing.assert_array_equal(inline[S.FRAMES], threaded[S.FRAMES])
