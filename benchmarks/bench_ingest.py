"""Ingest speed: frames/s of ``lanelab-ingest`` next to a raw read of the same log.

    python benchmarks/bench_ingest.py [--frames 200] [--repeats 5] [--json out.json]

For each encoding and resolution a synthetic log is written (JPEG images, zstd chunks, /tf
at 50 Hz, a 3D label on every frame), then timed:

- raw: the plain ``mcap`` reader with its decoders iterates the image topic and
  ``cv2.imdecode`` decodes every image (the floor of any reader that looks at the pixels);
- ingest: :func:`data_ingest.ingest.ingest.ingest_log` (hash, read every topic, TF
  interpolation, label transforms, clip files written) into a fresh store.

The ratio ingest / raw is the figure to quote. Figures are medians of ``--repeats`` runs,
raw and ingest interleaved, after a warm-up run. The ingestor parses
labels and hashes the log on a second thread (Arrow and hashlib release the GIL); everything
else, and the raw read, runs on one core.
"""

from __future__ import annotations

import argparse
import base64
import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

from data_ingest.ingest.config import load_ingest_config
from data_ingest.ingest.ingest import ingest_log
from data_ingest.synth.config import load_synth_config
from data_ingest.synth.drive import SyntheticDrive
from data_ingest.synth.mcap_writer import write_drive_log

ENCODINGS = {
    "ros2": ["encoding=ros2"],
    "foxglove-protobuf": ["encoding=foxglove", "foxglove_schema=protobuf"],
    "foxglove-json": ["encoding=foxglove", "foxglove_schema=json"],
}
RESOLUTIONS = [(360, 480), (720, 960)]
IMAGE_TOPIC = "/camera/front/image"


def raw_read(path: Path) -> int:
    """Read the log's images with the plain mcap reader and decode each; return the count.

    CDR and protobuf go through the reader's decoders; Foxglove JSON through json.loads and base64.
    """
    count = 0
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[Ros2DecoderFactory(), ProtobufDecoderFactory()])
        channel = next(c for c in reader.get_summary().channels.values() if c.topic == IMAGE_TOPIC)
        if channel.message_encoding == "json":
            images = (base64.b64decode(json.loads(message.data)["data"])
                      for _, _, message in reader.iter_messages(topics=[IMAGE_TOPIC], log_time_order=False))
        else:
            images = (decoded.data for _, _, _, decoded in
                      reader.iter_decoded_messages(topics=[IMAGE_TOPIC], log_time_order=False))
        for data in images:
            count += cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR) is not None
    return count


def _rate(frames: int, fn) -> float:
    start = time.perf_counter()
    fn()
    return frames / (time.perf_counter() - start)


def measure(tmp: Path, encoding: str, height: int, width: int, frames: int, repeats: int) -> dict:
    fps = 10.0
    synth = load_synth_config([*ENCODINGS[encoding], f"camera.height={height}", f"camera.width={width}",
                               f"duration_s={frames / fps}", f"fps={fps}"])
    log = tmp / f"{encoding}_{height}x{width}.mcap"
    write_drive_log(log, SyntheticDrive(synth, 0), synth, log_index=0)
    raw, ingest = [], []
    for repeat in range(repeats + 1):  # the first round warms caches and imports up
        cfg = load_ingest_config([f"input={log}", f"output={tmp / f'store_{encoding}_{height}_{repeat}'}"])
        raw.append(_rate(frames, lambda: raw_read(log)))
        result = ingest_log(log, None, cfg)
        assert result.status == "ingested" and result.num_frames == frames, result
        ingest.append(frames / result.seconds)
    raw_fps, ingest_fps = statistics.median(raw[1:]), statistics.median(ingest[1:])
    return {"encoding": encoding, "resolution": f"{height}x{width}", "mb": log.stat().st_size / 1e6,
            "raw_fps": raw_fps, "ingest_fps": ingest_fps, "ratio": ingest_fps / raw_fps}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for height, width in RESOLUTIONS:
            for encoding in ENCODINGS:
                rows.append(measure(Path(tmp), encoding, height, width, args.frames, args.repeats))
                r = rows[-1]
                print(f"{r['resolution']:>9}  {r['encoding']:<18} {r['mb']:6.1f} MB  raw {r['raw_fps']:7.0f} "
                      f"frames/s  ingest {r['ingest_fps']:7.0f} frames/s  ratio {r['ratio']:.2f}", flush=True)
    if args.json:
        args.json.write_text(json.dumps({"machine": platform.processor() or platform.machine(),
                                         "frames": args.frames, "repeats": args.repeats, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
