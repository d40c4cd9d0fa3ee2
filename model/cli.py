"""``train``: the contact-condition-guided diffusion model (issue 6; not yet built)."""

from __future__ import annotations

import sys


def main() -> None:
    print("train: not yet built — the trainer, checkpoints and reports arrive with the model issue "
          "(the denoiser, loss, samplers and metrics are in model/). Available now: `rig`, `dataset`.",
          file=sys.stderr)
    raise SystemExit(2)
