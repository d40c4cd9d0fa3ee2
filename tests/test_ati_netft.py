"""ATI Net F/T: RDT packing from the manual, and the driver against its simulator on loopback.

Sources: ATI Net F/T manual 9620-05-NET FT, "UDP Interface Using RDT" (request
``>HHI`` with header 0x1234, commands 0/2/3/0x42; 36-byte ``>IIIiiiiii`` record) and
"System Status Code"; ATI's Java demo NetFTSensor.java (big-endian byte order of the
request, a polled read = command 2 with count 1, bias = command 0x42) and
NetFTSampleGUI.java (the netftapi2.xml fields cfgcpf, cfgcpt, scfgfu, scfgtu, cfgmr).
"""

import numpy as np
import pytest

from rig.clock import SystemClock
from rig.drivers import ati_netft as rdt
from rig.drivers.ati_netft import AtiNetFT
from rig.errors import DeviceFault, DeviceTimeout, FramingError
from rig.sim.ati_netft_sim import AtiNetFtSim
from rig.sim.contact import SpringContact
from rig.sim.world import SimWorld
from rig.types import ForceGauge

FZ_1MM = 6.0 + 0.35  # placeholder spring at 1 mm + the world's unloaded bias, N


@pytest.fixture
def world():
    w = SimWorld(SystemClock(), contact=SpringContact())
    w.stages["z"]._pos = w.spec.geometry["z"].origin + 1.0  # pressed 1 mm
    return w


@pytest.fixture
def sims():
    made = []
    yield made
    for s in made:
        s.close()


def open_pair(world, sims, *, mode="realtime", **sim_kwargs):
    sim = AtiNetFtSim(world, **sim_kwargs)
    sims.append(sim)
    g = AtiNetFT(sim.host, world.clock, rdt_port=sim.rdt_port, http_port=sim.http_port, mode=mode, timeout_s=0.5)
    return g, sim


# -- byte-exact packing ---------------------------------------------------------------


def test_requests_byte_exact_from_the_manual():
    # Manual "RDT Request": uint16 0x1234, uint16 command, uint32 sample count, big-endian
    # (NetFTSensor.java writes header, command, count most significant byte first).
    assert rdt.pack_request(rdt.CMD_REALTIME, 0) == bytes.fromhex("1234 0002 00000000")
    assert rdt.pack_request(rdt.CMD_STOP, 0) == bytes.fromhex("1234 0000 00000000")
    assert rdt.pack_request(rdt.CMD_BUFFERED, 10) == bytes.fromhex("1234 0003 0000000a")
    assert rdt.pack_request(rdt.CMD_BIAS, 0) == bytes.fromhex("1234 0042 00000000")
    assert rdt.pack_request(rdt.CMD_REALTIME, 70000) == bytes.fromhex("1234 0002 00011170")


def test_record_unpacks_byte_exact():
    # Manual "RDT Record": uint32 rdt_sequence, ft_sequence, status; int32 Fx..Tz; big-endian.
    record = bytes.fromhex("00000005 0001e240 00000000 000f4240 fff0bdc0 000000017fffffff 80000000 fffffffe")
    assert len(record) == rdt.RECORD_LENGTH == 36
    assert rdt.unpack_record(record) == (5, 123456, 0, (1_000_000, -1_000_000, 1, 2**31 - 1, -(2**31), -2))
    assert rdt.pack_record(5, 123456, 0, (1_000_000, -1_000_000, 1, 2**31 - 1, -(2**31), -2)) == record


def test_status_bits_are_named():
    assert rdt.status_names(0) == []
    assert rdt.status_names(0x80020000) == ["error summary", "transducer saturation or A/D error"]
    assert rdt.status_names(0x80010000) == ["error summary", "monitor condition latched"]


XML = (
    b'<?xml version="1.0"?><netft><cfgfu>2</cfgfu><scfgfu>N</scfgfu><cfgtu>3</cfgtu><scfgtu>Nm</scfgtu>'
    b"<cfgcpf>1000000</cfgcpf><cfgcpt>1000000</cfgcpt><cfgmr>330;330;990;30;30;30</cfgmr>"
    b"<comrdtrate>1000</comrdtrate><comrdtbsiz>40</comrdtbsiz></netft>"
)


def test_config_page_parsed_and_scaled_to_N_and_Nmm():
    cfg = rdt.parse_config(XML, "gauge", "http://x/netftapi2.xml")
    assert (cfg.force_unit, cfg.torque_unit, cfg.rdt_rate_hz, cfg.rdt_buffer_size) == ("N", "N-m", 1000, 40)
    np.testing.assert_allclose(cfg.scale, [1e-6, 1e-6, 1e-6, 1e-3, 1e-3, 1e-3])  # N·m → N·mm ×1000
    np.testing.assert_allclose(cfg.rated_native, [330, 330, 990, 30000, 30000, 30000])
    lbf = rdt.parse_config(
        XML.replace(b"<cfgfu>2</cfgfu><scfgfu>N</scfgfu>", b"<cfgfu>1</cfgfu><scfgfu>lbf</scfgfu>").replace(
            b"<cfgtu>3</cfgtu><scfgtu>Nm</scfgtu>", b"<cfgtu>1</cfgtu><scfgtu>lbf-in</scfgtu>"
        ),
        "gauge",
        "u",
    )
    np.testing.assert_allclose(lbf.scale, [4.4482216152605e-6] * 3 + [112.9848290276167e-6] * 3, rtol=1e-12)


