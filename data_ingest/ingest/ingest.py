"""Drive logs -> one clip store: which logs need work, the work on each, and the manifest.

:func:`ingest` finds the logs of ``cfg.input`` (a file, a folder searched for ``*.mcap``, or
a glob), skips those the store already holds unchanged (same name, same sha256, clips
present), and ingests the others, in ``cfg.workers`` processes: read (:mod:`scan`),
complete the frames (:mod:`assemble`), cut and write clips (:mod:`clips`). The store is
updated as every writing tool updates one (:class:`~lanelab.store.StoreWriter`): after each
log the manifest is rewritten atomically, so an interrupted run keeps every finished log and
the next run resumes with the rest. A log that fails is reported, the clip files it wrote
are deleted, and the others go on. The run holds the store's writers' lock, so a second
run into the same store is refused. Ctrl-C records the logs already finished (those of
the workers too), kills the workers (:mod:`workers`) and raises :class:`IngestInterrupted`
saying how many logs were recorded. :func:`verify` checks the store's clip files against
the sha256 the manifest records for them.

A log is known by its name (file stem). Its clip ids are ``<name>_<fingerprint>_<k>``
where the fingerprint hashes the log's sha256 and the store options: re-ingesting a
changed log writes new files, switches the manifest to them, then deletes the old ones,
so the store is consistent at every moment.
"""

from __future__ import annotations

import glob
import hashlib
import json
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from data_ingest.autolabel.log import autolabel_log
from data_ingest.autolabel.quality import Quality, report_text, write_quality
from data_ingest.ingest.assemble import PlannedFrame
from data_ingest.ingest.clips import clips_for_train, cut, draw_split, log_name, split_key
from data_ingest.ingest.config import IngestConfig, store_options
from data_ingest.ingest.errors import IngestInterrupted, LogError
from data_ingest.ingest.frames import read_frames
from data_ingest.ingest.log_result import FAILED, INGESTED, UNCHANGED, LogResult
from data_ingest.ingest.mcap_reader import ReadReport
from data_ingest.ingest.scan import LogContents
from data_ingest.ingest.spill import Spill
from data_ingest.ingest.summary import print_summary
from data_ingest.ingest.workers import in_workers
from lanelab.config_checks import ConfigError
from lanelab.progress import Progress
from lanelab.store import (
    UNREADABLE_SUFFIX,
    ClipEntry,
    ManifestError,
    SourceEntry,
    StoreBusy,
    StoreRefused,
    StoreWriter,
    damaged_clips,
    file_sha256,
    read_manifest,
    write_clip,
)

def source_name(path: str | Path) -> str:
    """The name a log is known by in a store and in its clip ids: its file stem, sanitised (:func:`log_name`)."""
    return log_name(Path(path).stem)


def find_logs(input_: str) -> list[Path]:
    """The logs of ``input_``: a file, every ``*.mcap`` below a folder, or the files a glob matches."""
    path = Path(input_)
    if path.is_file():
        return [path]
    if path.is_dir():
        return sorted(path.rglob("*.mcap"))
    return sorted(Path(match) for match in glob.glob(input_, recursive=True) if Path(match).is_file())


def fingerprint(sha256: str, options: dict) -> str:
    """8 hex digits naming what a log's clips were made from: its bytes and the store options."""
    return hashlib.sha256(f"{sha256}/{json.dumps(options, sort_keys=True)}".encode()).hexdigest()[:8]


# --- one log ---------------------------------------------------------------------------------

def ingest_log(path: Path, known_sha256: str | None, cfg: IngestConfig,
               progress: Callable[[int], None] = lambda n: None) -> LogResult:
    """Ingest the log at ``path`` into ``cfg.output`` unless its sha256 is ``known_sha256``.

    Writes its clip files (each atomically) but not the manifest; never raises for a bad log.
    ``progress(n)`` gets the bytes of the log read since its last call.
    """
    start = time.perf_counter()
    size = path.stat().st_size
    read = 0

    def count(n: int) -> None:
        nonlocal read
        read += n
        progress(n)

    result = LogResult(str(path), INGESTED)
    with ThreadPoolExecutor(max_workers=1) as hasher:
        sha256 = hasher.submit(file_sha256, path)  # hashlib releases the GIL: a new log is hashed while read
        if known_sha256 is not None and sha256.result() == known_sha256:
            result.status = UNCHANGED
        else:
            report = ReadReport(size)
            try:
                _ingest(path, cfg, report, result, sha256, count)
            except LogError as err:
                result.status, result.error = FAILED, str(err)
            except Exception as err:  # whatever else a damaged log provokes, the other logs go on
                result.status = FAILED
                result.error = f"{path}: cannot be ingested: {type(err).__name__}: {err}"
            result.warnings[:0] = report.problems()
        result.sha256 = sha256.result()
    progress(size - read)
    result.seconds = time.perf_counter() - start
    return result


