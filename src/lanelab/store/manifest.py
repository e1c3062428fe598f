"""``manifest.json``: a store's format and version, its sources and its clips.

Written atomically (:func:`lanelab.atomic_file.atomic_output`); read with checks that name
the file and the fault.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from lanelab.atomic_file import atomic_output
from lanelab.data_paths import path_problem
from lanelab.store.schema import FORMAT_NAME, FORMAT_VERSION, manifest_path


# The manifest option that lists the clips without ego motion: their frames' T_world_lane is the
# identity because the source gave no poses (lanelab-openlane before OpenLane v1.2, lanelab-once
# without poses=), so frames of such a clip cannot be related to one another.
WITHOUT_POSE = "clips_without_pose"


def clips_without_pose(manifest: Manifest) -> set[str]:
    """The ids of the manifest's clips without ego motion (:data:`WITHOUT_POSE`)."""
    return set(manifest.options.get(WITHOUT_POSE, []))


class ManifestError(ValueError):
    """A store's manifest is missing, garbled or of a format this lanelab cannot read; names the file."""


@dataclass(frozen=True)
class SourceEntry:
    """A drive log a store was made from."""

    path: str
    sha256: str
    num_frames: int


@dataclass(frozen=True)
class ClipEntry:
    """A clip of a store; ``source`` is the ``path`` of its :class:`SourceEntry`.

    ``sha256``: of the clip file as written; None (stores written before it was recorded,
    or another writer) means the file is not verified by hash.
    """

    clip_id: str
    source: str
    split: str
    num_frames: int
    first_timestamp_ns: int
    last_timestamp_ns: int
    sha256: str | None = None


@dataclass
class Manifest:
    """``manifest.json``: the store's sources and clips.

    ``options``: how the store was made (the writing tool's options); readers may ignore it.
    """

    sources: list[SourceEntry] = field(default_factory=list)
    clips: list[ClipEntry] = field(default_factory=list)
    options: dict[str, Any] = field(default_factory=dict)


def read_manifest(store_dir: str | Path) -> Manifest:
    """Read ``<store_dir>/manifest.json``; :class:`ManifestError` names the file and the fault."""
    path = manifest_path(store_dir)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ManifestError(f"{path}: no clip store manifest there") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ManifestError(f"{path}: cannot read the manifest: {err}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise ManifestError(f"{path}: not a {FORMAT_NAME} manifest (format: {found!r})")
    if data.get("version") != FORMAT_VERSION:
        raise ManifestError(f"{path}: format version {data.get('version')!r} is not supported "
                            f"(this lanelab reads version {FORMAT_VERSION})")
    try:
        manifest = Manifest(
            sources=[_entry(SourceEntry, entry) for entry in data["sources"]],
            clips=[_entry(ClipEntry, entry) for entry in data["clips"]],
            options=dict(data.get("options", {})),
        )
    except (KeyError, TypeError) as err:
        raise ManifestError(f"{path}: malformed manifest: {err}") from None
    for clip in manifest.clips:  # a clip id names a file of the store: data must not lead out of it
        problem = clip_id_problem(clip.clip_id)
        if problem:
            raise ManifestError(f"{path}: clip id {clip.clip_id!r} {problem}: refused")
    return manifest


def clip_id_problem(clip_id: object) -> str:
    """What makes ``clip_id`` unfit to name a clip file in ``clips/``: "" if nothing."""
    if not isinstance(clip_id, str):
        return "is not a string"
    if "/" in clip_id or "\\" in clip_id:
        return "holds a path separator"
    return path_problem(clip_id)


def _entry(kind: type, entry: dict[str, Any]) -> Any:
    """A manifest entry of the given dataclass from its JSON object. Keys it does not know are
    ignored: other writers may record more per source or clip (the contract fixes these names,
    not that there are no others); a missing one is a TypeError."""
    if not isinstance(entry, dict):
        raise TypeError(f"a {kind.__name__} is a JSON object, got {entry!r}")
    known = {f.name for f in fields(kind)}
    return kind(**{key: value for key, value in entry.items() if key in known})


def write_manifest(store_dir: str | Path, manifest: Manifest) -> Path:
    """Write ``<store_dir>/manifest.json`` atomically; return its path."""
    path = manifest_path(store_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "sources": [asdict(entry) for entry in manifest.sources],
        "clips": [{key: value for key, value in asdict(entry).items() if value is not None}
                  for entry in manifest.clips],
        "options": manifest.options,
    }
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return path
