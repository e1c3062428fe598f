"""Write a set of synthetic drive logs: parallel workers, a progress bar, a summary, a preview.

Each log is written atomically under ``<output_dir>/<name>.mcap``; logs already there
are kept, so an interrupted run resumes where it stopped. A run holds the folder's lock
(``<output_dir>/.synth.lock``, :mod:`lanelab.folder_lock`) from before it writes
``synth_config.yaml`` to its end: a second run into the same folder stops at once, naming the
process that writes it, so the folder never mixes two runs' logs and config.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import time
from concurrent.futures import ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

from omegaconf import OmegaConf

from data_ingest.synth.config import SynthConfig
from data_ingest.synth.drive import SyntheticDrive
from data_ingest.synth.frame import SynthFrame
from data_ingest.synth.mcap_writer import LogSummary, write_drive_log
from data_ingest.synth.preview import PreviewRow, frames_to_keep, write_contact_sheet
from lanelab.atomic_file import PARTIAL_GLOB, atomic_output
from lanelab.child_processes import init_worker, kill_pool
from lanelab.config_checks import ConfigError
from lanelab.folder_lock import FolderBusy, lock_folder
from lanelab.progress import Progress

LOCK_NAME = ".synth.lock"
PREVIEW_LOGS = 4
PREVIEW_FRAMES = 3


@dataclass
class LogResult:
    """What one log's job returns to the parent process."""

    path: Path
    summary: LogSummary | None  # None when the log already existed
    preview: PreviewRow | None


def log_path(cfg: SynthConfig, index: int) -> Path:
    return Path(cfg.output_dir) / f"synth_s{cfg.seed}_{index:03d}.mcap"


def frames_per_log(cfg: SynthConfig) -> int:
    return max(int(round(cfg.duration_s * cfg.fps)), 1)


class _KeepFrames:
    """A drive whose ``frames()`` also keeps a few frames for the preview."""

    def __init__(self, drive: SyntheticDrive, keep: set[int], row: PreviewRow) -> None:
        self._drive, self._keep, self._row = drive, keep, row

    def __getattr__(self, name: str):
        return getattr(self._drive, name)

    def frames(self) -> Iterator[SynthFrame]:
        for frame in self._drive.frames():
            if frame.index in self._keep:
                self._row.frames.append(frame)
            yield frame


def _preview_frames(drive: SyntheticDrive, keep: set[int], row: PreviewRow) -> None:
    """Render (without writing) a log that already exists, up to its last kept frame."""
    for frame in _KeepFrames(drive, keep, row).frames():
        if frame.index >= max(keep):
            break


def write_one_log(cfg: SynthConfig, index: int, with_preview: bool, progress: Callable[[int], None]) -> LogResult:
    """Write log ``index`` unless it exists (or ``cfg.overwrite``); keep preview frames."""
    drive = SyntheticDrive(cfg, index)
    path = log_path(cfg, index)
    row = PreviewRow(path.stem, drive.camera, drive.scenario) if with_preview else None
    keep = frames_to_keep(frames_per_log(cfg), PREVIEW_FRAMES) if with_preview else set()
    if path.exists() and not cfg.overwrite:
        if row is not None:
            _preview_frames(drive, keep, row)
        return LogResult(path, None, row)
    source = _KeepFrames(drive, keep, row) if row is not None else drive
    return LogResult(path, write_drive_log(path, source, cfg, progress=progress, log_index=index), row)


_counter = None  # frames written, shared with the worker processes


def _init_worker(counter, parent_pid: int) -> None:
    global _counter
    _counter = counter
    init_worker(parent_pid)


def _count_frame(n: int = 1) -> None:
    with _counter.get_lock():
        _counter.value += n


def _worker(cfg: SynthConfig, index: int, with_preview: bool) -> LogResult:
    return write_one_log(cfg, index, with_preview, _count_frame)


def _run_parallel(cfg: SynthConfig, bar: Progress) -> list[LogResult]:
    """The logs written by ``cfg.workers`` processes, which die with this one; on Ctrl-C or an
    error they are killed at once (the logs they were writing stay partial, cleared next run)."""
    ctx = mp.get_context("fork")
    counter = ctx.Value("q", 0)
    pool = ProcessPoolExecutor(cfg.workers, mp_context=ctx, initializer=_init_worker, initargs=(counter, os.getpid()))
    try:
        futures = [pool.submit(_worker, cfg, i, i < PREVIEW_LOGS and cfg.preview) for i in range(cfg.num_logs)]
        pending = set(futures)
        while pending:
            _, pending = wait(pending, timeout=0.25)
            bar.update(counter.value - bar.n)
        results = [future.result() for future in futures]
    except BaseException:
        kill_pool(pool)
        raise
    pool.shutdown()
    return results


def _print_summary(results: list[LogResult], seconds: float) -> None:
    written = [r.summary for r in results if r.summary is not None]
    frames = sum(s.num_frames for s in written)
    print(f"\n{'log':<28}{'frames':>8}{'MB':>9}  scenario")
    for result in results:
        scenario = result.preview.scenario if result.preview else {}
        if result.summary is None:
            print(f"{result.path.name:<28}{'kept':>8}{'':>9}  (already there; overwrite=true to rewrite)")
            continue
        s = result.summary
        print(f"{result.path.name:<28}{s.num_frames:>8}{s.bytes / 1e6:>9.1f}  "
              + " ".join(f"{k}={v}" for k, v in sorted(scenario.items())))
    rate = frames / seconds if seconds > 0 else 0.0
    print(f"{len(written)} logs written, {len(results) - len(written)} kept, {frames} frames "
          f"in {seconds:.1f} s ({rate:.1f} frames/s)")


def synthesize(cfg: SynthConfig) -> list[LogResult]:
    """Write ``cfg.num_logs`` drive logs into ``cfg.output_dir`` (and the preview).

    Raises ConfigError when another run holds the folder or it cannot be written."""
    out = Path(cfg.output_dir)
    try:
        lock = lock_folder(out, LOCK_NAME)
    except FolderBusy as busy:
        raise ConfigError(f"output_dir={out} is being written by another lanelab-synth ({busy.owner}); wait for "
                          "it to finish or choose another output_dir") from None
    except OSError as err:
        raise ConfigError(f"output_dir={out}: cannot write there ({err.strerror or err})") from None
    with lock:
        for leftover in out.glob(PARTIAL_GLOB):  # a killed run's temporaries: no other run writes here
            leftover.unlink(missing_ok=True)
        return _synthesize(cfg, out)


def _synthesize(cfg: SynthConfig, out: Path) -> list[LogResult]:
    with atomic_output(out / "synth_config.yaml") as tmp:
        tmp.write_text(OmegaConf.to_yaml(OmegaConf.structured(cfg)))
    todo = sum(1 for i in range(cfg.num_logs) if cfg.overwrite or not log_path(cfg, i).exists())
    start = time.perf_counter()
    with Progress(todo * frames_per_log(cfg), "lanelab-synth", "frames") as bar:
        if cfg.workers > 1 and cfg.num_logs > 1:
            results = _run_parallel(cfg, bar)
        else:
            results = [write_one_log(cfg, i, i < PREVIEW_LOGS and cfg.preview, bar.update)
                       for i in range(cfg.num_logs)]
    _print_summary(results, time.perf_counter() - start)
    if cfg.preview:
        rows = [r.preview for r in results if r.preview is not None]
        print(f"preview: {write_contact_sheet(out / 'preview.png', rows)}")
    return results
