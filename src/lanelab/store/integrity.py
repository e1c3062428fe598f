"""Checking a store's clip files against its manifest: the sha256 each clip entry records.

A clip entry written by this lanelab records its file's sha256; one from an older store
records none and is not verified by hash (its Parquet page checksums, if any, still are on
every read).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from lanelab.store import clip_file
from lanelab.store.manifest import ClipEntry, read_manifest
from lanelab.store.schema import clip_path


def file_sha256(path: str | Path) -> str:
    """The sha256 of a file's bytes, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(1 << 22):
            digest.update(block)
    return digest.hexdigest()


def clip_fault(store_dir: str | Path, clip: ClipEntry) -> str | None:
    """What is wrong with a clip's file (missing, or not the bytes the manifest recorded); None when
    it matches, or when the manifest records no sha256 for it."""
    path = clip_path(store_dir, clip.clip_id)
    if not path.is_file():
        return "missing"
    if clip.sha256 is not None and file_sha256(path) != clip.sha256:
        return "damaged: its sha256 is not the one the manifest records"
    return None


def damaged_clips(store_dir: str | Path) -> list[str]:
    """One line per clip of the store whose file is missing or damaged, naming the file.

    A clip with a recorded sha256 is checked by it; one without is read whole, checking its
    Parquet page checksums.
    """
    lines = []
    for clip in read_manifest(store_dir).clips:
        path = clip_path(store_dir, clip.clip_id)
        fault = clip_fault(store_dir, clip)
        if fault is not None:
            lines.append(f"{path}: clip {clip.clip_id!r} {fault}")
        elif clip.sha256 is None:
            try:
                clip_file.check_readable(path)
            except clip_file.ClipFileError as err:
                lines.append(str(err))
    return lines
