"""The closing summary of ``lanelab-ingest``: a line per log, its problems, then totals."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path

from data_ingest.ingest.config import SplitConfig
from data_ingest.ingest.log_result import INGESTED, LogResult
from lanelab.store import SPLITS, ClipEntry, Manifest


def print_summary(results: list[LogResult], manifest: Manifest, seconds: float, split: SplitConfig,
                  moved: Sequence[ClipEntry] = ()) -> None:
    """The table of logs, the totals, the store's clips per split, and a warning naming each split
    that the ratios give a share but has no clip (``moved``: the clips put into train for lack of one)."""
    print(f"\n{'log':<32}{'status':>10}{'frames':>8}{'clips':>7}{'labeled':>9}{'dropped':>9}")
    for r in results:
        counts = f"{r.num_frames:>8}{len(r.clips):>7}{_percent(r.labeled, r.num_frames):>9}" \
                 f"{sum(r.dropped.values()):>9}" if r.status == INGESTED else ""
        print(f"{Path(r.path).name:<32}{r.status:>10}{counts}")
        if r.error:
            print(f"    error: {r.error}")
        if r.autolabeled:
            print(f"    auto-labels: {r.autolabeled}")
        for warning in r.warnings:
            print(f"    warning: {warning}")

    statuses = Counter(r.status for r in results)
    frames = sum(r.num_frames for r in results)
    labeled = sum(r.labeled for r in results)
    dropped = sum((r.dropped for r in results), Counter())
    print(f"{len(results)} logs: " + ", ".join(f"{n} {status}" for status, n in sorted(statuses.items()))
          + f"; {frames} frames ingested in {seconds:.1f} s ({frames / max(seconds, 1e-9):.0f} frames/s), "
          + f"{_percent(labeled, frames)} labeled, {sum(dropped.values())} dropped"
          + (":" if dropped else ""))
    for reason, n in dropped.most_common():
        print(f"{n:>8}  {reason}")
    splits = Counter(clip.split for clip in manifest.clips)
    print(f"store: {len(manifest.clips)} clips, {sum(c.num_frames for c in manifest.clips)} frames from "
          f"{len(manifest.sources)} logs (" + ", ".join(f"{s} {splits[s]}" for s in SPLITS) + " clips)")
    if moved:
        print(f"note: no clip drew the train split; moved there from {moved[0].split}: "
              + ", ".join(clip.clip_id for clip in moved))
    empty = [name for name in SPLITS if getattr(split, name) > 0 and splits[name] == 0]
    if empty and manifest.clips:
        print(f"warning: no clip in split {', '.join(empty)}: lanelab-train needs train and val clips (and test for "
              f"test=true). With few logs, split.by=clip draws each clip apart (clips.max_length_s cuts long logs "
              f"into more clips)")


def _percent(part: int, whole: int) -> str:
    return f"{100 * part / whole:.1f}%" if whole else "-"
