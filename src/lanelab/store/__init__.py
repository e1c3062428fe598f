"""The clip store (DESIGN.md, "Clip store contract"), a stage of its own: no torch, no model.

- :mod:`~lanelab.store.schema`: the format, its Parquet columns and file layout, defined once;
- :mod:`~lanelab.store.records`: a clip file's rows as :class:`FrameRecord` (lanes: :class:`lanelab.lanes.Lane`);
- :mod:`~lanelab.store.manifest`: ``manifest.json``, read and written;
- :mod:`~lanelab.store.clip_file`: clip files written and read (the only code that names columns);
- :mod:`~lanelab.store.reader`: :class:`ClipStore`, what the datasets read;
- :mod:`~lanelab.store.writer`: :class:`StoreWriter`, the one update policy of the writing tools;
- :mod:`~lanelab.store.lock`: the writers' lock, one writing process at a time;
- :mod:`~lanelab.store.integrity`: clip files checked against the sha256 the manifest records;
- :mod:`~lanelab.store.image_codec`: the stored images' encodings, decoded to RGB.
"""

from lanelab.store.clip_file import ClipFileError, write_clip
from lanelab.store.integrity import damaged_clips, file_sha256
from lanelab.store.lock import StoreBusy
from lanelab.store.manifest import (
    ClipEntry,
    Manifest,
    ManifestError,
    WITHOUT_POSE,
    SourceEntry,
    clips_without_pose,
    read_manifest,
    write_manifest,
)
from lanelab.store.reader import ClipStore, DataError
from lanelab.store.records import FrameRecord
from lanelab.store.schema import CLIP_SCHEMA, SPLITS, clip_path, manifest_path
from lanelab.store.writer import MADE_BY_OPTION, UNREADABLE_SUFFIX, StoreRefused, StoreWriter
