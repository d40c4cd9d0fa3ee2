"""Round-trip latency and stream rates of the drivers against the simulators.

    .venv/bin/python bench/rig_bench.py [--n 500] [--stream-s 3]

Prints a Markdown table. Every exchange is a real one: the driver writes to a pty
(or a loopback socket), the simulator thread parses and answers it.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

from rig.clock import SystemClock
from rig.drivers.ati_netft import AtiNetFT
from rig.drivers.ft300 import FT300
from rig.drivers.m8128 import M8128
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.sim.ati_netft_sim import AtiNetFtSim
from rig.sim.ft300_sim import Ft300Sim
from rig.sim.link import SimServer
from rig.sim.m8128_sim import M8128Sim
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.world import SimWorld
from rig.sim.zaber_sim import ZaberChainSim, ZaberDeviceSim
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink

US = 0.047625e-3


def timed(fn, n: int) -> list[float]:
    fn()  # warm-up
    out = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t) * 1e3)
    return out


def row(name: str, transport: str, samples_ms: list[float]) -> str:
    s = sorted(samples_ms)
    p = lambda q: s[min(len(s) - 1, int(q * len(s)))]
    return f"| {name} | {transport} | {len(s)} | {p(0.5):.3f} | {p(0.99):.3f} | {statistics.fmean(s):.3f} |"


def latency_rows(n: int) -> list[str]:
    clock = SystemClock()
    world = SimWorld(clock)
    rows = []
    for transport in ("pty", "tcp"):
        srv = SimServer(ZaberChainSim(clock, {1: ZaberDeviceSim(world.stages["x"], US)}), clock, transport=transport)
        chain = ZaberChain(SerialLink(srv.url, baudrate=115200, timeout_s=0.5, device="zaber"))
        x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
        rows.append(row("Zaber ASCII position read (`get pos`)", transport, timed(x.position, n)))
        chain.close()
        srv.close()

        srv = SimServer(
            RtuServer({1: PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)}),
            clock,
            transport=transport,
        )
        bus = ModbusBus(srv.url, baudrate=38400, timeout_s=0.5, retries=0, device="bus")
        th = PrDriveAxis(bus, name="theta", device_id=1, pulses_per_rev=10000, travel_per_rev=4.0, unit="deg")
        rows.append(row("PR drive position read (Modbus fc 3, 2 regs)", transport, timed(th.position, n)))
        bus.close()
        srv.close()

        srv = SimServer(Ft300Sim(world), clock, transport=transport)
        g = FT300(ModbusBus(srv.url, baudrate=19200, timeout_s=0.5, retries=0, device="ft300"), clock)
        rows.append(row("FT300 polled wrench read (Modbus fc 3, 6 regs)", transport, timed(g.read, n)))
        g.close()
        g.bus.close()
        srv.close()

        srv = SimServer(M8128Sim(world), clock, transport=transport)
        m = M8128(SerialLink(srv.url, baudrate=115200, timeout_s=0.5, device="m8128"), clock)
        rows.append(row("M8128 single wrench read (`AT+GOD`)", transport, timed(m.read, n)))
        m.close()
        m.link.close()
        srv.close()

    # Net F/T: UDP on loopback whatever the serial transport; one row.
    sim = AtiNetFtSim(world)
    g = AtiNetFT(sim.host, clock, rdt_port=sim.rdt_port, http_port=sim.http_port)
    rows.append(row("ATI Net F/T polled record (RDT cmd 2, count 1)", "udp", timed(g.read, n)))
    g.close()
    sim.close()
    return rows


def stream_rows(seconds: float) -> list[str]:
    clock = SystemClock()
    world = SimWorld(clock)
    rows = []
    cases = [
        ("FT300 stream", "ft300", 100.0),
        ("M8128 stream", "m8128", 100.0),
        ("M8128 stream", "m8128", 1000.0),
        ("FT300 stream (sim pushed to 2 kHz)", "ft300", 2000.0),
        ("Net F/T RDT real-time (udp)", "netft", 1000.0),
        ("Net F/T RDT real-time (udp)", "netft", 7000.0),
        ("Net F/T RDT buffered ×40 (udp)", "netft-buffered", 7000.0),
    ]
    for name, kind, rate in cases:
        if kind == "ft300":
            srv = SimServer(Ft300Sim(world, rate_hz=rate), clock)
            g = FT300(ModbusBus(srv.url, baudrate=19200, timeout_s=0.5, retries=0, device="ft300"), clock)
        elif kind.startswith("netft"):
            srv = AtiNetFtSim(world, rate_hz=rate, buffer_size=40)
            g = AtiNetFT(
                srv.host,
                clock,
                rdt_port=srv.rdt_port,
                http_port=srv.http_port,
                mode="buffered" if kind == "netft-buffered" else "realtime",
            )
        else:
            srv = SimServer(M8128Sim(world, rate_hz=rate), clock)
            g = M8128(SerialLink(srv.url, baudrate=115200, timeout_s=0.5, device="m8128"), clock, rate_hz=int(rate))
            g.configure()
        g.start_stream()
        g.buffer.wait_new(0, 5, timeout_s=2.0)
        n0, t0 = g.buffer.total, time.perf_counter()
        threading.Event().wait(seconds)
        n1, t1 = g.buffer.total, time.perf_counter()
        stats = g.stream_stats()
        gaps = [b.t_s - a.t_s for a, b in zip(g.buffer.since(float("-inf"))[:-1], g.buffer.since(float("-inf"))[1:])]
        gap_p99 = sorted(gaps)[int(0.99 * len(gaps))] * 1e3 if gaps else float("nan")
        g.close()
        srv.close()
        rows.append(f"| {name} | {rate:g} | {(n1 - n0) / (t1 - t0):.1f} | {stats['frames_bad']} | {gap_p99:.2f} |")
    return rows


def help_time_ms(runs: int = 10) -> float:
    rig = str(Path(sys.executable).parent / "rig")
    out = []
    for _ in range(runs):
        t = time.perf_counter()
        subprocess.run([rig, "--help"], capture_output=True, check=True)
        out.append((time.perf_counter() - t) * 1e3)
    return statistics.median(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=500, help="round trips per latency row")
    ap.add_argument("--stream-s", type=float, default=3.0, help="seconds per stream row")
    args = ap.parse_args()
    print(
        f"machine: {platform.node()} {platform.machine()}, {platform.processor() or 'cpu'}, "
        f"{__import__('os').cpu_count()} cores, Python {platform.python_version()}"
    )
    print("\n| exchange | transport | n | p50 ms | p99 ms | mean ms |\n|---|---|---|---|---|---|")
    for r in latency_rows(args.n):
        print(r)
    print("\n| stream | sim rate Hz | sustained samples/s | bad frames | p99 gap ms |\n|---|---|---|---|---|")
    for r in stream_rows(args.stream_s):
        print(r)
    print(f"\n`rig --help`: {help_time_ms():.0f} ms (median of 10 runs, whole process)")


if __name__ == "__main__":
    main()
