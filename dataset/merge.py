"""Merging runs of one object, sensor and scale into one run file that validates.

* Every source is read through the verified reader (acquisition/run_reader.py: schema, attributes,
  rows and images at open, each frame's checksum as it is copied): a damaged source, or a value
  outside the schema (a phase index past the file's list), is refused naming the file and the
  frame, never carried into the merged file nor rewritten into something else; the half-written
  merged file is removed (all or nothing, below). Each frame is read once, its checksum checked by
  that read: no separate verification pass before.
* Like with like: one object (and the same object geometry, object file and photo, and object
  image), sensor kind, sensor profile, frame size, mm per pixel and capture rate, and reference
  frames alike up to sensor noise (the merged file keeps the first source's: REFERENCE_TOLERANCE);
  anything else is refused naming the runs and their values.
* Every per-frame field of the run-file table is carried (a source written before an optional
  field existed contributes that field's fill value), and the full-rate wrench stream too.
* Time keeps increasing across sources: each source after the first is shifted by one offset for
  ``t_frame_s`` and its stream (its first frame one capture period after the previous source's
  last, and its first stream sample after the previous source's last) and one for
  ``t_capture_s``, as ``--resume`` offsets a resumed clock; ``capture_index`` is the merged file's
  own grid 0, 1, 2, ... The offsets are recorded in the merged file's ``rig_config``.
* Phases are re-encoded by name: the merged file's ``phases`` is the sources' lists joined in
  order of first appearance.
* The header is the first source's where the sources agree; a protocol that differs is carried
  as every source's text, each under a comment naming its file; ``contact_origin`` is the first
  source's (poses are relative to each run's own contact point, so they need no change).
* All or nothing: the merged file appears at ``--out`` only once complete (acquisition/whole_run.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from acquisition.run_storage import frames_codec
from acquisition.run_writer import RunHeader
from acquisition.whole_run import check_new_output, whole_run
from acquisition.writer_lock import RunFileError
from common.wording import signed, status_text

# The merged file keeps the first source's reference frame (the no-contact background of the physics
# row and of `preview --condition`), so every other source's must be the same up to sensor noise:
# blurred by a Gaussian of REFERENCE_BLUR_PX, two frames of one sensor with independent per-pixel
# noise of 1, 3 and 5 grey levels differ by at most 0.9, 3.0 and 5.2 levels (simulated runs of one
# profile: 0, their noise is seeded), a lighting drift of 3 % by 4.6; a press of 20 levels in the
# reference, or the light of another sensor or gel, by far more than REFERENCE_TOLERANCE.
REFERENCE_BLUR_PX = 2.0
REFERENCE_TOLERANCE = 8.0  # grey levels, after the blur

# root attributes (and the object image) every source must share, with what a difference would break
SHARED = (
    (S.ATTR_OBJECT, "the object"),
    (S.ATTR_OBJECT_GEOMETRY, "the object's geometry (the indenter's shape and size)"),
    (S.ATTR_SENSOR_KIND, "the sensor kind"),
    (S.ATTR_SENSOR_PROFILE, "the sensor profile (the physics render of each frame)"),
    (S.ATTR_OBJECT_FILE, "the object file"),
    (S.ATTR_OBJECT_PHOTO_SHA256, "the object's photo"),
    (S.ATTR_MM_PER_PX, "mm per pixel (where the condition is placed)"),
    (S.ATTR_CAPTURE_HZ, "the capture rate (one per merged file)"),
)


def _like_with_like(paths: Sequence[str | Path], sources: list[RunReader]) -> list[float]:
    """RunFileError naming the runs and values unless the sources are alike; else each source's
    reference frame's difference from the first's (grey levels, ``reference_difference``)."""
    shapes = [r.frame_shape for r in sources]
    if len(set(shapes)) > 1:
        detail = ", ".join(f"{p}: {s[1]}x{s[0]}" for p, s in zip(paths, shapes))
        raise RunFileError(f"runs differ in frame size ({detail}); merge like with like")
    for name, what in SHARED:
        values = [
            r.text(name) if name not in (S.ATTR_MM_PER_PX, S.ATTR_CAPTURE_HZ) else r.number(name) for r in sources
        ]
        if len({repr(v) for v in values}) > 1:
            detail = ", ".join(f"{p}: {str(v)[:60]!r}" for p, v in zip(paths, values))
            raise RunFileError(f"runs differ in {name}, {what} ({detail}); merge like with like")
    first = sources[0].image(S.OBJECT_IMAGE)
    for p, r in zip(paths[1:], sources[1:]):
        if not np.array_equal(r.image(S.OBJECT_IMAGE), first):
            raise RunFileError(f"{p}: its {S.OBJECT_IMAGE} differs from {paths[0]}'s; merge like with like")
    gaps = [0.0]
    for p, r in zip(paths[1:], sources[1:]):
        gap = reference_difference(sources[0].image(S.REFERENCE_FRAME), r.image(S.REFERENCE_FRAME))
        gaps.append(gap)
        if gap > REFERENCE_TOLERANCE:
            raise RunFileError(
                f"{p}: its {S.REFERENCE_FRAME} differs from {paths[0]}'s by up to {gap:.1f} grey levels (after a "
                f"{REFERENCE_BLUR_PX:g} px blur; sensor noise stays under {REFERENCE_TOLERANCE:g}): another sensor, "
                "lighting or gel, or a contact in the no-contact frame; the merged file keeps one reference frame, "
                "so merge like with like (split and train take several run files)"
            )
    return gaps


def reference_difference(a: np.ndarray, b: np.ndarray) -> float:
    """The largest difference between two reference frames, in grey levels, after a Gaussian blur of
    REFERENCE_BLUR_PX that averages away per-pixel noise (module docstring)."""
    import cv2

    if a.shape != b.shape:
        return float("inf")
    blur = [cv2.GaussianBlur(np.asarray(x, np.float32), (0, 0), REFERENCE_BLUR_PX) for x in (a, b)]
    return float(np.abs(blur[0] - blur[1]).max()) if a.size else 0.0


def _offsets(sources: list[RunReader], period: float) -> list[tuple[float, float]]:
    """(offset of t_frame_s and the stream, offset of t_capture_s) per source (module docstring)."""
    out = [(0.0, 0.0)]
    last_t = last_c = last_stream = None
    for k, r in enumerate(sources):
        t, c = r.rows[S.T_FRAME], r.rows[S.T_CAPTURE]
        stream = r.stream if r.stream is not None and len(r.stream) else None
        if k:
            needs: list[float] = [] if last_t is None or not len(t) else [float(last_t + period - t[0])]
            if last_stream is not None and stream is not None:
                needs.append(float(last_stream + period - stream[0, 0]))
            off_c = last_c + period - c[0] if last_c is not None and len(c) else 0.0
            out.append((max(needs, default=0.0), off_c))
        off_t, off_c = out[k]
        if len(t):
            last_t, last_c = float(t[-1] + off_t), float(c[-1] + off_c)
        if stream is not None:
            last_stream = float(stream[-1, 0] + off_t)
    return out


def _origin(r: RunReader) -> tuple[float, float, float, float]:
    x, y, z, theta = (float(v) for v in r.attrs[S.ATTR_CONTACT_ORIGIN])
    return x, y, z, theta


def _protocol(paths: Sequence[str | Path], sources: list[RunReader]) -> tuple[str, str]:
    names = list(dict.fromkeys(r.text(S.ATTR_PROTOCOL_NAME) for r in sources))
    texts = [r.text(S.ATTR_PROTOCOL) for r in sources]
    if len(set(texts)) == 1:
        return "+".join(names), texts[0]
    joined = "\n".join(f"# --- merged source {k}: {p} ---\n{t}" for k, (p, t) in enumerate(zip(paths, texts)))
    return "+".join(names), joined


def merge_runs(paths: Sequence[str | Path], out: str | Path) -> int:
    """One run file from several of one object, sensor and scale (module docstring); the frame count."""
    out = Path(out)
    if not paths:
        raise RunFileError("no run files to merge")
    check_new_output(out, "dataset merge")
    sources: list[RunReader] = []
    try:
        for p in paths:
            sources.append(RunReader.open(p))  # rows, attributes and images verified; each frame as it is copied
        gaps = _like_with_like(paths, sources)
        return _write(paths, sources, out, gaps)
    finally:
        for r in sources:
            r.close()


def _write(paths: Sequence[str | Path], sources: list[RunReader], out: Path, gaps: list[float]) -> int:
    first = sources[0]
    phases: list[str] = []
    for r in sources:
        phases += [p for p in r.phases if p not in phases]
    hz = first.number(S.ATTR_CAPTURE_HZ)
    offsets = _offsets(sources, 1.0 / hz)
    total = sum(r.n for r in sources)
    protocol_name, protocol_toml = _protocol(paths, sources)
    origins = [_origin(r) for r in sources]
    lines = [
        f"{Path(p).resolve()}: {r.n} frames, status {r.status}, t_frame_s and stream {off_t:+.6f} s, "
        f"t_capture_s {off_c:+.6f} s, contact_origin {_origin_text(origin)}, "
        f"reference frame within {gap:.1f} grey levels"
        for p, r, (off_t, off_c), origin, gap in zip(paths, sources, offsets, origins, gaps)
    ]
    header = RunHeader(
        protocol_name=protocol_name,
        protocol_toml=protocol_toml,
        rig_config="merged from (file: frames, status, time offsets added, contact point, reference frame's "
        "difference from the first's, blurred):\n" + "\n".join(lines),
        object_name=first.text(S.ATTR_OBJECT),
        object_geometry=first.text(S.ATTR_OBJECT_GEOMETRY),
        sensor_kind=first.text(S.ATTR_SENSOR_KIND),
        mm_per_px=first.number(S.ATTR_MM_PER_PX),
        capture_hz=hz,
        frames_planned=total,
        contact_origin=origins[0],
        phases=tuple(phases),
        sensor_profile=first.text(S.ATTR_SENSOR_PROFILE),
        object_file_toml=first.text(S.ATTR_OBJECT_FILE),
        object_photo_sha256=first.text(S.ATTR_OBJECT_PHOTO_SHA256),
    )
    codec = frames_codec(first.f)  # the first run's codec (simulated runs: the fast one); None: the default
    with whole_run(
        out,
        header,
        first.frame_shape,
        first.image(S.OBJECT_IMAGE),
        first.image(S.REFERENCE_FRAME),
        what="dataset merge",
        codec=codec,
    ) as writer:
        k = 0
        for r, (off_t, off_c) in zip(sources, offsets):
            rows = dict(r.rows)
            recode = np.array([phases.index(p) for p in r.phases], dtype=np.int8)  # this source's → the merged list's
            rows[S.PHASE_INDEX] = recode[rows[S.PHASE_INDEX]] if r.n else rows[S.PHASE_INDEX]
            rows[S.T_FRAME] = rows[S.T_FRAME] + off_t
            rows[S.T_CAPTURE] = rows[S.T_CAPTURE] + off_c
            stream = None
            if r.stream is not None and len(r.stream) and writer.records_stream:
                stream = r.stream.copy()
                stream[:, 0] += off_t
            for i in range(r.n):
                row = {name: values[i] for name, values in rows.items()}
                row[S.CAPTURE_INDEX] = k  # the merged file's own capture grid
                writer.append(r.frame(i), stream=stream if i == 0 else None, **row)
                k += 1
        statuses = [r.status for r in sources]
        bad = [f"{p}: {status_text(s, r.reason or 'no reason')}" for p, s, r in zip(paths, statuses, sources)]
        bad = [line for line, s in zip(bad, statuses) if s != "complete"]
        warnings = [int(r.f[S.SIM_SOLVER_WARNINGS][()]) for r in sources if S.SIM_SOLVER_WARNINGS in r.f]
        if warnings and all(w >= 0 for w in warnings):
            writer.set_sim_solver_warnings(sum(warnings))
        writer.set_status("complete" if not bad else "aborted", "; ".join(bad))
    return total


def _origin_text(origin) -> str:
    """A run's contact origin as x,y,z,theta to 4 decimals (never e-notation nor -0.0000); "none" without one."""
    if origin is None:
        return "none"
    try:
        return "(" + ", ".join(signed(float(v), 4, sign="") for v in origin) + ")"
    except (TypeError, ValueError):
        return str(origin)
