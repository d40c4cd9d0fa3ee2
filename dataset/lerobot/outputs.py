"""Where an import's run files go: one run to ``--out``, several to a new folder that appears only once
every file in it is complete."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

from acquisition.whole_run import check_new_output, whole_folder
from acquisition.writer_lock import RunFileError


@contextlib.contextmanager
def outputs(out: Path, names: list[str]) -> Iterator[list[Path]]:
    """One run: ``out`` is the file. Several: ``out`` is a new folder of one file per run, appearing only
    once every file is complete (acquisition/whole_run.py): a refusal at the last run leaves nothing."""
    if len(names) == 1:
        check_new_output(out, "dataset import")
        yield [out]
        return
    if out.exists() or out.suffix == ".h5":
        raise RunFileError(f"--out {out}: the folder holds {len(names)} runs; --out must be a new folder for them")
    if not out.parent.is_dir():
        raise RunFileError(f"--out {out}: the folder {out.parent} does not exist; create it first")
    with whole_folder(out, "import") as tmp:
        tmp.mkdir()
        yield [tmp / name for name in names]
