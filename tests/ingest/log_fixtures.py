"""Small synthetic drive logs for the ingestor's tests (and lanelab-predict's), written once per session.

The drive is rendered once (:class:`CachedDrive`); every log of the session is written from its
frames with the writer options a test asks for (encoding, image format, names, label frame).
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path
from typing import Callable

import pytest
from ingest_helpers import ENCODINGS, LOG_NAME, CachedDrive, small_config

from data_ingest.synth.drive import SyntheticDrive
from data_ingest.synth.mcap_writer import write_drive_log


@pytest.fixture(scope="session")
def drive() -> CachedDrive:
    """Log 0 of seed 0 at the small config, rendered once."""
    return CachedDrive.render(SyntheticDrive(small_config(), 0))


@pytest.fixture(scope="session")
def synth_log(tmp_path_factory, drive) -> Callable[..., Path]:
    """``synth_log(encoding="ros2", *overrides) -> Path``: the drive written as a log, cached.

    ``overrides`` are writer options of conf/synth.yaml. Logs of the drive in different
    encodings have the same file name in different folders.
    """
    cache: dict[tuple, Path] = {}

    def make(encoding: str = "ros2", *overrides: str) -> Path:
        key = (encoding, *overrides)
        if key not in cache:
            folder = tmp_path_factory.mktemp(hashlib.sha1(repr(key).encode()).hexdigest()[:10])
            cfg = small_config(*ENCODINGS[encoding], *overrides)
            source = dataclasses.replace(drive, camera=dataclasses.replace(drive.camera, frame_id=cfg.camera.frame_id))
            cache[key] = write_drive_log(folder / LOG_NAME, source, cfg, log_index=0).path
        return cache[key]

    return make
