"""ATI Net F/T six-axis interface: RDT over UDP (port 49152), configuration over HTTP.

Sources (ATI Net F/T manual 9620-05-NET FT, "UDP Interface Using RDT"; ATI's Java
demo ``NetFTSensor.java``): a request is ``>HHI`` = header 0x1234, command, sample
count (0 = until stopped); a record is 36 bytes ``>IIIiiiiii`` = rdt_sequence,
ft_sequence, status, Fx Fy Fz Tx Ty Tz in counts. Counts per force/torque unit and the
units come from ``http://HOST/netftapi2.xml`` (cfgcpf, cfgcpt, scfgfu, scfgtu; numeric
codes cfgfu/cfgtu; cfgmr the rated range; comrdtrate the RDT rate). A polled sample is
"real-time streaming, count 1", as ATI's demo reads one. Torques leave as N·mm.
"""

from __future__ import annotations

import math
import socket
import struct
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from rig.clock import Clock
from rig.drivers.gauge_base import GaugeBase
from rig.drivers.wrench_stream import STREAM_POLL_S
from rig.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, FramingError

RDT_PORT = 49152
RDT_HEADER = 0x1234
CMD_STOP = 0x0000
CMD_REALTIME = 0x0002
CMD_BUFFERED = 0x0003
CMD_BIAS = 0x0042
REQUEST = struct.Struct(">HHI")
RECORD = struct.Struct(">IIIiiiiii")
RECORD_LENGTH = RECORD.size  # 36
CONFIG_PAGE = "netftapi2.xml"
SEQUENCE_WINDOW = 1000  # an rdt_sequence jump beyond this is a restart, not a loss

# Unit codes of cfgfu/cfgtu (manual, "netftapi2.xml" fields) and the factor to N / N·mm.
FORCE_UNIT_CODES = {1: "lbf", 2: "N", 3: "klbf", 4: "kN", 5: "kgf", 6: "gf"}
TORQUE_UNIT_CODES = {1: "lbf-in", 2: "lbf-ft", 3: "N-m", 4: "N-mm", 5: "kgf-cm", 6: "kN-m"}
LBF_N = 4.4482216152605
N_PER_FORCE_UNIT = {"lbf": LBF_N, "N": 1.0, "klbf": 1000 * LBF_N, "kN": 1000.0, "kgf": 9.80665, "gf": 9.80665e-3}
NMM_PER_TORQUE_UNIT = {
    "lbf-in": LBF_N * 25.4,
    "lbf-ft": LBF_N * 304.8,
    "N-m": 1000.0,
    "N-mm": 1.0,
    "kgf-cm": 98.0665,
    "kN-m": 1e6,
}
# The web page writes "Nm"/"Nmm" as often as "N-m"/"N-mm": compare without separators.
_TORQUE_SPELLINGS = {u.replace("-", "").lower(): u for u in NMM_PER_TORQUE_UNIT}

# System status word (manual, "System Status Code"); any set bit makes a record unusable.
STATUS_BITS = {
    31: "error summary",
    30: "CPU or RAM error",
    29: "digital board error",
    28: "analog board error",
    27: "serial link error",
    26: "program memory error",
    25: "halted: configuration error",
    24: "settings validation error",
    23: "configuration incompatible with calibration",
    22: "network communication failure",
    21: "CAN error",
    20: "RDT communication error",
    19: "EtherNet/IP failure",
    18: "DeviceNet failure",
    17: "transducer saturation or A/D error",
    16: "monitor condition latched",
    14: "watchdog timeout",
    13: "stack check error",
    12: "EEPROM failure",
    11: "flash failure",
    10: "analog board watchdog",
    9: "excitation current too high",
    8: "excitation current too low",
    7: "analog ground out of range",
    6: "analog supply too high",
    5: "analog supply too low",
    4: "serial link data unavailable",
    3: "reference voltage error",
    2: "temperature error",
    1: "HTTP failure",
}


def status_names(status: int) -> list[str]:
    return [STATUS_BITS.get(bit, f"bit {bit}") for bit in range(31, -1, -1) if status >> bit & 1]


