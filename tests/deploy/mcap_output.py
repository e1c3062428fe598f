"""Reading a predicted log the way another tool would: the ``mcap`` library's reader, the
decoders of its ROS 2 and protobuf support packages, and the Foxglove protobuf schemas
(``foxglove_schemas_protobuf``); Foxglove's JSON is parsed by protobuf's own JSON parser
(unknown or mistyped fields fail), after writing its times as protobuf's JSON writes them."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from google.protobuf import json_format
from google.protobuf.descriptor import Descriptor
from google.protobuf.duration_pb2 import Duration
from google.protobuf.message import Message
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory


@dataclass(frozen=True)
class Record:
    topic: str
    schema_name: str
    schema_encoding: str
    message_encoding: str
    log_time: int
    data: bytes
    decoded: Any  # what the mcap decoders (or json.loads) make of it


def read_mcap(path: Path) -> tuple[str, list[Record]]:
    """The header's profile and every message, decoded, in log-time order."""
    factories = [Ros2DecoderFactory(), ProtobufDecoderFactory()]
    decoders: dict[int, Callable[[bytes], Any]] = {}
    records = []
    with open(path, "rb") as handle:
        reader = make_reader(handle)
        profile = reader.get_header().profile
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            if channel.id not in decoders:
                found = [f.decoder_for(channel.message_encoding, schema) for f in factories]
                decoders[channel.id] = json.loads if channel.message_encoding == "json" else next(filter(None, found))
            records.append(Record(channel.topic, schema.name if schema else "", schema.encoding if schema else "",
                                  channel.message_encoding, message.log_time, message.data,
                                  decoders[channel.id](message.data)))
    return profile, records


def as_foxglove(record: Record, message_type: type[Message]) -> Message:
    """The record as its Foxglove protobuf type, checking its schema names that type."""
    assert record.schema_name == message_type.DESCRIPTOR.full_name
    if record.message_encoding == "protobuf":
        assert record.schema_encoding == "protobuf"
        return message_type.FromString(record.data)
    assert (record.schema_encoding, record.message_encoding) == ("jsonschema", "json")
    return json_format.ParseDict(_protobuf_json(record.decoded, message_type.DESCRIPTOR), message_type())


def _protobuf_json(value: Any, descriptor: Descriptor) -> Any:
    """Foxglove's JSON ({"sec", "nsec"} times) -> protobuf's JSON mapping (RFC 3339 / "1.5s")."""
    if descriptor.full_name in ("google.protobuf.Timestamp", "google.protobuf.Duration"):
        time = (Timestamp if descriptor.full_name.endswith("Timestamp") else Duration)(
            seconds=value["sec"], nanos=value["nsec"])
        return time.ToJsonString()
    out = {}
    for key, item in value.items():
        field = descriptor.fields_by_name[key]  # an unknown field fails here
        if field.message_type is None:
            out[key] = item
        elif field.is_repeated:
            out[key] = [_protobuf_json(entry, field.message_type) for entry in item]
        else:
            out[key] = _protobuf_json(item, field.message_type)
    return out
