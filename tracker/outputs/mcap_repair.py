"""Recover the intact part of an MCAP recording whose writer died (no summary, no footer).

The tracker's sink writes messages only inside chunks, each with a CRC and handed to the
operating system once finished, so a killed writer leaves ``header, metadata..., chunk, message
indexes, chunk, ...`` and at most one cut record. ``recover_mcap`` reads it sequentially with
``mcap``'s StreamReader (CRCs checked: a chunk's records come only once it is whole) and copies
schemas, channels, messages and metadata into a new, finished file, stopping at the first record
cut short or failing its CRC. (``mcap``'s seeking reader starts from the footer: hence the copy.)
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.writer import CompressionType, Writer

from regressor.errors import SilhouettePoseError


class McapRecoveryError(SilhouettePoseError, ValueError):
    """The source cannot be recovered at all (e.g. not an MCAP file); message names the file."""


@dataclass(frozen=True)
class RecoveryReport:
    """What recover_mcap copied.

    messages: messages copied; metadata: metadata records copied; complete: the source had its
    footer (nothing was lost); stopped_by: why reading stopped early ("" when complete), e.g.
    "EndOfFile" for a file cut mid-record or "CRCValidationError".
    """

    messages: int
    metadata: int
    complete: bool
    stopped_by: str


def recover_mcap(src: str | Path, dst: str | Path, chunk_size: int = 64 * 1024) -> RecoveryReport:
    """Copy every intact message of ``src`` (possibly truncated) into a valid MCAP file ``dst``.

    Raises McapRecoveryError when ``src`` does not start with the MCAP magic, or when
    ``dst`` is ``src``.
    """
    src, dst = Path(src), Path(dst)
    if src.resolve() == dst.resolve():
        raise McapRecoveryError(f"{src}: recovery needs a different output file")
    copied = {"messages": 0, "metadata": 0}
    complete, stopped_by = False, ""
    with open(src, "rb") as source:
        magic = source.read(8)
        if magic != b"\x89MCAP0\r\n":
            raise McapRecoveryError(f"{src}: not an MCAP file (bad magic)")
        source.seek(0)
        with open(dst, "wb") as target:
            writer = Writer(target, chunk_size=chunk_size, compression=CompressionType.ZSTD)
            writer.start(profile="", library="silhouette-pose mcap_repair")
            schema_ids: dict[int, int] = {}
            channel_ids: dict[int, int] = {}
            try:
                for record in StreamReader(source, validate_crcs=True).records:
                    if isinstance(record, Footer):
                        complete = True
                    else:
                        _copy(record, writer, schema_ids, channel_ids, copied)
            except (McapError, CRCValidationError, struct.error, EOFError) as error:
                stopped_by = type(error).__name__
            writer.finish()
    return RecoveryReport(copied["messages"], copied["metadata"], complete, stopped_by)


def _copy(record, writer: Writer, schema_ids: dict[int, int], channel_ids: dict[int, int],
          copied: dict[str, int]) -> None:
    """Copy one record; schemas and channels are registered once (the summary repeats them)."""
    if isinstance(record, Schema) and record.id not in schema_ids:
        schema_ids[record.id] = writer.register_schema(record.name, record.encoding, record.data)
    elif isinstance(record, Channel) and record.id not in channel_ids:
        channel_ids[record.id] = writer.register_channel(
            record.topic, record.message_encoding, schema_ids.get(record.schema_id, 0),
            dict(record.metadata))
    elif isinstance(record, Message) and record.channel_id in channel_ids:
        writer.add_message(channel_ids[record.channel_id], log_time=record.log_time,
                           data=record.data, publish_time=record.publish_time,
                           sequence=record.sequence)
        copied["messages"] += 1
    elif isinstance(record, Metadata):
        writer.add_metadata(record.name, dict(record.metadata))
        copied["metadata"] += 1