def pack_request(command: int, count: int = 0) -> bytes:
    return REQUEST.pack(RDT_HEADER, command, count)


def unpack_record(data: bytes) -> tuple[int, int, int, tuple[int, ...]]:
    """(rdt_sequence, ft_sequence, status, six counts) of one 36-byte record."""
    rdt_seq, ft_seq, status, *counts = RECORD.unpack(data)
    return rdt_seq, ft_seq, status, tuple(counts)


def pack_record(rdt_seq: int, ft_seq: int, status: int, counts) -> bytes:
    return RECORD.pack(rdt_seq & 0xFFFFFFFF, ft_seq & 0xFFFFFFFF, status, *(int(c) for c in counts))


@dataclass(frozen=True)
class NetFtConfig:
    """What the driver needs from netftapi2.xml, checked."""

    counts_per_force: float
    counts_per_torque: float
    force_unit: str
    torque_unit: str
    rdt_rate_hz: int | None
    rdt_buffer_size: int | None
    rated: tuple[float, ...] | None  # cfgmr, in the configured units

    @property
    def scale(self) -> np.ndarray:
        """Counts → [N, N, N, N·mm, N·mm, N·mm]."""
        f = N_PER_FORCE_UNIT[self.force_unit] / self.counts_per_force
        t = NMM_PER_TORQUE_UNIT[self.torque_unit] / self.counts_per_torque
        return np.array([f, f, f, t, t, t])

    @property
    def rated_native(self) -> np.ndarray | None:
        """The rated range in N / N·mm, or None when the page gives none."""
        if self.rated is None:
            return None
        return np.asarray(self.rated) * np.repeat(
            [N_PER_FORCE_UNIT[self.force_unit], NMM_PER_TORQUE_UNIT[self.torque_unit]], 3
        )


def parse_config(xml: bytes, label: str, url: str) -> NetFtConfig:
    """Parse netftapi2.xml; a missing, non-finite, non-positive or unknown value is refused."""
    try:
        fields = {el.tag.rsplit("}", 1)[-1]: (el.text or "").strip() for el in ET.fromstring(xml).iter()}
    except ET.ParseError as exc:
        raise FramingError(label, f"GET {url}", xml[:80], f"unparsable XML: {exc}") from exc

    def bad(key: str, why: str):
        return FramingError(label, f"GET {url}", fields.get(key), f"<{key}> {why}")

    def positive(key: str) -> float:
        try:
            v = float(fields[key])
        except (KeyError, ValueError):
            raise bad(key, "missing or not a number") from None
        if not math.isfinite(v) or v <= 0:
            raise bad(key, "must be a finite positive number")
        return v

    def unit(text_key, code_key, codes, known, spell) -> str:
        name = spell(fields[text_key]) if fields.get(text_key) else None
        code = codes.get(int(fields[code_key])) if fields.get(code_key, "").isdigit() else None
        if name is None and code is None:
            raise bad(text_key, f"unknown unit (and no valid <{code_key}>)")
        if name is not None and name not in known:
            raise bad(text_key, "unknown unit")
        if name is not None and code is not None and name != code:
            raise bad(text_key, f"disagrees with <{code_key}> = {fields[code_key]} ({code})")
        return name if name is not None else str(code)  # both missing was refused above

    def optional_int(key: str) -> int | None:
        return int(fields[key]) if fields.get(key, "").isdigit() else None

    rated = None
    if fields.get("cfgmr"):
        try:
            rated = tuple(float(v) for v in fields["cfgmr"].split(";")[:6])
        except ValueError:
            raise bad("cfgmr", "not six numbers") from None
        if len(rated) != 6 or not all(math.isfinite(v) and v > 0 for v in rated):
            rated = None  # a 0 rating means "not set" (ATI's demo substitutes a default)
    return NetFtConfig(
        counts_per_force=positive("cfgcpf"),
        counts_per_torque=positive("cfgcpt"),
        force_unit=unit("scfgfu", "cfgfu", FORCE_UNIT_CODES, N_PER_FORCE_UNIT, lambda s: s),
        torque_unit=unit(
            "scfgtu",
            "cfgtu",
            TORQUE_UNIT_CODES,
            NMM_PER_TORQUE_UNIT,
            lambda s: _TORQUE_SPELLINGS.get(s.replace("-", "").lower(), s),
        ),
        rdt_rate_hz=optional_int("comrdtrate"),
        rdt_buffer_size=optional_int("comrdtbsiz"),
        rated=rated,
    )


