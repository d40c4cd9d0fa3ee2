"""The live link's messages from a browser: ``parse`` takes a JSON object or nothing (the server
answers anything else with ``MALFORMED``), ``handle`` acts on one: a frame drawn, the marker-flow
view, control taken or released, stop, and the commands (jog, home, zero, a library protocol) only
the page in control may give, each checked before it reaches the rig worker or refused in words.
"""

from __future__ import annotations

import json

from cli.console.flow import MarkerFlow
from cli.console.hub import Client, Hub
from cli.console.worker import Command, RigWorker
from common.errors import ToolError

MAX_STEP = 25.0  # mm or deg per jog from the page: the step selector's largest is 1

MALFORMED = 'malformed message: expected a JSON object such as {"type": "stop"}'


def parse(text: str | None) -> dict | None:
    """A browser's message: a JSON object, else None (binary, not JSON, an array, a number…)."""
    if text is None:
        return None
    try:
        message = json.loads(text)
    except (ValueError, RecursionError):  # not JSON, or nested deeper than the parser goes
        return None
    return message if isinstance(message, dict) else None


def handle(hub: Hub, worker: RigWorker | None, client: Client, message: dict, flow: MarkerFlow | None = None) -> None:
    """One message from a browser."""
    kind = message.get("type")
    if kind == "drawn":
        hub.frame_drawn(client, _number(message.get("t_s")))
        return
    if kind in ("flow", "set_reference"):  # views, not commands: any page may
        if flow is None:
            hub.tell(client, {"type": "refused", "text": "marker flow: this console's sensor has no markers"})
        elif kind == "flow":
            client.wants_flow = message.get("on") is True
            flow.wanted = hub.flow_wanted()
        else:
            flow.set_reference()
        return
    if kind == "take_control":
        refused = hub.take_control(client)
        if refused:
            hub.tell(client, {"type": "refused", "text": refused})
        return
    if kind == "release_control":
        hub.release_control(client)
        return
    if worker is None:
        hub.tell(client, {"type": "refused", "text": "no rig: this console only browses run files"})
        return
    if kind == "stop":  # from anyone: whoever watches may halt the rig (and end a protocol)
        worker.request_stop(client.peer)
        return
    if kind not in ("jog", "home", "zero", "run_protocol"):
        hub.tell(client, {"type": "refused", "text": f"unknown command {kind!r}"})
        return
    axis = message.get("axis") or None
    if axis is not None and not isinstance(axis, str):
        hub.tell(client, {"type": "refused", "text": f"{kind} refused: axis {axis!r} is not an axis name"})
        return
    if worker.rig_status["state"] not in ("open", "opening"):  # held elsewhere, failed or closed
        hub.tell(client, {"type": "refused", "text": f"{kind} refused: no rig ({worker.error or 'closed'})"})
        return
    if hub.controller is not client:
        holder = hub.controller.peer if hub.controller else "nobody"
        hub.tell(client, {"type": "refused", "text": f"{kind} refused: take control first (held by {holder})"})
        return
    if worker.protocol_running:
        hub.tell(client, {"type": "refused", "text": f"{kind} refused: a protocol is running (STOP ends it)"})
        return
    if kind == "run_protocol":
        from cli.console.protocol_run import check_origin, check_settings, library_protocol

        try:
            origin = check_origin(message.get("origin"))
            settings = check_settings(message.get("settings"))
            library_protocol(message.get("name"), worker.sensor, worker.simulated, settings)  # checked as the CLI does
        except ToolError as exc:
            hub.tell(client, {"type": "refused", "text": f"run protocol refused: {exc}"})
            return
        name = message["name"]
        worker.submit(Command("protocol", name=name, origin=origin, settings=tuple(settings), who=client.peer))
        return
    step = _number(message.get("step"))
    if kind == "jog":
        if not abs(step) <= MAX_STEP:
            hub.tell(
                client, {"type": "refused", "text": f"jog refused: step {message.get('step')!r} is not in ±{MAX_STEP}"}
            )
            return
    worker.submit(Command(kind, axis=axis, step=step if kind == "jog" else None, who=client.peer))


def _number(value) -> float:
    """A number from a browser's message; NaN when it is not one (refused further on)."""
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an integer of 400 digits
        return float("nan")