@pytest.mark.parametrize(
    "old, new, match",
    [
        (b"<cfgcpf>1000000</cfgcpf>", b"<cfgcpf>NaN</cfgcpf>", "cfgcpf"),
        (b"<cfgcpt>1000000</cfgcpt>", b"<cfgcpt>0</cfgcpt>", "cfgcpt"),
        (b"<cfgcpf>1000000</cfgcpf>", b"", "cfgcpf"),
        (b"<scfgfu>N</scfgfu>", b"<scfgfu>furlong</scfgfu>", "scfgfu"),
        (b"<cfgtu>3</cfgtu>", b"<cfgtu>4</cfgtu>", "disagrees"),
    ],
)
def test_bad_config_is_refused(old, new, match):
    with pytest.raises(FramingError, match=match):
        rdt.parse_config(XML.replace(old, new), "gauge", "u")


def rec(seq, status=0):
    return rdt.pack_record(seq, seq, status, (0,) * 6)


def test_sequence_gaps_counted_duplicates_and_old_records_dropped():
    sync = rdt.RdtSync(lambda r: None)
    assert len(sync.feed(rec(1) + rec(2))) == 2  # buffered: two records in one datagram
    assert len(sync.feed(rec(5))) == 1 and sync.lost == 2
    assert sync.feed(rec(5)) == [] and sync.feed(rec(4)) == [] and sync.out_of_order == 2
    assert sync.feed(rec(6)[:20]) == [] and sync.frames_bad == 1  # not a whole record
    sync.last_seq = 2**32 - 1
    assert len(sync.feed(rec(0))) == 1 and sync.lost == 2  # the counter wraps
    assert len(sync.feed(rec(500_000))) == 1 and (sync.resyncs, sync.lost) == (1, 2)  # a restart, followed


# -- driver against the simulator -------------------------------------------------------


def test_identification_and_polled_sample(world, sims):
    g, sim = open_pair(world, sims)
    assert isinstance(g, ForceGauge)
    assert (g.config.counts_per_force, g.config.torque_unit, g.config.rdt_rate_hz) == (1e6, "N-m", 1000)
    w = g.read()
    assert sim.requests[-1] == bytes.fromhex("1234 0002 00000001")  # one real-time record
    expected = world.true_wrench() + np.array(world.spec.gauge_offset)
    np.testing.assert_allclose(w.as_array(), expected, atol=0.3)
    assert w.fz_N == pytest.approx(FZ_1MM, abs=0.05)
    g.close()


def test_units_other_than_newton_are_converted(world, sims):
    g, _ = open_pair(
        world,
        sims,
        force_unit="lbf",
        torque_unit="lbf-in",
        counts_per_force=1_000_000,
        counts_per_torque=1_000_000,
        rated=(75, 75, 225, 260, 260, 260),
    )
    assert g.read().fz_N == pytest.approx(FZ_1MM, abs=0.05)
    g.close()


@pytest.mark.parametrize("mode, rate_hz", [("realtime", 500.0), ("buffered", 2000.0)])
def test_stream_at_the_set_rate_then_stop(world, sims, mode, rate_hz):
    g, sim = open_pair(world, sims, mode=mode, rate_hz=rate_hz, buffer_size=20)
    g.start_stream()
    start = bytes.fromhex("1234 0002 00000000" if mode == "realtime" else "1234 0003 00000000")
    assert start in sim.requests
    n0, t0 = g.buffer.total, world.clock.now()
    n = int(rate_hz * 0.5)
    assert g.buffer.wait_new(n0, n, timeout_s=5.0)
    rate = (g.buffer.total - n0) / (world.clock.now() - t0)
    assert rate == pytest.approx(rate_hz, rel=0.25)
    samples = g.buffer.since(float("-inf"))
    if mode == "buffered":  # 20 records share one datagram, hence one arrival stamp
        assert len({s.t_s for s in samples}) <= len(samples) // 20 + 1
    assert g.read().fz_N == pytest.approx(FZ_1MM, abs=0.05)
    g.stop_stream()
    assert sim.wait_request(bytes.fromhex("1234 0000 00000000"))
    after = g.buffer.total
    assert not g.buffer.wait_new(after, 1, timeout_s=0.1)  # nothing more arrives
    assert g.read().fz_N == pytest.approx(FZ_1MM, abs=0.05)  # polled again
    g.close()


