"""Reading the messages of an MCAP file front to back, recovering what a damaged file still holds.

Every log is read sequentially with the ``mcap`` library's :class:`StreamReader` (no index
needed), so an intact file and a truncated one (no footer or summary: a recorder that died)
take the same path. As ``mcap recover`` does, every complete message before a break is
kept and the break is reported with what was lost. Chunks are decompressed and their CRCs
checked here, one at a time: a chunk that fails is skipped and counted (with the messages
its index says it held), and reading goes on after it.

Message payloads are not decoded here (see :mod:`data_ingest.ingest.messages`); the caller
names the topics it wants and the others are only counted.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Callable, Collection, Iterator, Optional

from mcap.exceptions import InvalidMagic
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, DataEnd, Message, MessageIndex, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from data_ingest.ingest.errors import LogError


@dataclass(frozen=True)
class RawMessage:
    """A message of a wanted topic, still serialized, with its record's times (ns) and sequence."""

    channel: Channel
    schema: Optional[Schema]  # None when the channel has no schema (schema id 0)
    data: bytes
    log_time: int
    publish_time: int
    sequence: int

    @property
    def topic(self) -> str:
        return self.channel.topic


@dataclass
class ReadReport:
    """What reading a log of ``size`` bytes found, besides its messages."""

    size: int
    topics: Counter = field(default_factory=Counter)  # messages per topic, every channel listed
    schemas: dict[str, Optional[Schema]] = field(default_factory=dict)  # per topic
    bad_chunks: list[str] = field(default_factory=list)  # one line per skipped chunk
    lost_in_bad_chunks: Counter = field(default_factory=Counter)  # messages per topic, from the chunks' indexes
    broken_at: Optional[str] = None  # where and why reading stopped before the footer
    break_byte: Optional[int] = None  # where it stopped
    break_reason: Optional[str] = None  # why
    data_complete: bool = False  # the data section's end was read (a break after it loses no message)

    def problems(self) -> list[str]:
        """Damage found, one line each (nothing for an intact file)."""
        lines = []
        if self.bad_chunks:
            lost = ", ".join(f"{n} on {topic}" for topic, n in sorted(self.lost_in_bad_chunks.items()))
            lines.append(f"skipped {len(self.bad_chunks)} bad chunk(s)" + (f" holding {lost}" if lost else "")
                         + ": " + "; ".join(self.bad_chunks))
        if self.broken_at and self.data_complete:
            lines.append("the summary section or footer is cut; every message was read")
        elif self.broken_at:
            lines.append(self.broken_at)
        return lines


def read_messages(
    path: Path,
    topics: Collection[str],
    report: ReadReport,
    progress: Callable[[int], None] | None = None,
) -> Iterator[RawMessage]:
    """Yield the messages of ``topics`` in file order; fill ``report`` as the file is read.

    ``progress(n)`` is called with the bytes read since its last call. Raises
    :class:`LogError` only for a file with nothing to read (empty, not MCAP).
    """
    if report.size == 0:
        raise LogError(f"{path}: empty file (0 bytes)")
    wanted = set(topics)
    messages = 0
    with open(path, "rb") as handle:
        schemas, summary_channels = _summary_records(handle)
        channels: dict[int, Channel] = {}

        def add_channel(channel: Channel) -> None:
            channels[channel.id] = channel
            report.topics[channel.topic] += 0  # a topic without messages still shows
            report.schemas[channel.topic] = schemas.get(channel.schema_id)

        for channel in summary_channels.values():
            add_channel(channel)
        # No record can be longer than the file: a garbled length fails at once, not after a huge read.
        records = StreamReader(handle, emit_chunks=True, record_size_limit=report.size).records
        record_start = 0  # where the next record begins
        last_chunk_bad = False
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except Exception as err:  # a cut or garbled record ends the readable part of the file
                if record_start == 0:
                    reason = ("not an MCAP file (no MCAP magic at its start)" if isinstance(err, InvalidMagic)
                              else f"no complete MCAP record ({type(err).__name__})")
                    raise LogError(f"{path}: {reason}") from None
                _break(report, record_start, messages, f"{type(err).__name__} {err}".strip())
                return
            position = handle.tell()
            if progress is not None:
                progress(position - record_start)
            if isinstance(record, Chunk):
                if position >= report.size:  # a valid file never ends with a chunk: this one is cut short
                    _break(report, record_start, messages, "the chunk there is cut")
                    return
                inner = _open_chunk(record, record_start, position, report)
                last_chunk_bad = inner is None
            elif isinstance(record, MessageIndex):  # follows its chunk, tells what a bad one held
                if last_chunk_bad and record.channel_id in channels:
                    report.lost_in_bad_chunks[channels[record.channel_id].topic] += len(record.records)
                inner = []
            else:
                inner, last_chunk_bad = [record], False
                report.data_complete |= isinstance(record, DataEnd)
            record_start = position
            for item in inner or ():
                if isinstance(item, Message):
                    channel = channels.get(item.channel_id)
                    if channel is None:
                        continue  # its channel record was in a bad chunk
                    messages += 1
                    report.topics[channel.topic] += 1
                    if channel.topic in wanted:
                        yield RawMessage(channel, schemas.get(channel.schema_id), item.data, item.log_time,
                                         item.publish_time, item.sequence)
                elif isinstance(item, Schema):
                    schemas[item.id] = item
                elif isinstance(item, Channel):
                    add_channel(item)


def _summary_records(handle: BinaryIO) -> tuple[dict[int, Schema], dict[int, Channel]]:
    """Schemas and channels from the summary section, if the file has one: a chunk lost to a bad CRC
    may have held the only other copy of a channel record. Leaves ``handle`` at the start."""
    try:
        summary = SeekingReader(handle).get_summary()
    except Exception:  # no footer or no summary: the records come from the data section alone
        summary = None
    handle.seek(0)
    return (dict(summary.schemas), dict(summary.channels)) if summary else ({}, {})


def _break(report: ReadReport, at: int, messages: int, why: str) -> None:
    """Record where and why reading stopped."""
    report.break_byte, report.break_reason = at, why
    report.broken_at = (f"truncated or unreadable from byte {at} of {report.size} ({why}): recovered the {messages} "
                        f"messages before it; the last {report.size - at} bytes are lost")


def _open_chunk(chunk: Chunk, start: int, end: int, report: ReadReport) -> list | None:
    """The records of a chunk, or None (reported) when it fails its CRC or cannot be decompressed."""
    try:
        return breakup_chunk(chunk, validate_crc=True)
    except Exception as err:  # CRC mismatch, ZstdError, lz4 errors, garbled records: the chunk is lost
        report.bad_chunks.append(
            f"chunk at bytes {start}-{end} (log time {chunk.message_start_time / 1e9:.3f}-"
            f"{chunk.message_end_time / 1e9:.3f} s): {type(err).__name__}: {err}")
        return None
