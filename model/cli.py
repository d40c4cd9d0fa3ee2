"""``train``: the contact-condition-guided diffusion model (issue 6; not yet built)."""

from __future__ import annotations

import sys


def main() -> None:
    print("train: not yet built — training, generation and evaluation arrive with the model issue. "
          "Available now: `rig` (see README.md).", file=sys.stderr)
    raise SystemExit(2)
