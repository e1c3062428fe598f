"""Updating a clip store: the one policy that every tool writing a store follows.

A :class:`StoreWriter` holds a store for one run of a writing tool (``lanelab-ingest``,
``lanelab-openlane``):

- **one writer at a time**: it holds the store's lock (:mod:`~lanelab.store.lock`) until
  :meth:`StoreWriter.close` (or the end of its ``with`` block, or of its process); a second
  writer raises :class:`~lanelab.store.lock.StoreBusy` naming the process that holds it.
  Holding it, the writer deletes the half-written clip files (``.*.partial``) that a killed
  run left behind: no other writer can be writing them.

- **open or refuse**: a new store takes the tool's ``options``. An existing store's manifest
  is read; a garbled one raises :class:`~lanelab.store.manifest.ManifestError` and nothing is
  overwritten, unless ``overwrite``: then its bytes are kept as ``manifest.json.unreadable``
  (:attr:`StoreWriter.set_aside`) and the store starts afresh, every source re-written. A store that another tool made (``options["made_by"]``) is always refused;
  one made with other options is refused unless ``overwrite``: then it takes these options
  and no source counts as unchanged.
- **skip unchanged**: a source is known by its name (``source_name(path)``);
  :meth:`StoreWriter.kept_sha256` gives the sha256 of the version the store holds, when all
  of its clip files are there and match the sha256 the manifest records for them
  (:func:`~lanelab.store.integrity.clip_fault`), so that the tool keeps a source whose
  sha256 is the same and re-writes one whose clips were damaged.
- **replace and commit**: the tool writes a source's clip files
  (:func:`~lanelab.store.clip_file.write_clip`, each atomically, in any process), then
  :meth:`StoreWriter.commit` puts the source and its clips in the manifest in place of the
  earlier version of the same name, writes the manifest atomically and only then deletes the
  clip files that the manifest no longer lists. :meth:`StoreWriter.discard` deletes the files
  of a source that failed half-way. The store on disk is consistent at every moment.

The manifest lists sources by path and clips by id, whatever order they were written in.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import TracebackType
from typing import Any, Callable, Iterable, Mapping, Sequence

from lanelab.atomic_file import PARTIAL_GLOB
from lanelab.store.integrity import clip_fault
from lanelab.store.lock import lock_store
from lanelab.store.manifest import ClipEntry, Manifest, ManifestError, SourceEntry, read_manifest, write_manifest
from lanelab.store.schema import CLIPS_DIR, clip_path, manifest_path

MADE_BY_OPTION = "made_by"  # names the tool that made a store (lanelab-ingest records none)
UNREADABLE_SUFFIX = ".unreadable"  # a garbled manifest, set aside by overwrite


class StoreRefused(ValueError):
    """An existing store that this writer must not update: another tool made it, or other options."""


class StoreWriter:
    """A clip store opened for updating with ``options``, the options that shape its contents.

    source_name: a source path -> the name it is known by; a source committed under a name
        replaces the earlier source of that name.
    overwrite: take a store made with other options, re-writing every source.
    marks: names of options that list clip ids (e.g. ``clips_without_pose``): not compared
        when opening, kept up to date by :meth:`commit`.
    """

    def __init__(
        self,
        root: str | Path,
        options: Mapping[str, Any],
        source_name: Callable[[str], str],
        *,
        overwrite: bool = False,
        marks: Sequence[str] = (),
    ) -> None:
        self.root = Path(root)
        self._source_name = source_name
        self._overwrite = overwrite
        self._marks = tuple(marks)
        self._lock = lock_store(self.root)
        self.set_aside: Path | None = None  # where a garbled manifest went (overwrite)
        for leftover in (self.root / CLIPS_DIR).glob(PARTIAL_GLOB):
            leftover.unlink(missing_ok=True)
        try:
            self.manifest = self._open(dict(options))
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the store's lock; the writer commits nothing more."""
        self._lock.close()

    def __enter__(self) -> StoreWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()

    def _open(self, options: dict[str, Any]) -> Manifest:
        fresh = Manifest(options={**options, **{mark: [] for mark in self._marks}})
        path = manifest_path(self.root)
        if not path.exists():
            return fresh
        try:
            manifest = read_manifest(self.root)
        except ManifestError:
            if not self._overwrite:
                raise
            # Kept for whoever wants to look into it; the next commit writes a new manifest.
            self.set_aside = path.with_name(path.name + UNREADABLE_SUFFIX)
            path.replace(self.set_aside)
            return fresh
        marked = {mark: manifest.options.get(mark, []) for mark in self._marks}
        made_with = {key: value for key, value in manifest.options.items() if key not in self._marks}
        made_by, by = made_with.get(MADE_BY_OPTION), options.get(MADE_BY_OPTION)
        if made_by != by:
            raise StoreRefused(f"{manifest_path(self.root)} holds a store that this tool did not make "
                               f"({MADE_BY_OPTION}: {made_by!r} -> {by!r}); choose another output")
        if made_with != options:
            if not self._overwrite:
                changed = ", ".join(_differences(made_with, options)) or "unrecorded options"
                raise StoreRefused(f"{manifest_path(self.root)} was made with other options ({changed}); write "
                                   "to a new output, or overwrite the store (overwrite=true) to re-write its "
                                   "sources with these")
            manifest.options = options
        manifest.options = {**manifest.options, **marked}
        return manifest

    def kept_sha256(self, path: str, split: str | None = None) -> str | None:
        """The sha256 of the store's version of the source at ``path`` (known by its name), if
        its clips may stay: every clip file of it is there as written (its sha256, when
        recorded), all in ``split`` when one is given, and the store is not being
        overwritten. None when the source must be written."""
        return self.examine(path, split)[0]

    def examine(self, path: str, split: str | None = None) -> tuple[str | None, list[str]]:
        """:meth:`kept_sha256`, and what is wrong with the clip files of the store's version of
        the source: one "<clip id> <fault>" per missing or damaged file (the files read once; none
        looked at when overwriting)."""
        source = self._stored(path)
        if source is None or self._overwrite:  # overwritten whatever its clips hold
            return None, []
        clips = [clip for clip in self.manifest.clips if clip.source == source.path]
        faults = [f"{clip.clip_id} {fault}" for clip in clips if (fault := clip_fault(self.root, clip)) is not None]
        whole = all(split in (None, clip.split) for clip in clips) and not faults
        return (source.sha256 if whole else None), faults

    def _stored(self, path: str) -> SourceEntry | None:
        """The store's source of the same name as ``path``, if any."""
        name = self._source_name(path)
        return next((s for s in self.manifest.sources if self._source_name(s.path) == name), None)

    def commit(self, source: SourceEntry, clips: Sequence[ClipEntry], marks: Iterable[str] = ()) -> None:
        """Put ``source`` and its ``clips`` (their files written) in the manifest in place of the
        earlier source of its name, write the manifest, then delete the clip files it dropped.

        marks: the writer's marks that the new clips get (the clips they replace lose theirs).
        """
        name = self._source_name(source.path)
        replaced = {s.path for s in self.manifest.sources if self._source_name(s.path) == name}
        new_ids = {clip.clip_id for clip in clips}
        stale = {clip.clip_id for clip in self.manifest.clips if clip.source in replaced} - new_ids
        self.manifest.sources = sorted([s for s in self.manifest.sources if s.path not in replaced] + [source],
                                       key=lambda s: s.path)
        self.manifest.clips = sorted([c for c in self.manifest.clips if c.source not in replaced] + list(clips),
                                     key=lambda c: c.clip_id)
        given = set(marks)
        for mark in self._marks:
            others = set(self.manifest.options[mark]) - stale - new_ids
            self.manifest.options[mark] = sorted(others | new_ids if mark in given else others)
        write_manifest(self.root, self.manifest)
        self.discard(stale)

    def assign_split(self, clip_ids: Iterable[str], split: str) -> None:
        """Move listed clips to ``split`` and write the manifest."""
        moving = set(clip_ids)
        self.manifest.clips = [replace(clip, split=split) if clip.clip_id in moving else clip
                               for clip in self.manifest.clips]
        write_manifest(self.root, self.manifest)

    def discard(self, clip_ids: Iterable[str]) -> None:
        """Delete the files of these clips, but for those the manifest lists (a source that failed
        after writing some of its clips leaves the store as it was)."""
        listed = {clip.clip_id for clip in self.manifest.clips}
        for clip_id in set(clip_ids) - listed:
            clip_path(self.root, clip_id).unlink(missing_ok=True)


def _differences(old: Mapping[str, Any], new: Mapping[str, Any], prefix: str = "") -> list[str]:
    """``key: old -> new`` for each option that differs, nested keys dotted."""
    out = []
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key), new.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            out += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            out.append(f"{prefix}{key}: {a!r} -> {b!r}")
    return out
