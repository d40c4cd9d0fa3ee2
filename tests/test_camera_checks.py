"""Camera checks before a run (issue 14): `rig status` reports the camera, `rig camera
snapshot` writes a frame, and `rig sim serve`'s config names a camera that another
process reads over a real loopback socket -- so `--config rig-sim.toml` works wherever
`--sim` does, run-protocol included.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest
from processes import stop
from typer.testing import CliRunner

from cli.main import app
from rig.clock import SystemClock
from rig.drivers.camera import Camera, source_settings
from rig.drivers.camera_stream import HEADER, StreamSource, decode_header, encode_frame, parse_address
from rig.errors import DeviceDisconnected, FramingError
from rig.sim.rig_sim import SimulatedRig

runner = CliRunner()

TINY = """
[protocol]
name = "tiny"
object = "sphere10mm"
sensor = "rgb"

[motion]
depth_step_mm = 0.5
max_depth_mm = 0.5
shear_mm = 0.2
twist_deg = 1.0
speed_mm_s = 0.25
twist_speed_deg_s = 2.5
approach_mm = 0.3
approach_speed_mm_s = 2.0

[capture]
rate_hz = 2.5
"""  # 0.25 mm/s: inside the speed envelope of a real-time simulated rig (~0.35 mm/s in contact)


@pytest.fixture
def served(tmp_path):
    """What `rig sim serve --transport tcp` runs: the simulators and the camera stream, and its config."""
    with SimulatedRig(transport="tcp") as sim:
        camera = sim.serve_camera()
        path = tmp_path / "rig-sim.toml"
        path.write_text(sim.config_toml())
        yield sim, camera, path


def test_frame_header_round_trip_and_refusals():
    image = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
    data = encode_frame(image, 7)
    assert data[:4] == b"TFR1" and len(data) == HEADER.size + image.size
    assert decode_header(data[: HEADER.size], "cam") == (4, 5, 3, 7)
    with pytest.raises(FramingError, match="not a camera-stream frame header"):
        decode_header(b"XXXX" + data[4 : HEADER.size], "cam")
    assert parse_address("tcp://127.0.0.1:4000") == ("127.0.0.1", 4000)
    with pytest.raises(ValueError, match="tcp://HOST:PORT"):
        parse_address("127.0.0.1:4000")


def test_snapshot_sim_writes_a_frame(tmp_path):
    out = tmp_path / "frame.png"
    result = runner.invoke(app, ["rig", "camera", "snapshot", "--sim", "--out", str(out)])
    assert result.exit_code == 0, result.output
    image = cv2.imread(str(out))
    assert image.shape == (256, 256, 3) and image.std() > 1.0  # a rendered gel, not a blank
    assert "256x256 at 25 fps, exposure locked, white balance locked" in result.output


def test_snapshot_and_status_against_the_served_config(served, tmp_path):
    sim, camera, path = served
    out = tmp_path / "served.png"
    result = runner.invoke(app, ["rig", "camera", "snapshot", "--config", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert cv2.imread(str(out)).shape == (256, 256, 3) and camera.frames_sent >= 2
    result = runner.invoke(app, ["rig", "status", "--config", str(path)])
    assert result.exit_code == 0, result.output
    output = " ".join(result.output.split())  # rich wraps long lines
    assert f"camera stream: camera stream over TCP (`rig sim serve`) on {camera.url}: 256x256 at 25 fps" in output
    assert "exposure locked, white balance locked, newest frame" in output and "Fz" in output


def test_served_camera_gone_or_wrong_size_is_one_line(served, tmp_path):
    sim, camera, path = served
    result = runner.invoke(app, ["rig", "camera", "snapshot", "--config", str(path), "--out", str(tmp_path / "a.txt")])
    assert result.exit_code != 0 and "must end in one of .png" in result.output
    wrong_size = r"sends 256x256 frames but the config's \[camera\] width x height is 320x240"
    with pytest.raises(FramingError, match=wrong_size):
        source = StreamSource(camera.url, SystemClock(), fps=25.0, size=(240, 320))
        try:
            source.read()
        finally:
            source.release()
    camera.close()
    result = runner.invoke(app, ["rig", "camera", "snapshot", "--config", str(path), "--out", str(tmp_path / "b.png")])
    assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1
    assert f"camera stream {camera.url}" in result.output and "is `rig sim serve` running?" in result.output


def test_a_server_that_hangs_up_mid_frame_is_named():
    listener = socket.create_server(("127.0.0.1", 0))

    def half_a_frame():
        conn, _ = listener.accept()
        conn.recv(1)
        conn.sendall(encode_frame(np.zeros((8, 8, 3), np.uint8), 0)[:30])
        conn.close()

    thread = threading.Thread(target=half_a_frame)
    thread.start()
    source = StreamSource(f"tcp://127.0.0.1:{listener.getsockname()[1]}", SystemClock(), fps=25.0)
    with pytest.raises(DeviceDisconnected, match="the server closed the connection"):
        source.read()
    source.release()
    thread.join()
    listener.close()


class FakeV4L2:
    """The part of cv2.VideoCapture that the report reads, as a V4L2 camera answers it."""

    def __init__(self, auto_exposure: float, auto_wb: float):
        self.props = {cv2.CAP_PROP_FPS: 30.0, cv2.CAP_PROP_AUTO_EXPOSURE: auto_exposure, cv2.CAP_PROP_AUTO_WB: auto_wb}

    def getBackendName(self):  # noqa: N802 (OpenCV's name)
        return "V4L2"

    def get(self, prop):
        return self.props[prop]

    def read(self):
        return True, np.zeros((48, 64, 3), np.uint8)

    def release(self):
        pass


@pytest.mark.parametrize(
    "auto_exposure, auto_wb, locked", [(1.0, 0.0, (True, True)), (3.0, 1.0, (False, False)), (0.25, 1.0, (True, False))]
)
def test_v4l2_locks_are_read_from_the_device(auto_exposure, auto_wb, locked):
    settings = source_settings(FakeV4L2(auto_exposure, auto_wb))
    assert (settings["exposure_locked"], settings["white_balance_locked"]) == locked and settings["fps"] == 30.0
    camera = Camera(FakeV4L2(auto_exposure, auto_wb), SystemClock(), discard_frames=0)
    try:
        report = camera.report()
    finally:
        camera.close()
    assert (report.width_px, report.height_px) == (64, 48) and report.newest_age_s < 1.0


@pytest.fixture
def serve_process(tmp_path):
    """`rig sim serve --transport tcp` in a process of its own, as a user runs it; yields its config."""
    cfg = tmp_path / "rig-sim.toml"
    server = subprocess.Popen(
        [str(Path(sys.executable).parent / "rig"), "sim", "serve", "--out", str(cfg), "--transport", "tcp"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        lines = []
        for line in server.stdout:
            lines.append(line)
            if line.startswith("serving"):
                break
        assert any(line.startswith("camera  tcp://127.0.0.1:") for line in lines), lines
        yield cfg
    finally:
        stop(server)


@pytest.mark.slow
def test_run_protocol_against_rig_sim_serve_completes(serve_process, tmp_path):
    """The whole chain a user runs in two terminals: the stages, the gauge stream and the camera
    stream over loopback sockets to another process, with --config rig-sim.toml instead of --sim."""
    from acquisition import schema as S
    from acquisition.run_file import open_for_reading

    assert 'driver = "stream"' in serve_process.read_text()
    protocol = tmp_path / "tiny.toml"
    protocol.write_text(TINY)
    out = tmp_path / "tiny.h5"
    result = runner.invoke(
        app, ["rig", "run-protocol", str(protocol), "--config", str(serve_process), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert "complete: 21/21 frames" in result.output
    with open_for_reading(out) as f:
        assert f[S.FRAMES].shape == (21, 256, 256, 3) and f[S.FRAMES][-1].std() > 1.0  # rendered gel frames
        # the served rig's simulated sensor is named in the run, as a --sim run names it (never "a real sensor")
        from sensor_sim.profile import default_profile

        recorded = f.attrs[S.ATTR_SENSOR_PROFILE]
        assert f'name = "{default_profile().name}"' in recorded and default_profile().content_hash() in recorded
