"""The device registry: a gauge kind defined here, in a test, with a driver and a simulator of
its own and one registry row, is validated by the config, opened by the factory, stood in by
the simulated rig and shown by `rig status` -- no other file touched. And the built-in rows
are what the config, the factory and the command line offer.
"""

from __future__ import annotations

import struct
import threading

import numpy as np
import pytest
from typer.testing import CliRunner

from common.errors import ConfigError
from rig.clock import ScaledClock
from rig.config import parse_config
from rig.config.registry import DeviceKind, Key, Wire, kind, kinds, registered
from rig.drivers.gauge_base import GaugeBase
from rig.drivers.wrench_stream import STREAM_POLL_S, FrameSync
from rig.errors import FramingError
from rig.sim.served import serve_bytes
from rig.sim.stream_clock import SampleSchedule
from rig.transport.serial_link import SerialLink

# -- a throwaway gauge: "P" polls one frame, "S" starts a stream, "X" stops it; a frame is
#    b"T" + six little-endian float32 (N, N·mm) + the low byte of their sum ----------------
HEADER, FRAME_LENGTH = b"T", 26


def encode(values, gain: float = 1.0) -> bytes:
    data = struct.pack("<6f", *(np.asarray(values, dtype=np.float64) / gain))
    return HEADER + data + bytes([sum(data) & 0xFF])


def valid(frame: bytes) -> bool:
    return len(frame) == FRAME_LENGTH and frame[:1] == HEADER and sum(frame[1:25]) & 0xFF == frame[25]


class ToyGaugeSim:
    def __init__(self, world, rate_hz: float):
        self.world = world
        self.schedule = SampleSchedule(rate_hz)
        self.commands: list[bytes] = []
        self.stopped = threading.Event()  # the stop command arrived (the driver sends it as it closes)

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        out = []
        for byte in data:
            command = bytes([byte])
            self.commands.append(command)
            if command == b"P":
                out.append(encode(self.world.gauge_wrench(now_s)))
            elif command == b"S":
                self.schedule.start(now_s)
            elif command == b"X":
                self.schedule.stop()
                self.stopped.set()
        return out

    def tick_interval_s(self):
        return min(0.005, self.schedule.period_s) if self.schedule.next_t is not None else None

    def tick(self, now_s: float) -> list[bytes]:
        return [encode(w) for w in self.world.gauge_samples(self.schedule.due(now_s))]


def simulate_toy(world, clock, *, transport: str, rate_hz: float):
    return serve_bytes(ToyGaugeSim(world, rate_hz), clock, transport=transport, name="toy", gain=1.0)


class ToyGauge(GaugeBase):
    def __init__(self, link: SerialLink, clock, *, gain: float, fresh_after_s: float):
        super().__init__(clock, fresh_after_s=fresh_after_s)
        self.link, self.gain, self.name = link, gain, "gauge"
        self.label = f"gauge (toy on {link.url})"

    def make_sync(self) -> FrameSync:
        return FrameSync(HEADER, FRAME_LENGTH, valid)

    def decode(self, frame: bytes) -> np.ndarray:
        return np.array(struct.unpack("<6f", frame[1:25]), dtype=np.float64) * self.gain

    def _poll_raw(self) -> np.ndarray:
        with self.link.lock:
            self.link.discard_input()
            self.link.write(b"P", "P")
            frame = self.link.read_exact(FRAME_LENGTH, "P")
        if not valid(frame):
            raise FramingError(self.label, "P", frame, "bad header or sum")
        return self.decode(frame)

    def _stream_open(self):
        with self.link.lock:
            self.link.write(b"S", "S")
            self.link.port.timeout = STREAM_POLL_S
        return self.link.read_available

    def _stream_close(self) -> None:
        with self.link.lock:
            self.link.write(b"X", "X")

    def close(self) -> None:
        super().close()
        self.link.close()


def open_toy(cfg, ctx) -> ToyGauge:
    link = SerialLink(cfg.port, baudrate=cfg.baudrate, timeout_s=cfg.timeout_s, device=f"toy gauge on {cfg.port}")
    return ToyGauge(link, ctx.clock, gain=cfg.gain, fresh_after_s=cfg.fresh_after_s)


TOY = DeviceKind(
    "gauge",
    "toy",
    "Toy gauge (a test's own)",
    f"{__name__}:open_toy",
    wire=Wire(baudrate=9600),
    keys=(Key("gain", float, 1.0, positive=True, high=10.0, doc="N per count"),),
    simulator=f"{__name__}:simulate_toy",
)

