"""Foxglove's JSON encoding of its schemas, derived from the protobuf definitions.

Foxglove's ``jsonschema`` types have the fields of its protobuf types under the same names,
with times and durations as ``{"sec", "nsec"}`` objects and bytes as base64 strings. :func:`json_schema`
and :func:`to_json` walk the protobuf descriptor, so a JSON channel carries exactly what
the protobuf one would. The lanelab JSON messages follow the same conventions.
"""

from __future__ import annotations

import base64
import json
from typing import Any, Mapping

from google.protobuf.descriptor import Descriptor, FieldDescriptor
from google.protobuf.message import Message

_TIMES = ("google.protobuf.Timestamp", "google.protobuf.Duration")  # both {"sec", "nsec"} in JSON

TIME_SCHEMA = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
    },
}

_SCALAR_SCHEMAS = {
    FieldDescriptor.TYPE_DOUBLE: {"type": "number"},
    FieldDescriptor.TYPE_FLOAT: {"type": "number"},
    FieldDescriptor.TYPE_INT32: {"type": "integer"},
    FieldDescriptor.TYPE_INT64: {"type": "integer"},
    FieldDescriptor.TYPE_UINT32: {"type": "integer", "minimum": 0},
    FieldDescriptor.TYPE_UINT64: {"type": "integer", "minimum": 0},
    FieldDescriptor.TYPE_FIXED32: {"type": "integer", "minimum": 0},
    FieldDescriptor.TYPE_FIXED64: {"type": "integer", "minimum": 0},
    FieldDescriptor.TYPE_BOOL: {"type": "boolean"},
    FieldDescriptor.TYPE_STRING: {"type": "string"},
    FieldDescriptor.TYPE_BYTES: {"type": "string", "contentEncoding": "base64"},
    FieldDescriptor.TYPE_ENUM: {"type": "integer"},
}


def json_schema(descriptor: Descriptor) -> dict[str, Any]:
    """The JSON schema of a Foxglove message type, e.g. ``CompressedImage.DESCRIPTOR``."""
    if descriptor.full_name in _TIMES:
        return dict(TIME_SCHEMA)
    return {
        "title": descriptor.full_name,
        "type": "object",
        "properties": {field.name: _field_schema(field) for field in descriptor.fields},
    }


def _field_schema(field: FieldDescriptor) -> dict[str, Any]:
    item = json_schema(field.message_type) if field.message_type else dict(_SCALAR_SCHEMAS[field.type])
    return {"type": "array", "items": item} if field.is_repeated else item


def to_json(message: Message) -> dict[str, Any]:
    """A Foxglove protobuf message as the JSON object of its ``jsonschema`` twin."""
    if message.DESCRIPTOR.full_name in _TIMES:
        return {"sec": message.seconds, "nsec": message.nanos}
    return {field.name: _field_value(field, getattr(message, field.name)) for field in message.DESCRIPTOR.fields}


def _field_value(field: FieldDescriptor, value: Any) -> Any:
    if field.is_repeated:
        return [_single_value(field, item) for item in value]
    return _single_value(field, value)


def _single_value(field: FieldDescriptor, value: Any) -> Any:
    if field.message_type:
        return to_json(value)
    if field.type == FieldDescriptor.TYPE_BYTES:
        return base64.b64encode(value).decode("ascii")
    return value


def from_json(value: Mapping[str, Any], message_type: type[Message]) -> Message:
    """A message in Foxglove's JSON encoding (what :func:`to_json` makes) as its protobuf type."""
    message = message_type()
    _fill(message, value)
    return message


def _fill(message: Message, value: Mapping[str, Any]) -> None:
    if message.DESCRIPTOR.full_name in _TIMES:
        message.seconds, message.nanos = int(value["sec"]), int(value["nsec"])
        return
    for field in message.DESCRIPTOR.fields:
        if field.name not in value:
            continue
        item, target = value[field.name], getattr(message, field.name)
        if field.message_type:
            for entry in item if field.is_repeated else ():
                _fill(target.add(), entry)
            if not field.is_repeated:
                _fill(target, item)
            continue
        if field.type == FieldDescriptor.TYPE_BYTES:
            item = [base64.b64decode(v) for v in item] if field.is_repeated else base64.b64decode(item)
        if field.is_repeated:
            target.extend(item)
        else:
            setattr(message, field.name, item)


def dumps(message: Mapping[str, Any]) -> bytes:
    """Compact UTF-8 JSON; key order as built, so equal inputs give equal bytes."""
    return json.dumps(message, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
