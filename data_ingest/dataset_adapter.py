"""The folder loop shared by the adapters of public datasets (``lanelab-openlane``, ``lanelab-once``):
every folder of the split folders named in ``splits`` becomes one clip of that split, its id the
folder's name, in a store updated as every writing tool updates one
(:class:`~lanelab.store.StoreWriter`).

- :func:`check_splits`: the ``splits`` option (split folder -> store split), checked;
- :func:`adapt_folders`: open the store and adapt each folder, a bad one failing alone;
- :func:`kept_with_pose` / :func:`commit_clip`: a folder's clip kept as the store holds it, or
  written and committed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Protocol, Sequence, TypeVar

from lanelab.config_checks import ConfigError
from lanelab.store import (
    MADE_BY_OPTION,
    SPLITS,
    WITHOUT_POSE,
    ClipEntry,
    FrameRecord,
    SourceEntry,
    StoreBusy,
    StoreRefused,
    StoreWriter,
    file_sha256,
    write_clip,
)

WRITTEN, KEPT, FAILED = "written", "kept", "failed"  # what became of a source folder


class FolderResult(Protocol):
    """What became of one folder, as the adapters' summaries print it."""

    @property
    def name(self) -> str: ...

    status: str
    num_frames: int
    has_pose: bool
    error: str


Result = TypeVar("Result", bound=FolderResult)


def check_splits(splits: Mapping[str, str], dataset: str, example: str) -> None:
    """ConfigError when ``splits`` names no split folder or maps one to a split the store has not."""
    if not splits:
        raise ConfigError(f"splits is empty: name at least one {dataset} split folder, e.g. {example}")
    for folder, split in splits.items():
        if split not in SPLITS:
            raise ConfigError(f"splits.{folder}={split!r} is not one of {', '.join(SPLITS)}")


def adapt_folders(
    made_by: str,
    options: Mapping[str, Any],
    output: str,
    root: str,
    splits: Mapping[str, str],
    adapt_folder: Callable[[StoreWriter, Path, str], Result],
    failed: Callable[[str, str], Result],
) -> list[Result]:
    """Make or update the store ``output`` (made by ``made_by`` with ``options``): one result per
    folder of ``<root>/<split folder>``, in order, by ``adapt_folder(writer, folder, split)``, or
    ``failed(name, error)`` where it raised a ValueError.

    Raises ConfigError when the output is a store made by another tool or with other options, or
    being written by another process.
    """
    try:
        writer = StoreWriter(output, {MADE_BY_OPTION: made_by, **options}, _clip_of, marks=[WITHOUT_POSE])
    except (StoreRefused, StoreBusy) as err:
        raise ConfigError(str(err)) from None
    results = []
    with writer:
        for folder, split in splits.items():
            split_dir = Path(root) / folder
            if not split_dir.is_dir():
                print(f"{made_by}: no split folder {split_dir}, skipped")
                continue
            for source_dir in sorted(path for path in split_dir.iterdir() if path.is_dir()):
                try:
                    result = adapt_folder(writer, source_dir, split)
                except ValueError as err:  # LaneFileError names the file; the store's own checks name the clip
                    result = failed(source_dir.name, str(err))
                results.append(result)
    return results


def kept_with_pose(writer: StoreWriter, source: str, split: str, sha256: str) -> bool | None:
    """None when the store must (re)write ``source``'s clip: it holds none, or one of another split
    or sha256; else whether the kept clip has ego poses."""
    if writer.kept_sha256(source, split) != sha256:
        return None
    return _clip_of(source) not in writer.manifest.options[WITHOUT_POSE]


def commit_clip(
    writer: StoreWriter,
    output: str,
    source: str,
    split: str,
    sha256: str,
    timestamps_ns: Sequence[int],
    records: Iterable[FrameRecord],
    has_pose: bool,
) -> None:
    """Write ``source``'s clip (``records``, one a timestamp) and commit it to the manifest, marked
    :data:`~lanelab.store.WITHOUT_POSE` unless ``has_pose``."""
    clip_id = _clip_of(source)
    path = write_clip(output, clip_id, records)
    clip = ClipEntry(clip_id, source, split, len(timestamps_ns), timestamps_ns[0], timestamps_ns[-1], file_sha256(path))
    writer.commit(SourceEntry(source, sha256, len(timestamps_ns)), [clip], marks=[] if has_pose else [WITHOUT_POSE])


def _clip_of(source: str) -> str:
    """The clip a source (its folder) holds: the folder's name is its clip's id."""
    return Path(source).name
