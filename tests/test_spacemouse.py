"""HID pendant report parsing on recorded reports, and jogging from it."""

from pathlib import Path

import pytest

from rig.drivers.spacemouse import PendantState, ReportError, SpaceMouse, deflection, parse_report

REPORTS = Path(__file__).parent / "data" / "spacemouse_reports.txt"


def recorded():
    for line in REPORTS.read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        cols = line.split()
        tail = cols[-3:]
        report = bytes.fromhex("".join(cols[:-3]))
        yield report, tuple(map(int, tail[0].split(","))), tuple(map(int, tail[1].split(","))), int(tail[2])


class FakeHid:
    """hidapi's device interface fed from recorded reports."""

    def __init__(self, reports):
        self.reports = list(reports)
        self.closed = False

    def read(self, size, timeout_ms=0):
        return list(self.reports.pop(0)[:size]) if self.reports else []

    def close(self):
        self.closed = True


def test_recorded_reports_parse_in_sequence():
    state = PendantState()
    rows = list(recorded())
    assert len(rows) == 8
    for report, translation, rotation, buttons in rows:
        state = parse_report(report, state)
        assert (state.translation, state.rotation, state.buttons) == (translation, rotation, buttons)


def test_malformed_reports_are_errors():
    with pytest.raises(ReportError):
        parse_report(b"", PendantState())
    with pytest.raises(ReportError, match="too short"):
        parse_report(bytes.fromhex("01 5e01"), PendantState())


def test_deflection_dead_band_and_z_sign():
    s = PendantState(translation=(350, -30, 200), rotation=(0, 0, -175))
    assert deflection(s, "x") == 1.0
    assert deflection(s, "y") == 0.0  # inside the dead band
    assert deflection(s, "z") == pytest.approx(-200 / 350)  # pushing the cap down lowers z
    assert deflection(s, "theta") == pytest.approx(-0.5)


def test_poll_applies_every_waiting_report():
    hid = FakeHid(r[0] for r in recorded())
    pendant = SpaceMouse(hid)
    state = pendant.poll()
    assert state.translation == (10, 11, 12) and state.rotation == (13, 14, 15)
    pendant.close()
    assert hid.closed


def test_pendant_jog_moves_the_simulated_axis():
    from cli.interactive import jog_with_pendant
    from rig.clock import ScaledClock
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig

    reports = [bytes.fromhex("01 0000 0000 a2fe"), bytes.fromhex("01 0000 0000 0000"), bytes.fromhex("03 01 00")]

    class OneReportPerPoll(FakeHid):
        def read(self, size, timeout_ms=0):
            return super().read(size) if timeout_ms else []

    with SimulatedRig(ScaledClock(20.0)) as sim, Rig.open(sim.config(), sim.clock, axes=("z",)) as rig:
        z0 = rig.axes["z"].position()
        with rig.motion("jog") as m:
            jog_with_pendant(m, "z", 0.1, None, pendant=SpaceMouse(OneReportPerPoll(reports)))
        assert rig.axes["z"].position() == pytest.approx(z0 + 0.1, abs=1e-4)  # pulled up: z rises one step