AXES = """
[axes.z]
driver = "zaber"
port = "/dev/ttyUSB0"
scale = 0.001
travel = [0.0, 10.0]
max_speed = 2.0

[safety]
max_force_N = [5.0, 5.0, 20.0]
max_torque_Nmm = [100.0, 100.0, 100.0]
gel_thickness_mm = 3.0
"""


@pytest.fixture
def toy():
    with registered(TOY) as row:
        yield row


def test_config_reads_a_registered_kind_with_its_own_keys_and_wire_defaults(toy):
    cfg = parse_config(AXES + '[gauge]\ndriver = "toy"\nport = "/dev/ttyUSB1"\ngain = 2.5\n', "r.toml")
    assert (cfg.gauge.driver, cfg.gauge.gain, cfg.gauge.baudrate, cfg.gauge.timeout_s) == ("toy", 2.5, 9600, 0.5)
    with pytest.raises(ConfigError, match=r"r.toml: \[gauge.gain\] must be > 0 and <= 10.0, got -1.0"):
        parse_config(AXES + '[gauge]\ndriver = "toy"\nport = "/dev/ttyUSB1"\ngain = -1.0\n', "r.toml")
    # another kind's key is not this kind's
    with pytest.raises(ConfigError, match=r"\[gauge.device_id\] unknown key"):
        parse_config(AXES + '[gauge]\ndriver = "toy"\nport = "/dev/ttyUSB1"\ndevice_id = 9\n', "r.toml")


def test_unregistered_kind_is_refused_naming_the_known_ones():
    with pytest.raises(ConfigError, match=r"\[gauge.driver\] must be one of 'ft300', 'm8128', 'ati_netft', got 'toy'"):
        parse_config(AXES + '[gauge]\ndriver = "toy"\nport = "/dev/ttyUSB1"\n', "r.toml")


def test_factory_and_simulated_rig_open_the_registered_gauge(toy):
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig

    clock = ScaledClock(20.0)
    with SimulatedRig(clock, gauge="toy", transport="tcp") as sim:
        cfg = sim.config(with_camera=False)
        assert cfg.gauge.driver == "toy" and cfg.gauge.port == sim.servers["gauge"].url
        with Rig.open(cfg, clock) as rig:
            assert isinstance(rig.gauge, ToyGauge) and rig.gauge.streaming
            assert np.allclose(rig.gauge.read().as_array(), sim.world.gauge_wrench(clock.now()), atol=0.5)
            z0 = rig.axes["z"].position()
            with rig.motion("test") as m:  # the force guard reads the toy gauge
                m.move({"z": z0 - 0.2}, 2.0)
            assert abs(rig.axes["z"].position() - (z0 - 0.2)) < 1e-3
        assert sim.gauge_sim.model.stopped.wait(10), sim.gauge_sim.model.commands[-5:]  # the server's own thread
        assert sim.gauge_sim.model.commands[:1] == [b"S"] and b"X" in sim.gauge_sim.model.commands


def test_rig_status_shows_the_registered_gauge(toy, tmp_path):
    from cli.main import app
    from rig.sim.rig_sim import SimulatedRig

    with SimulatedRig(ScaledClock(20.0), gauge="toy", transport="tcp") as sim:
        path = tmp_path / "rig-sim.toml"
        path.write_text(sim.config_toml(with_camera=False))
        result = CliRunner().invoke(app, ["rig", "status", "--config", str(path)])
    assert result.exit_code == 0, result.output
    assert "toy: Toy gauge (a test's own) on socket://127.0.0.1:" in result.output
    assert "Fz" in result.output


def test_the_built_in_rows_are_what_the_config_and_the_cli_offer():
    from cli.sim_cmd import GaugeKind

    assert kinds("axis") == ("zaber", "pr_drive")
    assert kinds("gauge") == ("ft300", "m8128", "ati_netft")
    assert set(kinds("camera")) >= {"v4l2", "folder", "video", "sim"}
    # the enum is made from the rows when the CLI is imported (a row added later is not in it)
    assert set(kinds("gauge", simulated=True)) <= {g.value for g in GaugeKind}
    assert (kind("gauge", "ft300").wire.baudrate, kind("gauge", "m8128").wire.baudrate) == (19200, 115200)
    assert kind("gauge", "ati_netft").wire.baudrate is None  # UDP: a baudrate key is refused
    with pytest.raises(ConfigError, match=r"\[gauge.baudrate\] unknown key"):
        parse_config(AXES + '[gauge]\ndriver = "ati_netft"\nport = "10.0.0.2"\nbaudrate = 9600\n', "r.toml")
    with pytest.raises(ValueError, match="already registered"):
        with registered(DeviceKind("gauge", "ft300", "again", "x:y")):
            pass
