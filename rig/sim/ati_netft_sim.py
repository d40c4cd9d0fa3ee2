"""A simulated ATI Net F/T: RDT on a loopback UDP port, netftapi2.xml on a loopback HTTP port.

Like the real box it answers the address a request came from: a real-time request
with count N gets N records (0: until stopped), one per datagram at the RDT rate; a
buffered request gets ``buffer_size`` records per datagram; 0x42 sets the software
bias to the present load. rdt_sequence restarts at 1 with every request. Outgoing
datagrams pass the usual ``FaultInjector`` (drop, garble, truncate); ``repeat_next``
sends a datagram twice, as a duplicating network would. The wrench comes from the
shared ``SimWorld`` (or any object with ``gauge_samples(times)`` and a ``clock``).
"""

from __future__ import annotations

import select
import socket
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np

from rig.drivers import ati_netft as rdt
from rig.sim.faults import FaultInjector
from rig.sim.stream_clock import SampleSchedule

INTERNAL_RATE_HZ = 7000  # the Net F/T's own sample rate; ft_sequence counts these


class AtiNetFtSim:
    def __init__(
        self,
        world,
        *,
        rate_hz: float = 1000.0,
        buffer_size: int = 10,
        counts_per_force: int = 1_000_000,
        counts_per_torque: int = 1_000_000,
        force_unit: str = "N",
        torque_unit: str = "N-m",
        rated: tuple[float, ...] = (330, 330, 990, 30, 30, 30),
        faults: FaultInjector | None = None,
    ):
        self.world = world
        self.clock = world.clock
        self.rate_hz = rate_hz
        self.buffer_size = buffer_size
        self.cpf, self.cpt = counts_per_force, counts_per_torque
        self.force_unit, self.torque_unit = force_unit, torque_unit
        self.rated = rated
        self.faults = faults or FaultInjector()
        self.xml_override: bytes | None = None  # tests: serve this page instead
        self.status = 0  # status word put in every record (tests set bits)
        self.counts_override: tuple[int, ...] | None = None  # tests: the next record's counts
        self.requests: list[bytes] = []  # every request datagram, for byte-exact tests
        self.bias_counts = np.zeros(6, dtype=np.int64)
        self._lock = threading.RLock()
        self._arrived = threading.Condition(self._lock)
        self._client = None
        self._mode = None
        self._remaining = 0  # records still to send; 0 = until stopped
        self._seq = 0
        self._pending: list[bytes] = []  # buffered mode: records waiting for a full datagram
        self._repeat = 0
        self.schedule = SampleSchedule(rate_hz, report_on_advance=hasattr(self.clock, "add_listener"))
        self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.udp.bind(("127.0.0.1", 0))
        self.rdt_port = self.udp.getsockname()[1]
        self.http = ThreadingHTTPServer(("127.0.0.1", 0), _page_handler(self))
        self.http_port = self.http.server_address[1]
        self.host = "127.0.0.1"
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self._run, name="sim-netft-rdt", daemon=True),
            threading.Thread(target=self.http.serve_forever, name="sim-netft-http", daemon=True),
        ]
        for t in self._threads:
            t.start()
        if hasattr(self.clock, "add_listener"):
            self.clock.add_listener(self.pump)  # a manual clock emits what became due

    # -- the configuration page ---------------------------------------------------
    def config_xml(self) -> bytes:
        if self.xml_override is not None:
            return self.xml_override
        fu = {v: k for k, v in rdt.FORCE_UNIT_CODES.items()}[self.force_unit]
        tu = {v: k for k, v in rdt.TORQUE_UNIT_CODES.items()}[self.torque_unit]
        fields = {
            "setcfgsel": 0,
            "cfgnam": "sim",
            "cfgcalsn": "FT00000",
            "cfgfu": fu,
            "scfgfu": self.force_unit,
            "cfgtu": tu,
            "scfgtu": self.torque_unit,
            "cfgcpf": self.cpf,
            "cfgcpt": self.cpt,
            "cfgmr": ";".join(f"{v:g}" for v in self.rated),
            "comrdtrate": int(self.rate_hz),
            "comrdtbsiz": self.buffer_size,
            "runstat": f"0x{self.status:08X}",
            "runrate": INTERNAL_RATE_HZ,
        }
        body = "".join(f"<{k}>{v}</{k}>" for k, v in fields.items())
        return f'<?xml version="1.0"?>\n<netft>{body}</netft>'.encode()

    # -- requests ----------------------------------------------------------------
    def _counts(self, values: np.ndarray) -> np.ndarray:
        """N / N·mm → counts in the configured units, saturating at int32."""
        per = np.repeat(
            [self.cpf / rdt.N_PER_FORCE_UNIT[self.force_unit], self.cpt / rdt.NMM_PER_TORQUE_UNIT[self.torque_unit]], 3
        )
        return np.clip(np.round(values * per), -(2**31), 2**31 - 1).astype(np.int64)

    def handle(self, data: bytes, addr, now_s: float) -> None:
        with self._lock:
            self.requests.append(data)
            self._arrived.notify_all()
            if len(data) != rdt.REQUEST.size:
                return  # assumed: the box ignores what is not a request
            header, command, count = rdt.REQUEST.unpack(data)
            if header != rdt.RDT_HEADER:
                return
            if command == rdt.CMD_STOP:
                self.schedule.stop()
                self._mode, self._pending = None, []
            elif command in (rdt.CMD_REALTIME, rdt.CMD_BUFFERED):
                self._client, self._mode, self._remaining = addr, command, count
                self._seq, self._pending = 0, []
                self.schedule.start(now_s)
            elif command == rdt.CMD_BIAS:
                self.bias_counts = self._counts(self.world.gauge_samples([now_s])[0])
        self.pump()

    def wait_request(self, request: bytes, timeout_s: float = 2.0) -> bool:
        """Block (real time, bounded) until the last request received is ``request``."""
        with self._arrived:
            return self._arrived.wait_for(lambda: self.requests[-1:] == [request], timeout=timeout_s)

    def repeat_next(self, n: int = 1) -> None:
        with self._lock:
            self._repeat += n

    # -- records -----------------------------------------------------------------
    def pump(self) -> None:
        with self._lock:
            if self._mode is None:
                return
            times = self.schedule.due(self.clock.now())
            if self._remaining:
                times = times[: self._remaining - self._seq]
            if not times:
                return
            records = []
            for t, w in zip(times, self.world.gauge_samples(times)):
                self._seq += 1
                counts = self._counts(w) - self.bias_counts
                if self.counts_override is not None:
                    counts, self.counts_override = self.counts_override, None
                counts = np.clip(counts, -(2**31), 2**31 - 1)
                records.append(rdt.pack_record(self._seq, int(t * INTERNAL_RATE_HZ), self.status, counts))
            if self._mode == rdt.CMD_REALTIME:
                datagrams = records
            else:
                self._pending += records
                n = len(self._pending) // self.buffer_size * self.buffer_size
                datagrams = [b"".join(self._pending[i : i + self.buffer_size]) for i in range(0, n, self.buffer_size)]
                self._pending = self._pending[n:]
            if self._remaining and self._seq >= self._remaining:
                self.schedule.stop()
                self._mode = None
            for d in datagrams:
                out, _ = self.faults.apply(d)  # assumed: a delay fault is not modelled on UDP
                if out is None:
                    continue
                copies = 1
                if self._repeat:
                    self._repeat -= 1
                    copies = 2
                for _ in range(copies):
                    try:
                        self.udp.sendto(out, self._client)
                    except OSError:
                        pass  # the host went away; UDP does not care

    def _run(self) -> None:
        while not self._stop.is_set():
            period = self.schedule.period_s if self.schedule.next_t is not None else 0.05
            try:
                readable, _, _ = select.select([self.udp], [], [], min(0.005, period))
            except (OSError, ValueError):
                return
            if readable:
                try:
                    data, addr = self.udp.recvfrom(65536)
                except OSError:
                    return
                self.handle(data, addr, self.clock.now())
            self.pump()

    def close(self) -> None:
        self._stop.set()
        self.http.shutdown()
        self.http.server_close()
        self._threads[0].join(timeout=1.0)
        self.udp.close()


def _page_handler(sim: AtiNetFtSim):
    class Handler(BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 (http.server's name)
            if self.path.split("?")[0] != "/" + rdt.CONFIG_PAGE:
                self.send_error(404)
                return
            body = sim.config_xml()
            self.send_response(200)
            self.send_header("Content-Type", "text/xml")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):  # keep test output clean
            pass

    return Handler
