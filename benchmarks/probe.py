"""What the probes of a trained detector (bend_probe.py, shift_probe.py) share: their command
line and the frames they run on."""

from __future__ import annotations

import argparse
from collections.abc import Iterator

from lanelab.store import ClipStore, FrameRecord


def probe_parser(description: str) -> argparse.ArgumentParser:
    """Arguments: checkpoint, store, --split, --every."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("store")
    parser.add_argument("--split", default="test")
    parser.add_argument("--every", type=int, default=2, help="probe every k-th frame of each clip")
    return parser


def probed_frames(args: argparse.Namespace) -> Iterator[FrameRecord]:
    """Every ``args.every``-th frame of each clip of the store's split."""
    store = ClipStore(args.store)
    for clip in store.clips_in(args.split):
        yield from store.read_frames(clip.clip_id)[:: args.every]
