"""Load a trained run for generation: the EMA weights and the conditioning statistics."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from torch import nn

from acquisition import schema as S
from dataset.condition import condition_image, normalise_wrench
from dataset.torch_dataset import condition_of, image_to_tensor, scale_images, tensor_to_image
from model.conditioning.physics_condition import PhysicsSpec, resize
from model.denoiser import checkpoint as C
from model.denoiser.config import ModelConfig
from model.denoiser.diffusion import Diffusion
from model.denoiser.registry import build_network


def add_physics(items: list[dict], size: int, spec: PhysicsSpec) -> None:
    """Give each item without one its ``physics`` field: the physics render of its run frame at its
    measured pose and wrench through the model's ``spec`` (what the training cache holds,
    model/conditioning/physics_condition.py), rendered now from its ``run_path``: the wrench is the item's
    ``wrench_raw`` (N, N·mm) where it has one
    (a force sweep's), else the run's recorded one at its frame; an item marked ``depth_from_fz``
    is rendered at the depth where the simulator's contact gives that wrench's Fz (as `generate`
    renders a pose given without z, model/conditioning/force_render.py). The item keeps the render, so a second
    sampler setting does not render it again."""
    from acquisition.run_reader import RunReader
    from model.conditioning.force_render import force_pose

    renderers: dict = {}
    recorded: dict[str, np.ndarray] = {}
    for it in items:
        if "physics" in it:
            continue
        path = it["run_path"]
        if path not in renderers:
            with RunReader.open(path) as run:
                obj = run.text(S.ATTR_OBJECT)
                recorded[path] = run.rows[S.WRENCH]
            renderers[path] = spec.renderer(obj, where=path)
        raw = it.get("wrench_raw")
        wrench = np.asarray(raw, dtype=float) if raw is not None else recorded[path][int(it["frame"])]
        pose = it["pose"].numpy().astype(float)
        if it.get("depth_from_fz"):  # the depth where the simulator's contact gives this Fz
            pose, note = force_pose(renderers[path], pose, float(wrench[2]))
            if note and float(wrench[2]) > 0:  # past what the gel can give (no load renders the touch, rightly)
                it["physics_note"] = note
        it["physics"] = image_to_tensor(resize(renderers[path].render(pose, wrench), size))


def generate_items(
    net,
    diffusion: Diffusion,
    items: list[dict],
    device,
    *,
    steps: int,
    sampler: str,
    seed: int,
    guidance: float = 1.0,
    batch_size: int = 64,
    physics: PhysicsSpec | None = None,
    same_noise: bool = False,
    autocast: torch.dtype | None = None,
):
    """Generated frames (BGR uint8), in order, for Dataset items (their condition and wrench),
    ``batch_size`` at a time from one noise stream seeded with ``seed``; ``same_noise``: every item
    from the one initial noise the first item alone would get (a deterministic sampler: DDIM, DPM), as
    generating each alone from ``seed`` does, in one batch (``Diffusion.sample``). A physics-conditioned
    network gets each item's physics render: the item's own, else rendered through ``physics``
    (the model's PhysicsSpec, ``add_physics``); a model whose physics channels sit at the depth Fz
    implies (``physics_depth = "force"``) gets every render there. ``autocast``: the network's
    arithmetic (None: fp32; model/denoiser/precision.py)."""
    cfg = getattr(net, "cfg", None)
    g = torch.Generator(device=device).manual_seed(seed)
    for lo in range(0, len(items), batch_size):
        chunk = items[lo : lo + batch_size]
        if cfg is not None and cfg.uses_physics and any("physics" not in it for it in chunk):
            if physics is None:
                raise ValueError(f"a {cfg.conditioning!r} model needs its physics render's record to generate")
            if cfg.force_depth:  # every render at the depth its Fz implies (add_physics keeps it in the item)
                for it in chunk:
                    it["depth_from_fz"] = True
            add_physics(chunk, cfg.image_size, physics)
        cond = scale_images(torch.stack([condition_of(it) for it in chunk]).to(device))
        wrench = torch.stack([it["wrench"] for it in chunk]).to(device)
        if same_noise:  # each batch from the seed's first draw, as each item alone would be
            g = torch.Generator(device=device).manual_seed(seed)
        out = diffusion.sample(
            net,
            cond,
            wrench,
            steps=steps,
            sampler=sampler,
            guidance=guidance,
            generator=g,
            same_noise=same_noise,
            autocast=autocast,
        )
        yield from (tensor_to_image(x) for x in out)


@dataclass
class TrainedModel:
    net: nn.Module  # the EMA weights of the network ModelConfig.network names
    diffusion: Diffusion
    cfg: ModelConfig
    wrench_mean: np.ndarray
    wrench_std: np.ndarray
    mm_per_px: float  # the training frames' scale...
    frame_px: int  # ...at this many pixels across: an object image spans frame_px × mm_per_px mm
    device: torch.device
    physics: PhysicsSpec | None = None  # what renders the physics channels (physics conditioning only)
    _renderers: dict | None = None  # object name → its ObjectRender, made on first use
    trained: str = ""  # how far it was trained, in words (from the checkpoint; reports state it)
    autocast: torch.dtype | None = None  # the network's arithmetic when sampling (None: fp32)

    @classmethod
    def load(cls, run_dir: str | Path, device: str = "cpu", precision: str = "auto") -> "TrainedModel":
        """The run's EMA weights on ``device``, sampling in the arithmetic ``precision`` gives there
        (``--mixed-precision``: auto, no, bf16; model/denoiser/precision.py)."""
        from model.denoiser.precision import sampling_dtype

        dev = torch.device(device)
        autocast = sampling_dtype(precision, dev)  # refused before the checkpoint is read
        run_dir = C.run_folder(run_dir)  # the training folder, its checkpoint folder or a file in it
        ck = C.folder(run_dir)
        meta = C.read_state(
            ck,
            hint=" (--checkpoint takes the folder `train --out DIR` wrote, DIR/checkpoint or a file in it; "
            f"train one with `train --out {run_dir}`)",
        )
        cfg = C.model_config(meta, ck / C.STATE)
        mean, std, mm_per_px, frame_px = C.conditioning(meta, ck / C.STATE)
        raw = C.physics_record(meta, ck / C.STATE)
        physics = None if raw is None else PhysicsSpec.from_meta(raw, str(ck / C.STATE))
        net = build_network(cfg)
        C.load_weights(net, ck, C.EMA)
        return cls(
            net.to(dev).eval(),
            Diffusion(cfg),
            cfg,
            np.asarray(mean),
            np.asarray(std),
            mm_per_px,
            frame_px,
            dev,
            physics,
            trained=_trained(meta),
            autocast=autocast,
        )

    def generate(
        self,
        object_bgr: np.ndarray,
        wrench: np.ndarray,
        pose=(0.0, 0.0, 0.0),
        *,
        steps: int = 50,
        sampler: str = "ddim",
        seed: int = 0,
        guidance: float = 1.0,
        object_name: str | None = None,
    ) -> np.ndarray:
        """One tactile frame (BGR uint8, S×S) for an object image, a wrench (N, N·mm) and a pose:
        (x, y mm, θ deg) or (x, y, z mm, θ deg). A physics-conditioned model needs the pose with z
        (mm from the contact point, negative into the gel) and ``object_name``, a library object."""
        wrench = np.asarray(wrench, dtype=np.float64)
        if wrench.shape != (6,) or not np.all(np.isfinite(wrench)):
            raise ValueError(f"wrench must be six finite numbers Fx,Fy,Fz (N),Mx,My,Mz (N·mm), got {wrench.tolist()}")
        cond = image_to_tensor(self.condition(object_bgr, pose))
        if self.cfg.uses_physics:
            if object_name is None:
                raise ValueError(
                    f"this model is conditioned on the physics render ({self.cfg.conditioning}): give a library "
                    "object or a run file of one as the object, not an image"
                )
            cond = torch.cat([cond, image_to_tensor(self.physics_image(object_name, pose, wrench))])
        cond = scale_images(cond[None])
        w = torch.from_numpy(normalise_wrench(wrench, self.wrench_mean, self.wrench_std).astype(np.float32))[None]
        g = torch.Generator(device=self.device).manual_seed(seed)
        out = self.diffusion.sample(
            self.net,
            cond.to(self.device),
            w.to(self.device),
            steps=steps,
            sampler=sampler,
            guidance=guidance,
            generator=g,
            autocast=self.autocast,
        )[0]
        return tensor_to_image(out)

    def condition(self, object_bgr: np.ndarray, pose=(0.0, 0.0, 0.0)) -> np.ndarray:
        """The condition image (BGR uint8, S×S) for an object image of the sensor's field of view at a
        pose (x, y mm, θ deg, or x, y, z, θ): what training built from the run's object image at the
        frame's pose."""
        x, y, _, theta = _pose4(pose, need_z=False)
        return condition_image(object_bgr, x, y, theta, self.mm_per_px, self.frame_px, self.cfg.image_size)

    def physics_image(self, object_name: str, pose, wrench=None) -> np.ndarray:
        """The physics channels' image (BGR uint8, S×S) for a library object at a pose (x, y, z mm,
        θ deg; or x, y, θ with the depth from the wrench's Fz, ``physics_pose``) under a wrench (N,
        N·mm; a marker sensor's markers follow its Fx, Fy, Mz): what training's cache holds for a
        run frame of that object at that measured pose and wrench."""
        render = self._physics_renderer(object_name)
        return resize(render.render(self.physics_pose(object_name, pose, wrench), wrench), self.cfg.image_size)

    def physics_pose(self, object_name: str, pose, wrench=None) -> tuple[float, float, float, float]:
        """(x, y, z, θ) for the physics render: z as given; for a pose of x, y, θ and a wrench — or
        any pose, for a model rendered at the depth Fz implies (``physics_depth = "force"``) — the
        depth at which the object there presses with the wrench's Fz (the simulator's own
        force-depth relation through the checkpoint's sensor profile)."""
        values = [float(v) for v in pose]
        if (len(values) != 3 and not self.cfg.force_depth) or wrench is None:
            return _pose4(values, need_z=True)
        x, y, _, theta = _pose4(values, need_z=False)
        fz = float(np.asarray(wrench, dtype=float)[2])
        # asked for by a user: a force the gel cannot give (or no force) is an error naming it, never a
        # silent deepest render (the training cache and the force sweep render past it: conditioning/force_render.py)
        at = self._physics_renderer(object_name).pose_at_force(x, y, theta, fz)
        return x, y, float(at[2]), theta

    def _physics_renderer(self, object_name: str):
        if self.physics is None:
            raise ValueError(f"this model ({self.cfg.conditioning}) has no physics conditioning")
        if self._renderers is None:
            self._renderers = {}
        if object_name not in self._renderers:
            self._renderers[object_name] = self.physics.renderer(object_name, where="--object")
        return self._renderers[object_name]

    def generate_items(self, items: list[dict], **kwargs):
        """``generate_items`` with this model's EMA weights (and physics render)."""
        return generate_items(
            self.net, self.diffusion, items, self.device, physics=self.physics, autocast=self.autocast, **kwargs
        )

    def generate_split(
        self,
        split_dir: str | Path,
        part: str,
        out_dir: str | Path,
        *,
        limit: int | None = None,
        steps: int = 50,
        sampler: str = "ddim",
        seed: int = 0,
        guidance: float = 1.0,
        batch_size: int = 64,
        log=lambda line: None,
    ) -> int:
        """Every frame of a split's part (``limit``: that many, spread evenly), as RUN-FRAME.png
        in ``out_dir`` with index.csv (run file, frame, wrench, pose, png). Returns the count."""
        import csv

        from dataset.torch_dataset import TactileDataset, spread

        data = TactileDataset(split_dir, part, size=self.cfg.image_size)
        if len(data) == 0:
            raise ValueError(f"{split_dir}: the {part} part is empty")
        items = [data[int(i)] for i in spread(len(data), limit)]
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        made = self.generate_items(
            items, steps=steps, sampler=sampler, seed=seed, guidance=guidance, batch_size=batch_size
        )
        with open(out / "index.csv", "w", newline="") as fh:
            writer = csv.writer(fh)
            # the wrench and pose columns as export/import's frames.csv names them
            writer.writerow(
                ["run", "frame", *S.columns_of(S.FIELD[S.WRENCH]), *S.columns_of(S.FIELD[S.POSE_MEASURED]), "png"]
            )
            for k, (it, img) in enumerate(zip(items, made), 1):
                name = f"{it['run']:02d}-{it['frame']:06d}.png"
                cv2.imwrite(str(out / name), img)
                raw = it["wrench"].numpy() * data.std + data.mean
                writer.writerow(
                    [
                        data.runs[it["run"]],
                        it["frame"],
                        *(f"{v:.6g}" for v in raw),
                        *(f"{v:.6g}" for v in it["pose"].numpy()),
                        name,
                    ]
                )
                if k % batch_size == 0 or k == len(items):
                    log(f"{k}/{len(items)} frames")
        return len(items)


def _trained(meta: dict) -> str:
    """ "N steps × batch B, lr L" from a checkpoint's state (what it has of it)."""
    raw = meta.get("train")
    train: dict = raw if isinstance(raw, dict) else {}
    words = [f"{meta.get('step')} steps"]
    if isinstance(train.get("batch_size"), int):
        words[0] += f" × batch {train['batch_size']}"
    if isinstance(train.get("lr"), (int, float)):
        words.append(f"lr {train['lr']:g}")
    return ", ".join(words)


def _pose4(pose, *, need_z: bool) -> tuple[float, float, float, float]:
    """(x, y, z, θ) from (x, y, θ) or (x, y, z, θ), checked finite; ValueError naming what is missing."""
    values = [float(v) for v in pose]
    if len(values) not in (3, 4) or not all(np.isfinite(values)):
        raise ValueError(f"pose must be x,y (mm),theta (deg) or x,y,z (mm),theta (deg), finite; got {values}")
    if len(values) == 3:
        if need_z:
            raise ValueError(
                f"pose {values}: a physics-conditioned model needs the depth too: x,y,z,theta "
                "(z in mm from the contact point, negative into the gel), or a wrench whose Fz gives it"
            )
        values.insert(2, 0.0)
    x, y, z, theta = values
    return x, y, z, theta
