"""The run browser (``dataset view``, ``rig console``) reads through the verified reader.

Before: it read with raw slicing, so a damaged frame was an HTTP 500 (a traceback in the server's
log) and any other ``*.h5`` in a listed folder was served unchecked. Now a file the reader refuses
is a JSON error naming it (422), a name or frame that is not there a 404, and a run still being
written keeps growing on the page. No browser needed: plain HTTP requests.
"""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from urllib.parse import quote

import numpy as np
import pytest
from test_verified_reads import chunk_middle, flip, write_run

from acquisition import schema as S
from acquisition.run_file import RunWriter
from cli.console.launch import console_options
from cli.console.server import serving_in_thread


def _get(base: str, path: str) -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(base + path, timeout=30) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def _error(base: str, path: str, status: int) -> str:
    code, body = _get(base, path)
    assert code == status, (path, code, body)
    return json.loads(body)["error"]


@pytest.mark.realtime  # a live run read as it grows, on real time
def test_damaged_and_foreign_files_are_json_errors_and_a_live_run_grows(tmp_path):
    write_run(tmp_path / "good.h5")
    damaged = write_run(tmp_path / "damaged.h5")
    flip(damaged, chunk_middle(damaged, S.FRAMES, 4))
    relabelled = write_run(tmp_path / "relabelled.h5")
    relabelled.write_bytes(relabelled.read_bytes().replace(b"sphere10mm", b"sphere15mm"))
    (tmp_path / "notes.h5").write_bytes(b"not a run file")
    live = write_run(tmp_path / "live.h5", n=20, written=3, close=False)
    writer = RunWriter.reopen(live)  # a run being written while the page follows it
    options = console_options(config=None, sim=False, live=False, runs=[tmp_path])
    try:
        with serving_in_thread(options) as url:
            base = url.split("?")[0]
            code, body = _get(base, "api/run?name=good.h5")
            assert code == 200 and json.loads(body)["frames"] == 12
            assert _get(base, "api/run/image?kind=frame&i=11&name=good.h5")[0] == 200
            # a damaged frame: the reader's one line, 422, for every frame of that file (issue 36: every
            # reader verifies every frame when it opens a run, as validate does)
            for i in (4, 3):
                error = _error(base, f"api/run/image?kind=frame&i={i}&name=damaged.h5", 422)
                assert error.startswith(f"{damaged}: frames[4]: checksum mismatch"), error
            assert "attrs_sha256" in _error(base, "api/run?name=relabelled.h5", 422)
            assert "notes.h5" in _error(base, "api/run?name=notes.h5", 422)
            assert "no run file named" in _error(base, f"api/run?name={quote('nosuch.h5')}", 404)
            assert "has frames 0..11, not 99" in _error(base, "api/run/image?kind=frame&i=99&name=good.h5", 404)
            code, body = _get(base, "api/run?name=live.h5")
            assert code == 200 and json.loads(body)["status"] == "running" and json.loads(body)["frames"] == 3
            for i in range(3, 5):
                writer.append(
                    np.full((32, 32, 3), 100 + i, np.uint8),
                    **S.blank_row() | {S.CAPTURE_INDEX: i, S.T_FRAME: 1.0 + i, S.T_CAPTURE: float(i)},
                )
            code, body = _get(base, "api/run?name=live.h5")
            assert code == 200 and json.loads(body)["frames"] == 5
            code, picture = _get(base, "api/run/image?kind=frame&i=4&name=live.h5")
            assert code == 200 and picture.startswith(b"\x89PNG")
    finally:
        writer.close()