def test_device_bias_zeroes_the_present_load(world, sims):
    g, sim = open_pair(world, sims)
    assert g.read().fz_N == pytest.approx(FZ_1MM, abs=0.05)
    g.device_bias()
    assert sim.wait_request(bytes.fromhex("1234 0042 00000000"))
    np.testing.assert_allclose(g.read().as_array(), 0.0, atol=0.3)
    world.stages["z"]._pos += 1.0  # 2 mm: the bias stays, the extra load shows
    assert g.read().fz_N == pytest.approx(6.0 * 2**1.5 - 6.0, abs=0.05)
    g.close()


def test_host_tare_from_the_stream(world, sims):
    g, _ = open_pair(world, sims)
    g.start_stream()
    bias = g.tare(20)
    assert bias[2] == pytest.approx(FZ_1MM, abs=0.05)
    assert abs(g.read().fz_N) < 0.05
    g.close()


def test_dropped_and_repeated_datagrams_are_counted_not_used(world, sims):
    g, sim = open_pair(world, sims, rate_hz=1000.0)
    g.start_stream()
    assert g.buffer.wait_new(g.buffer.total, 5, timeout_s=2.0)
    sim.faults.drop_next(3)
    sim.repeat_next(2)
    assert g.buffer.wait_new(g.buffer.total, 30, timeout_s=3.0)
    stats = g.stream_stats()
    assert stats["lost"] == 3
    assert stats["out_of_order"] == 2
    seqs = [s.t_s for s in g.buffer.since(float("-inf"))]
    assert seqs == sorted(seqs)
    g.close()


def test_bad_status_is_a_fault_naming_the_bits(world, sims):
    g, sim = open_pair(world, sims)
    sim.status = 0x80020000
    with pytest.raises(DeviceFault, match="transducer saturation"):
        g.read()
    g.start_stream()
    with pytest.raises(DeviceFault, match="error summary, transducer saturation"):
        for _ in range(50):
            g.read()
            g.buffer.wait_new(g.buffer.total, 1, timeout_s=0.05)
    assert g.stream_stats()["status"] == 0x80020000
    sim.status = 0
    assert g.buffer.wait_new(g.buffer.total, 3, timeout_s=2.0)
    try:
        g.read()
    except DeviceFault:
        pass  # a fault latched before the recovery is reported once
    assert g.read().fz_N == pytest.approx(FZ_1MM, abs=0.05)
    g.close()


def test_value_beyond_the_rated_range_is_refused(world, sims):
    g, sim = open_pair(world, sims)
    sim.counts_override = (0, 0, 2**31 - 1, 0, 0, 0)  # 2147 N on a 990 N axis
    with pytest.raises(FramingError, match="rated range"):
        g.read()
    g.start_stream()
    assert g.buffer.wait_new(g.buffer.total, 3, timeout_s=2.0)
    sim.counts_override = (0, 0, -(2**31), 0, 0, 0)
    bad_before = g.stream_stats()["frames_bad"]
    assert g.buffer.wait_new(g.buffer.total, 20, timeout_s=2.0)
    assert g.stream_stats()["frames_bad"] == bad_before + 1
    assert max(abs(s.fz_N) for s in g.buffer.since(float("-inf"))) < 10.0
    g.close()


def test_nan_in_the_configuration_refuses_to_open(world, sims):
    sim = AtiNetFtSim(world)
    sims.append(sim)
    sim.xml_override = XML.replace(b"<cfgcpf>1000000</cfgcpf>", b"<cfgcpf>nan</cfgcpf>")
    with pytest.raises(FramingError, match="cfgcpf"):
        AtiNetFT(sim.host, world.clock, rdt_port=sim.rdt_port, http_port=sim.http_port)


def test_silent_sensor_times_out(world, sims):
    g, sim = open_pair(world, sims)
    sim.faults.drop_next(10)
    g.timeout_s = 0.05
    g.sock.settimeout(0.05)
    with pytest.raises(DeviceTimeout, match="no record after 3 requests"):
        g.read()
    g.close()


def test_simulated_rig_with_a_net_ft_moves_under_its_force_guard():
    """Config kind `ati_netft`: the config, the factory and the simulated rig open it like any gauge."""
    from rig.clock import ScaledClock
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig

    clock = ScaledClock(20.0)
    with SimulatedRig(clock, gauge="ati_netft") as sim:
        cfg = sim.config(with_camera=False)
        assert cfg.gauge.driver == "ati_netft" and cfg.gauge.rdt_port == sim.netft.rdt_port
        with Rig.open(cfg, clock) as rig:
            assert type(rig.gauge).__name__ == "AtiNetFT"
            z0 = rig.axes["z"].position()
            with rig.motion("test") as m:
                m.move({"z": z0 - 0.5}, 2.0)
            assert abs(rig.axes["z"].position() - (z0 - 0.5)) < 1e-3
            assert np.all(np.isfinite(rig.status().wrench.as_array()))
