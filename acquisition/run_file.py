"""Run files, in one import: the writer, the verified reader and their errors.

Each part has a module of its own:

* acquisition/run_writer.py: ``RunHeader`` and ``RunWriter`` (create, append, status, close);
* acquisition/run_resume.py: ``RunWriter.reopen`` for ``--resume``, every committed chunk verified;
* acquisition/run_reader.py: ``RunReader``, the one read path every command uses (schema, rows
  and checksums verified as it reads), and ``open_for_reading``, the file-level open under it;
* acquisition/run_identity.py: a run's identity as ``dataset split`` records it;
* acquisition/attr_checksum.py: the checksum of the root attributes; acquisition/crash_tail.py:
  what ``--resume`` keeps of a run whose writer crashed;
* acquisition/run_storage.py: creation filters, temp names, ``recover``; ``dataset compact``:
  acquisition/run_compact.py.

docs/run-file.md has the details.
"""

from acquisition.run_reader import RunReader, open_for_reading
from acquisition.run_storage import ROW_BLOCK, STREAM_BLOCK, TEMP_MARKS, chunked, recover, remove_stale_temps, temp_path
from acquisition.run_writer import PER_FRAME, RunHeader, RunWriter
from acquisition.writer_lock import RunFileError, RunLocked

__all__ = [
    "RunFileError",
    "RunHeader",
    "RunLocked",
    "RunReader",
    "RunWriter",
    "open_for_reading",
    "recover",
    "PER_FRAME",
    "ROW_BLOCK",
    "STREAM_BLOCK",
    "TEMP_MARKS",
    "chunked",
    "remove_stale_temps",
    "temp_path",
]
