"""``dataset``: turns collected runs into training data (issue 5; not yet built)."""

from __future__ import annotations

import sys


def main() -> None:
    print("dataset: not yet built — info, validate, split 8:2, merge, export, import and preview "
          "arrive with the dataset issue. Available now: `rig` (see README.md).", file=sys.stderr)
    raise SystemExit(2)