class RdtSync:
    """Turns datagrams into checked records; the stream counterpart of ``FrameSync``.

    UDP may lose, repeat or reorder datagrams: a record whose rdt_sequence does not
    advance is dropped (counted), a jump counts the records lost; a jump beyond
    ``SEQUENCE_WINDOW`` either way is a restarted count (a resync), followed. A record failing
    ``problem`` (status bits, out of range) is counted and never becomes a value.
    """

    def __init__(self, problem):
        self.problem = problem
        self.last_seq: int | None = None
        self.frames_ok = self.frames_bad = self.bytes_skipped = 0
        self.lost = self.out_of_order = self.resyncs = 0

    def feed(self, datagram: bytes) -> list[bytes]:
        if not datagram:
            return []
        if len(datagram) % RECORD_LENGTH:
            self.frames_bad += 1
            self.bytes_skipped += len(datagram)
            return []
        out = []
        for i in range(0, len(datagram), RECORD_LENGTH):
            record = datagram[i : i + RECORD_LENGTH]
            seq = RECORD.unpack_from(record)[0]
            if self.last_seq is not None:
                step = (seq - self.last_seq + 2**31) % 2**32 - 2**31  # sequence numbers wrap
                if -SEQUENCE_WINDOW < step <= 0:
                    self.out_of_order += 1
                    continue
                if 0 < step <= SEQUENCE_WINDOW:
                    self.lost += step - 1
                else:  # far off either way: the box restarted its count; follow it
                    self.resyncs += 1
            self.last_seq = seq
            if self.problem(record) is not None:
                self.frames_bad += 1
                continue
            self.frames_ok += 1
            out.append(record)
        return out


