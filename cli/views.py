"""Terminal rendering of rig state."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS


def print_status(rig, console: Console | None = None) -> None:
    console = console or Console()
    st = rig.status()
    table = Table(title=f"{rig.config.name}")
    for col in ("axis", "position", "unit", "state", "homed", "travel", "warnings"):
        table.add_column(col)
    for name, s in st.axes.items():
        cfg = rig.config.axes[name]
        table.add_row(name, f"{s.position:+.4f}", cfg.unit, s.state.value, "yes" if s.homed else "NO",
                      f"[{cfg.travel[0]:g}, {cfg.travel[1]:g}]", " ".join(s.warnings) or "-")
    console.print(table)
    if st.wrench is not None:
        values = st.wrench.as_array()
        console.print("wrench (untared raw minus session tare): " + "  ".join(
            f"{c} {v:+.3f} {u}" for c, v, u in zip(WRENCH_COMPONENTS, values, WRENCH_UNITS)))
