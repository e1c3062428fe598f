"""What became of one drive log in a ``lanelab-ingest`` run: :class:`LogResult` and its statuses.

Its own module because two others read it: :mod:`~data_ingest.ingest.ingest` fills it in and
:mod:`~data_ingest.ingest.summary` prints it, and ``ingest`` calls the summary (one way only).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from data_ingest.autolabel.quality import Quality
from lanelab.store import ClipEntry

INGESTED, UNCHANGED, FAILED = "ingested", "unchanged", "failed"


@dataclass
class LogResult:
    """What happened to one log."""

    path: str
    status: str  # INGESTED | UNCHANGED | FAILED
    sha256: str = ""
    clips: list[ClipEntry] = field(default_factory=list)  # of a failed log: those written before it failed
    num_frames: int = 0
    labeled: int = 0
    dropped: Counter = field(default_factory=Counter)  # frames, by reason
    warnings: list[str] = field(default_factory=list)
    error: str | None = None
    seconds: float = 0.0
    autolabeled: str = ""  # with autolabel.enabled: what the auto-labeler made of the log
    quality: Quality = field(default_factory=Quality)  # auto-labels scored against the log's true lanes
