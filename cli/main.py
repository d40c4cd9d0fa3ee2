"""The whole command line as one app: ``python -m cli rig …``, ``… dataset …``, ``… model …``.

One Typer app per area, joined here with ``add_typer``; the console scripts ``rig``,
``dataset``, ``train``, ``generate`` and ``evaluate`` run the same apps directly. This is
the application layer: it imports every layer below and nothing imports it.
"""

from __future__ import annotations

import typer

from cli import model_app
from cli.dataset_app import app as dataset
from cli.rig_app import app as rig

model = typer.Typer(
    help="The contact-condition-guided diffusion model: train, generate, evaluate, compare.",
    no_args_is_help=True,
    add_completion=False,
)
model.command("train")(model_app.train)
model.command("generate")(model_app.generate)
model.command("evaluate")(model_app.evaluate)
model.command("compare")(model_app.compare)

app = typer.Typer(
    help="Tactile-sensing lab tool: the rig, datasets and the model.", no_args_is_help=True, add_completion=False
)
app.add_typer(rig, name="rig")
app.add_typer(dataset, name="dataset")
app.add_typer(model, name="model")