def _ingest(path: Path, cfg: IngestConfig, report: ReadReport, result: LogResult, sha256: Future,
            progress: Callable[[int], None]) -> None:
    Path(cfg.output).mkdir(parents=True, exist_ok=True)
    with Spill(cfg.output) as spill:
        def autolabel(frames: list[PlannedFrame], contents: LogContents, warnings: list[str]) -> list[PlannedFrame]:
            frames, result.quality, result.autolabeled = autolabel_log(path, source_name(path), frames, contents,
                                                                       spill, cfg, warnings)
            return frames

        log = read_frames(path, cfg, spill, report, progress, autolabel if cfg.autolabel.enabled else None)
        result.dropped, result.warnings = log.dropped, result.warnings + log.warnings
        frames = log.frames
        if not frames:
            raise log.unusable(path)
        _write_clips(path, frames, spill, sha256.result(), cfg, result.clips)
        result.num_frames = len(frames)
        result.labeled = sum(frame.record.labeled for frame in frames)


def _write_clips(path: Path, frames: list[PlannedFrame], spill: Spill, sha256: str, cfg: IngestConfig,
                 written: list[ClipEntry]) -> None:
    """Cut the frames into clips and write them; each clip goes to ``written`` once its file is."""
    name = source_name(path)
    prefix = f"{name}_{fingerprint(sha256, store_options(cfg))}"
    stamps = np.array([frame.record.timestamp_ns for frame in frames], dtype=np.int64)
    for index, part in enumerate(cut(stamps, cfg.clips.gap_s, cfg.clips.max_length_s)):
        clip_id = f"{prefix}_{index:03d}"
        clip_sha256 = file_sha256(write_clip(cfg.output, clip_id, _with_images(frames[part], spill)))
        written.append(ClipEntry(clip_id, str(path), draw_split(split_key(name, index, cfg.split), cfg.split),
                                 len(frames[part]), int(stamps[part][0]), int(stamps[part][-1]), clip_sha256))


def _with_images(frames: list[PlannedFrame], spill: Spill) -> Iterator:
    """The frames' records with their image bytes, loaded one at a time."""
    return (replace(frame.record, image=spill.get(frame.image.data)) for frame in frames)


# --- a run -----------------------------------------------------------------------------------

def ingest(cfg: IngestConfig) -> list[LogResult]:
    """Ingest ``cfg.input`` into the store ``cfg.output``; print a progress bar and a closing summary.

    Raises ConfigError when there is no log or the store cannot take these options (or
    another run is writing it), IngestInterrupted on Ctrl-C once the finished logs are recorded.
    """
    logs = find_logs(cfg.input)
    if not logs:
        raise ConfigError(f"input={cfg.input!r}: no MCAP log there (a file, a folder of *.mcap or a glob)")
    try:
        writer = StoreWriter(cfg.output, store_options(cfg), source_name, overwrite=cfg.overwrite)
    except ManifestError as err:
        raise ConfigError(f"output={cfg.output!r} holds a manifest that cannot be read: {err}; overwrite=true "
                          f"re-ingests every log into a new one (the old one kept as manifest.json"
                          f"{UNREADABLE_SUFFIX})") from None
    except (StoreRefused, StoreBusy) as err:
        raise ConfigError(str(err)) from None
    except OSError as err:  # read-only, a file in the way, no space: before any log is read
        raise ConfigError(f"output={cfg.output}: cannot write the store there ({err.strerror or err})") from None
    if writer.set_aside is not None:
        print(f"lanelab-ingest: the unreadable manifest is kept as {writer.set_aside}; every log is ingested anew")
    with writer:
        return _ingest_logs(logs, cfg, writer)


