"""Marker flow for the console (sensor_sim/markers.py ``displacements``, cli/console/flow.py)
on rendered marker frames: the same pairs as the full minimum-cost matching, a known shift
recovered, and the flow thread computing only while a page wants it."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from sensor_sim.markers import displacements, find_markers, match, spacing_px


@pytest.fixture(scope="module")
def frames():
    from objects.pose import Pose
    from sensor_sim.light import OpticsSpec
    from sensor_sim.scene import Scene

    scene = Scene("sphere10mm", "rgb_markers", optics=OpticsSpec(kind="rgb_markers", noise_std=0.0))
    still = scene.frame(Pose(0, 0, 0.5, 0)).image
    solved = scene.contact.solver.solve(Pose(0, 0, -0.9, 0), shift_mm=(0.5, 0.0), fields={"uz", "uxy"})
    return still, scene.renderer.render(solved.fields)


def test_a_known_shift_is_recovered(frames):
    still, _ = frames
    ref = find_markers(still)
    d = displacements(ref, np.roll(still, (1, 3), axis=(0, 1)))  # 3 px right, 1 px down
    inside = (d[:, 0] > 20) & (d[:, 0] < 230) & (d[:, 1] > 20) & (d[:, 1] < 230)  # away from the wrapped edge
    assert inside.sum() > 200
    assert np.allclose(d[inside, 2:], (3.0, 1.0), atol=0.1)


def test_the_same_pairs_as_the_full_matching(frames):
    still, sheared = frames
    ref = find_markers(still)
    pitch = spacing_px(ref)
    d = displacements(ref, sheared, pitch_px=pitch)
    a, b = match(ref, find_markers(sheared))  # the full minimum-cost matching, then the same cut
    full = np.hstack([a, b - a])
    full = full[np.linalg.norm(full[:, 2:], axis=1) <= 0.7 * pitch]
    order = lambda rows: rows[np.lexsort((rows[:, 1], rows[:, 0]))]
    assert np.allclose(order(d), order(full))
    assert d[:, 2].mean() > 1.0 and np.abs(d[:, 2:]).max() > 0.5 * pitch  # a real shear along +x, large here


def test_the_flow_thread_works_only_while_wanted(frames):
    from cli.console.flow import MarkerFlow

    still, sheared = frames
    got: list[dict] = []
    arrived = threading.Event()

    def on_flow(flow):
        got.append(flow)
        arrived.set()

    flow = MarkerFlow(on_flow, every_s=0.0)
    flow.start()
    try:
        flow.offer(0, 0.0, still)  # the first frame: the reference
        flow.offer(1, 0.1, sheared)
        assert not arrived.wait(0.5) and flow.computed == 0  # nobody wants it: nothing computed
        flow.wanted = 1
        flow.offer(2, 0.2, sheared)
        assert arrived.wait(30), "no flow computed"
        message = got[-1]
        assert message["index"] == 2 and message["reference_index"] == 0 and message["markers"] == 400
        vectors = np.asarray(message["vectors"])
        assert vectors.shape[1] == 4 and vectors[:, 2].mean() > 1.0
    finally:
        flow.close()
