"""Where a log's image bytes wait while the rest of the log is read.

Images are the bulk of a drive log. Reading a log once, the ingestor appends each image's
bytes to an unnamed temporary file (deleted by the OS even after a crash) and keeps only
where they lie; clips are written from it once the log's frames are known. Memory stays
bounded whatever the log's length.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class SpillRef:
    offset: int
    length: int


class Spill:
    """An append-only temporary file of byte strings (a context manager)."""

    def __init__(self, directory: str | Path | None = None) -> None:
        self._file = tempfile.TemporaryFile(dir=directory)
        self._end = 0

    def put(self, data: bytes) -> SpillRef:
        self._file.write(data)
        ref = SpillRef(self._end, len(data))
        self._end += len(data)
        return ref

    def get(self, ref: SpillRef) -> bytes:
        self._file.flush()
        return os.pread(self._file.fileno(), ref.length, ref.offset)

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> Spill:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
