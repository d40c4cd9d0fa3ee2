"""A scene: an indenter on a sensor, asked for forces, images, or both.

It computes only what is asked: no image → no displacement fields and no render;
a sensor without markers → no tangential displacement field; no shear or twist →
no tangential solve at all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from objects.pose import Pose
from sensor_sim.contact import ContactResult, SensorGeometry
from sensor_sim.elastomer import Elastomer
from sensor_sim.light import OpticsSpec
from sensor_sim.optics import Renderer
from sensor_sim.world_contact import ElastomerContact


@dataclass
class SceneFrame:
    wrench: np.ndarray  # (6,) N, N·mm
    image: np.ndarray | None  # (H, W, 3) BGR uint8
    contact: ContactResult


class Scene:
    def __init__(
        self,
        indenter: str = "sphere10mm",
        kind: str = "rgb",
        *,
        gel: Elastomer | None = None,
        geometry: SensorGeometry | None = None,
        optics: OpticsSpec | None = None,
        background: np.ndarray | None = None,
        seed: int = 0,
    ):
        self.geometry = geometry or SensorGeometry()
        self.contact = ElastomerContact(indenter, gel, self.geometry)
        self.optics = optics or OpticsSpec(kind=kind)
        self._renderer: Renderer | None = None
        self._background = background
        self._seed = seed

    @property
    def renderer(self) -> Renderer:
        if self._renderer is None:  # built on first image: a forces-only scene never pays for it
            self._renderer = Renderer(self.optics, self.geometry, self._background, self._seed)
        return self._renderer

    def frame(self, pose: Pose, *, image: bool = True) -> SceneFrame:
        """Wrench (and image) at ``pose``. Past the gel thickness the indenter presses on
        the window: the image is the fully squeezed gel, the wrench adds the window's
        steep load, and ``frame.contact.on_backing`` is set (see ``backing.py``).
        ``frame.contact.converged`` says whether the solves reached their tolerance.
        Raises PhysicsInputError for a non-finite pose."""
        fields = self.renderer.needs() if image else frozenset()
        result = self.contact.solve(pose, fields)
        img = self.renderer.render(result.fields) if image else None
        return SceneFrame(result.wrench.copy(), img, result)
