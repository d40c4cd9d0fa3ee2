"""``rig check-axes``: open the rig, find the gel if needed, run the check (rig/axis_check.py,
reading the images with rig/contact_image.py), print the verdict (rig/axis_verdict.py) and, with
--fix, write the config (rig/axis_fix.py). Light at import: everything inside the function.
"""

from __future__ import annotations

CENTRED_MM = 0.1  # a centring move smaller than this is not worth a jog: the centre is found within ~1.5 px (0.08 mm)


def run_check(*, config, sim: bool, profile, fix: bool, settings, say, note, out=print, warn=print) -> bool:
    """The command: True when the axes agree with the camera (after --fix wrote the fix, the next
    run says so). ``say``/``note``: progress and the envelope's notes (stderr); ``out``: results."""
    from cli.session import open_rig, resolve_config_path
    from common.errors import ConfigError
    from rig.axis_check import check_axes, check_depth
    from rig.axis_verdict import judge
    from rig.contact_search import find_contact

    if fix and sim:
        raise ConfigError(
            "<built-in simulated rig>",
            "--fix",
            "the built-in simulated rig's config is not a file: with "
            "`rig sim serve --out rig-sim.toml`, check (and fix) `--config rig-sim.toml`",
        )
    path = None if sim else resolve_config_path(config)
    with open_rig(path, sim, profile=profile, camera=True, discrete=True) as rig:
        check_depth(rig.config, settings)  # a press the depth guard would refuse: refused before any move
        if rig.depth_guard() is None:
            say("no gel surface remembered for this rig: finding it first, as rig find-contact does")
            find_contact(rig, on_start=say)
        seen = check_axes(rig, None, settings, on_start=say, on_note=note)
        cam = rig.config.camera
        verdict = judge(seen, cam.mm_per_px if cam is not None else None)
        _print_verdict(verdict, seen, out, warn)
        if verdict.fix.needed:
            if fix:
                _write_fix(rig, path, verdict, out)
            else:
                out(f"fix: rig check-axes --fix writes this into {rig.config.path} (a copy of the old file is kept):")
                for line in verdict.fix.changes():
                    out(f"  {line}")
    return verdict.ok


def _print_verdict(v, seen, out, warn) -> None:
    from cli.options import fixed

    for line in v.notes:
        out(f"ok: {line}")
    for line in v.findings:
        warn(f"problem: {line}")
    width, height = seen.frame_px
    right, up = v.centre_offset_px
    where = (
        f"{abs(right):.1f} px {'right of' if right >= 0 else 'left of'} and {abs(up):.1f} px "
        f"{'above' if up >= 0 else 'below'} the centre"
    )
    out(
        f"contact pressed at column {seen.centre_px[0]:.1f}, row {seen.centre_px[1]:.1f} of the {width}x{height} "
        f"frame: {where}"
    )
    if v.centring_mm and v.ok:
        start = ", ".join(f"{name} = {fixed(seen.start[name], 3, sign=False)} mm" for name in ("x", "y"))
        steps = [(name, step) for name, step in v.centring_mm.items() if abs(step) >= CENTRED_MM]
        if not steps:
            out(f"centred over the gel within {CENTRED_MM} mm at {start}: rig find-contact --set-origin stores it")
        else:
            jogs = "; ".join(f"rig jog --axis {name} --step {fixed(step, 3)}" for name, step in steps)
            out(f"to centre it over the gel (from {start}): {jogs}; then rig find-contact --set-origin")
    out("axes agree with the camera" if v.ok else f"axes do NOT agree with the camera ({len(v.findings)} problem(s))")


def _write_fix(rig, path, v, out) -> None:
    from rig.axis_fix import fixed_config_text, write_config

    text = path.read_text()
    new_text = fixed_config_text(text, str(path), v.fix)
    backup = write_config(path, new_text)
    out(f"fixed: wrote {path} (the old file kept as {backup}):")
    for line in v.fix.changes():
        out(f"  {line}")
    forgotten = rig.state.forget_origin()
    if forgotten is not None:
        out(f"the remembered origin {forgotten.text()} was in the old axes: forgotten (rig find-contact --set-origin)")
    out("run rig check-axes again to confirm")