class AtiNetFT(GaugeBase):
    """A Net F/T at ``host``; reads its configuration on construction."""

    def __init__(
        self,
        host: str,
        clock: Clock,
        *,
        name: str = "gauge",
        rdt_port: int = RDT_PORT,
        http_port: int = 80,
        timeout_s: float = 0.5,
        retries: int = 2,
        mode: str = "realtime",
        overrange: float = 1.5,
        buffer_size: int = 4096,
        fresh_after_s: float = 0.05,
    ):
        if mode not in ("realtime", "buffered"):
            raise ValueError(f"mode must be 'realtime' or 'buffered', got {mode!r}")
        super().__init__(clock, buffer_size, fresh_after_s=fresh_after_s)
        self.name, self.host, self.mode = name, host, mode
        self.timeout_s, self.retries = timeout_s, retries
        self.overrange = overrange  # readings beyond this × the rated range are refused
        self.label = f"{name} (ATI Net F/T at {host}:{rdt_port})"
        self.config_url = f"http://{host}:{http_port}/{CONFIG_PAGE}"
        self.config = self.read_config()
        self.status = 0  # the last non-zero status word seen
        self._fault: DeviceFault | None = None
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect((host, rdt_port))  # only the sensor's datagrams are received
        self.sock.settimeout(timeout_s)

    def read_config(self) -> NetFtConfig:
        try:
            with urllib.request.urlopen(self.config_url, timeout=self.timeout_s) as reply:
                body = reply.read(1 << 20)
        except (urllib.error.URLError, OSError) as exc:
            raise DeviceTimeout(self.label, f"GET {self.config_url}", None, f"configuration page: {exc}") from exc
        return parse_config(body, self.label, self.config_url)

    # -- one record ---------------------------------------------------------------
    def _record_problem(self, record: bytes) -> str | None:
        _, _, status, counts = unpack_record(record)
        if status:
            self.status = status
            self._fault = DeviceFault(
                self.label, "RDT record", f"status 0x{status:08X}", "status " + ", ".join(status_names(status))
            )
            return "status"
        rated = self.config.rated_native
        if rated is not None:
            values = np.asarray(counts) * self.config.scale
            if np.any(np.abs(values) > self.overrange * rated):
                return f"beyond {self.overrange:g} × the rated range: {values.round(3).tolist()}"
        return None

    def decode(self, record: bytes) -> np.ndarray:
        return np.asarray(unpack_record(record)[3], dtype=np.float64) * self.config.scale

    def make_sync(self) -> RdtSync:
        return RdtSync(self._record_problem)

    def _check_status(self) -> None:
        fault, self._fault = self._fault, None
        if fault is not None:
            raise fault

    def _drain(self) -> None:
        self.sock.setblocking(False)
        try:
            while True:
                self.sock.recv(65536)
        except (BlockingIOError, ConnectionRefusedError):
            pass
        finally:
            self.sock.settimeout(self.timeout_s)

    def _send(self, command: int, count: int, what: str) -> None:
        try:
            self.sock.send(pack_request(command, count))
        except OSError as exc:
            raise DeviceDisconnected(self.label, what, None, str(exc)) from exc

    def _poll_raw(self) -> np.ndarray:
        what = "RDT real-time, 1 sample"
        for _ in range(self.retries + 1):  # UDP: a lost request or record is asked again
            self._drain()
            self._send(CMD_REALTIME, 1, what)
            try:
                record = self.sock.recv(65536)
            except TimeoutError:
                continue
            except ConnectionRefusedError as exc:
                raise DeviceDisconnected(self.label, what, None, "port unreachable") from exc
            if len(record) != RECORD_LENGTH:
                raise FramingError(self.label, what, record, f"{len(record)} bytes, expected {RECORD_LENGTH}")
            problem = self._record_problem(record)
            self._check_status()
            if problem is not None:
                raise FramingError(self.label, what, record, problem)
            return self.decode(record)
        raise DeviceTimeout(self.label, what, None, f"no record after {self.retries + 1} requests")

    def device_bias(self) -> None:
        """Command 0x42: the sensor subtracts its present load from later records."""
        self._send(CMD_BIAS, 0, "RDT set software bias")

    # -- streaming ------------------------------------------------------------------
    def _stream_open(self):
        self._drain()
        self._fault = None
        self._send(CMD_REALTIME if self.mode == "realtime" else CMD_BUFFERED, 0, "RDT start streaming")
        self.sock.settimeout(STREAM_POLL_S)

        def read_chunk() -> bytes:
            try:
                return self.sock.recv(65536)
            except TimeoutError:
                return b""
            except OSError as exc:
                raise DeviceDisconnected(self.label, "RDT stream", None, str(exc)) from exc

        return read_chunk

    def start_stream(self) -> None:
        """Start, and repeat the start request while no record comes (a lost datagram)."""
        starting, before = self._reader is None, self.buffer.total
        super().start_stream()
        for _ in range(self.retries if starting else 0):
            if self.buffer.wait_new(before, 1, timeout_s=self.timeout_s):
                return
            self._send(CMD_REALTIME if self.mode == "realtime" else CMD_BUFFERED, 0, "RDT start streaming")

    def _stream_close(self) -> None:
        self._send(CMD_STOP, 0, "RDT stop streaming")
        self._drain()  # records still in flight

    def _raw_sample(self):
        self._check_status()
        return super()._raw_sample()

    def _await(self, wait, what: str) -> None:
        self._check_status()
        super()._await(lambda timeout: self._fault is not None or wait(timeout), what)
        self._check_status()

    def stream_stats(self) -> dict:
        stats = super().stream_stats()
        sync = self._reader.sync if self._reader else None
        stats.update({k: getattr(sync, k) if sync else 0 for k in ("lost", "out_of_order", "resyncs")})
        stats["status"] = self.status
        return stats

    def close(self) -> None:
        try:
            super().close()
        finally:
            self.sock.close()
