"""Merging runs of one object, sensor and frame size into one run file.

Every per-frame field of the run-file table (acquisition/schema.py) is carried; a
source written before an optional field existed contributes that field's fill value.
Phases are re-encoded by name: the merged file's ``phases`` is the sources' lists
joined in order of first appearance, so sources whose lists differ in order still
decode to the same names. The full-rate wrench stream is per run and per clock: the
merged file has none (each source keeps its own).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from acquisition import schema as S
from acquisition.run_file import RunFileError, RunHeader, RunWriter
from acquisition.run_layout import decode_phases
from acquisition.run_storage import frames_codec
from dataset.runs import open_run, read


def merge_runs(paths: Sequence[str | Path], out: str | Path) -> int:
    """One run file from several of one object, sensor and frame size; keeps each frame's source."""
    sources = [open_run(p) for p in paths]
    try:
        first = sources[0]
        keys = [
            (str(f.attrs.get(S.ATTR_OBJECT)), str(f.attrs.get(S.ATTR_SENSOR_KIND)), f[S.FRAMES].shape[1:])
            for f in sources
        ]
        if len(set(keys)) > 1:
            detail = ", ".join(f"{p}: {k[0]}/{k[1]}/{k[2][1]}x{k[2][0]}" for p, k in zip(paths, keys))
            raise RunFileError(f"runs differ in object, sensor or frame size ({detail}); merge like with like")
        phases: list[str] = []
        for f in sources:
            phases += [p for p in decode_phases(f) if p not in phases]
        a = first.attrs
        total = sum(f[S.FRAMES].shape[0] for f in sources)
        header = RunHeader(
            protocol_name=str(a.get(S.ATTR_PROTOCOL_NAME, "")),
            protocol_toml=str(a.get(S.ATTR_PROTOCOL, "")),
            rig_config="merged from: " + ", ".join(str(Path(p).resolve()) for p in paths),
            object_name=keys[0][0],
            object_geometry=str(a.get(S.ATTR_OBJECT_GEOMETRY, "")),
            sensor_kind=keys[0][1],
            mm_per_px=float(a.get(S.ATTR_MM_PER_PX, float("nan"))),
            capture_hz=float(a.get(S.ATTR_CAPTURE_HZ, 1.0)),
            frames_planned=total,
            contact_origin=tuple(a.get(S.ATTR_CONTACT_ORIGIN, (0, 0, 0, 0))),
            phases=tuple(phases),
        )
        writer = RunWriter.create(
            out,
            header,
            keys[0][2],
            first[S.OBJECT_IMAGE][()],
            first[S.REFERENCE_FRAME][()],
            codec=frames_codec(first),  # the first run's codec (simulated runs: the fast one); None: the default
        )
        k = 0
        try:
            statuses = []
            for f in sources:
                statuses.append(f[S.STATUS][()].decode())
                n = f[S.FRAMES].shape[0]
                rows = {
                    fl.path: read(f, fl.path, slice(0, n)) if fl.path in f else np.full((n, *fl.shape), fl.fill)
                    for fl in S.PER_FRAME_FIELDS
                }
                # this source's phase indices → the merged list's
                recode = np.array([phases.index(p) for p in decode_phases(f)] or [0], dtype=np.int8)
                rows[S.PHASE_INDEX] = recode[np.clip(rows[S.PHASE_INDEX], 0, len(recode) - 1)]
                for i in range(n):
                    row = {name: values[i] for name, values in rows.items()}
                    row[S.CAPTURE_INDEX] = k  # the merged file's own capture grid
                    writer.append(read(f, S.FRAMES, i), **row)
                    k += 1
            bad = [f"{p}: {s}" for p, s in zip(paths, statuses) if s != "complete"]
            writer.set_status("complete" if not bad else "aborted", "; ".join(bad))
        finally:
            writer.close()
        return total
    finally:
        for f in sources:
            f.close()