def _ingest_logs(logs: list[Path], cfg: IngestConfig, writer: StoreWriter) -> list[LogResult]:
    start = time.perf_counter()
    results: dict[str, LogResult] = {}
    todo: list[tuple[Path, str | None]] = []
    names: dict[str, Path] = {}
    rewritten: dict[str, str] = {}  # log -> why its clips are re-written
    for path in logs:
        name = source_name(path)
        if name in names:
            results[str(path)] = LogResult(str(path), FAILED, error=f"{path}: has the same name as {names[name]}; "
                                                                    "a store knows logs by name: rename one")
            continue
        names[name] = path
        known, faults = writer.examine(str(path))
        todo.append((path, known))
        if faults:  # re-ingested whatever its sha256: say why, in its summary line
            rewritten[str(path)] = (f"re-written: the store's clip(s) of this log were missing or damaged "
                                    f"({'; '.join(faults)})")

    total = sum(path.stat().st_size for path, _ in todo)
    recorded = 0
    with Progress(total, "lanelab-ingest", "B", unit_scale=True) as bar:
        try:
            for result in _run(todo, cfg, bar):
                if result.status == INGESTED:
                    if result.path in rewritten:
                        result.warnings.insert(0, rewritten[result.path])
                    writer.commit(SourceEntry(result.path, result.sha256, result.num_frames), result.clips)
                    recorded += 1
                elif result.status == FAILED:
                    writer.discard(clip.clip_id for clip in result.clips)
                results[result.path] = result
        except KeyboardInterrupt:
            raise IngestInterrupted(f"interrupted: {recorded} log(s) ingested into {cfg.output} by this run are "
                                    "recorded; run the same command again to resume with the rest") from None
    in_order = [results[str(path)] for path in logs]
    moved = clips_for_train(writer.manifest.clips, cfg.split)
    if moved:
        writer.assign_split([clip.clip_id for clip in moved], "train")
    print_summary(in_order, writer.manifest, time.perf_counter() - start, cfg.split, moved)
    if cfg.autolabel.enabled and cfg.autolabel.report:
        _report_quality(in_order, cfg)
    return in_order


def _report_quality(results: list[LogResult], cfg: IngestConfig) -> None:
    """Print the auto-labels' quality on the logs of this run that have true lanes; write the report."""
    quality = Quality()
    for result in results:
        quality.extend(result.quality)
    if not quality.results:
        print(f"auto-label quality: no log of this run has true lanes on {cfg.topics.lanes} to score the "
              "auto-labels against")
        return
    out = Path(cfg.autolabel.report_dir or Path(cfg.output) / "autolabel_report")
    scored = [Path(r.path).name for r in results if r.quality.results]
    report, written = write_quality(quality, {"logs": ", ".join(scored), "store": cfg.output}, out,
                                    cfg.autolabel.pictures)
    print(f"\nAuto-labels against the true lanes on {cfg.topics.lanes}\n" + report_text(report))
    print(f"auto-label report: {', '.join(str(path) for path in written)}")


def _run(todo: list[tuple[Path, str | None]], cfg: IngestConfig, bar: Progress) -> Iterator[LogResult]:
    """Results of ingesting each log, as they finish (in worker processes when cfg.workers > 1)."""
    if cfg.workers == 1 or len(todo) < 2:
        for path, known in todo:
            yield ingest_log(path, known, cfg, bar.update)
        return
    jobs = [(path, known, cfg) for path, known in todo]
    yield from in_workers(ingest_log, jobs, min(cfg.workers, len(todo)), lambda n: bar.update(n - bar.n))


def verify(store: str) -> int:
    """Check every clip file of ``store`` against its manifest: print a line per missing or damaged
    clip, then a closing line; return how many are. Raises ConfigError when there is no store."""
    try:
        num_clips = len(read_manifest(store).clips)
    except ManifestError as err:
        raise ConfigError(str(err)) from None
    faults = damaged_clips(store)
    for line in faults:
        print(f"lanelab-ingest: {line}")
    print(f"lanelab-ingest: {store}: {len(faults)} of {num_clips} clip(s) missing or damaged"
          + ("; ingest their logs again to re-write them" if faults else ""))
    return len(faults)
