"""Decoding single messages: labels parsed in batches, raw images with padded rows."""

from __future__ import annotations

import json

import numpy as np
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.records import Channel, Schema

from data_ingest.ingest.mcap_reader import RawMessage
from data_ingest.contract import IMAGE
from data_ingest.ingest.messages import Decoder, LanesMsg, MessageError, parse_lanes3d
from data_ingest.synth.encoders import RAW_IMAGE, FoxgloveProtobufEncoder


def label(sec: int, points: list, visibility: list) -> bytes:
    return json.dumps({"timestamp": {"sec": sec, "nsec": 5}, "frame_id": "base_link", "extra": [1, 2],
                       "lanes": [{"track_id": 7, "category": 2, "points": points, "visibility": visibility},
                                 {"track_id": 8, "category": 1, "points": [[9.0, 9.0, 9.0]], "visibility": [1]}]},
                      indent=2).encode()  # pretty-printed: line breaks inside


def test_a_bad_label_in_a_batch_spoils_only_itself():
    good = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
    first, bad, last = parse_lanes3d([label(1, good, [1, 0.5]), label(2, [[1.0, 2.0]], [1]), label(3, good, [0, 1])])
    assert isinstance(bad, MessageError) and "a point does not have 3 coordinates" in str(bad)
    for message, sec, visibility in ((first, 1, [1, 0.5]), (last, 3, [0, 1])):
        assert isinstance(message, LanesMsg) and message.stamp_ns == sec * 10**9 + 5
        assert message.track_ids.tolist() == [7, 8] and message.num_points.tolist() == [2, 1]
        np.testing.assert_array_equal(message.points, [*good, [9.0, 9.0, 9.0]])
        np.testing.assert_array_equal(message.visibility, [*visibility, 1])
    (broken,) = parse_lanes3d([b'{"timestamp": {"sec": 1, "nsec": 0}, "lanes": [{"track_id": "seven"}]'])
    assert isinstance(broken, MessageError)


def test_raw_image_rows_lose_their_padding():
    pixels = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    padded = np.concatenate([pixels.reshape(2, 9), np.full((2, 7), 255, np.uint8)], axis=1)  # step 16
    message = RawImage(frame_id="cam", width=3, height=2, encoding="rgb8", step=16, data=padded.tobytes())
    schema = FoxgloveProtobufEncoder().schema(RAW_IMAGE)
    raw = RawMessage(Channel(id=1, topic="/image", message_encoding="protobuf", metadata={}, schema_id=1),
                     Schema(id=1, data=schema.data, encoding=schema.encoding, name=schema.name),
                     message.SerializeToString(), log_time=0, publish_time=0, sequence=0)
    image = Decoder().decode(raw, IMAGE)
    assert (image.encoding, image.width, image.height, image.data) == ("rgb8", 3, 2, pixels.tobytes())
