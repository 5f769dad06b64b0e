"""Sequential scan of MCAP files and recovery of interrupted or damaged recordings.

A recorder killed with SIGKILL leaves an MCAP file without summary and footer, possibly ending in
the middle of a record. `scan_mcap` walks the records from the start, bounds-checking every
record length against the file size, decompresses and CRC-checks every chunk, and reports each
problem with its byte offset:
- a record that runs past the end of the file (truncation) ends the scan;
- a chunk whose framing is intact but whose data fails decompression or its CRC is skipped
  (its messages are lost) and the scan continues with the next record;
- an unknown opcode (garbage where a record should start) ends the scan.
`recover_bag` writes everything intact into a clean rosbag2 directory with metadata.yaml.
Importing this module does not import rclpy.
"""

from __future__ import annotations

import io
import mmap
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Header, Message, Schema
from mcap.stream_reader import breakup_chunk

from island_mapping.bag.errors import BagCorruptError, BagError
from island_mapping.bag.qos import qos_from_yaml
from island_mapping.bag.writer import BagWriter, Compression, WriterConfig

MCAP_MAGIC = b"\x89MCAP0\r\n"
RECORD_PREFIX_BYTES = 9  # opcode (1 byte) + record length (uint64)
_KNOWN_OPCODES = frozenset(int(o) for o in Opcode)


@dataclass(frozen=True)
class Damage:
    """One problem found in a file: byte offset of the record and what was wrong."""

    offset: int
    reason: str


@dataclass
class McapScan:
    """What a sequential scan of one MCAP file found."""

    path: Path
    profile: str = ""
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[Message] = field(default_factory=list)
    message_offsets: list[int] = field(default_factory=list)
    """File offset of the record (message or chunk) holding each message [bytes]."""
    damages: list[Damage] = field(default_factory=list)
    complete: bool = False
    """True when the data section ended properly (DataEnd or Footer record found)."""
    end_offset: int = 0
    """Offset where the scan stopped [bytes]."""

    def first_error(self) -> BagCorruptError | None:
        """The damage as an exception (None for a healthy, complete file)."""
        if self.damages:
            d = self.damages[0]
            return BagCorruptError(str(self.path), d.offset, d.reason, self._before(d.offset))
        if not self.complete:
            return BagCorruptError(
                str(self.path),
                self.end_offset,
                "file ends without data-end record, summary and footer (interrupted recording)",
                len(self.messages),
            )
        return None

    def _before(self, offset: int) -> int:
        return sum(1 for m in self.message_offsets if m < offset)


def _opcode_name(op: int) -> str:
    try:
        return Opcode(op).name
    except ValueError:
        return f"0x{op:02x}"


def scan_mcap(path: str | os.PathLike[str]) -> McapScan:
    """Read every intact record of an MCAP file in file order (see the module docstring)."""
    p = Path(path)
    try:
        size = p.stat().st_size
        fh = p.open("rb")
    except OSError as exc:
        raise BagError(f"cannot read {p}: {exc.strerror or exc}") from None
    scan = McapScan(p)
    with fh:
        if size < len(MCAP_MAGIC) or size == 0:
            scan.damages.append(Damage(0, f"file is {size} bytes, too short for an MCAP file"))
            return scan
        with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            if buf[: len(MCAP_MAGIC)] != MCAP_MAGIC:
                scan.damages.append(Damage(0, "not an MCAP file (bad magic bytes)"))
                return scan
            _scan_records(buf, size, scan)
    return scan


def _scan_records(buf: mmap.mmap, size: int, scan: McapScan) -> None:
    pos = len(MCAP_MAGIC)
    while True:
        scan.end_offset = pos
        if pos == size:
            return
        if size - pos < RECORD_PREFIX_BYTES:
            scan.damages.append(
                Damage(pos, f"truncated record header ({size - pos} of 9 bytes present)")
            )
            return
        op = buf[pos]
        (length,) = struct.unpack_from("<Q", buf, pos + 1)
        if op not in _KNOWN_OPCODES:
            scan.damages.append(Damage(pos, f"corrupted data: unknown record opcode 0x{op:02x}"))
            return
        body_start = pos + RECORD_PREFIX_BYTES
        if length > size - body_start:
            scan.damages.append(
                Damage(
                    pos,
                    f"truncated {_opcode_name(op)} record (needs {length} bytes, "
                    f"{size - body_start} left in the file)",
                )
            )
            return
        body = bytes(buf[body_start : body_start + length])
        stream = ReadDataStream(io.BytesIO(body))
        try:
            if op == Opcode.HEADER:
                scan.profile = Header.read(stream).profile
            elif op == Opcode.SCHEMA:
                s = Schema.read(stream)
                scan.schemas[s.id] = s
            elif op == Opcode.CHANNEL:
                c = Channel.read(stream)
                scan.channels[c.id] = c
            elif op == Opcode.MESSAGE:
                scan.messages.append(Message.read(stream, length))
                scan.message_offsets.append(pos)
            elif op == Opcode.CHUNK:
                _scan_chunk(Chunk.read(stream), pos, scan)
            elif op in (Opcode.DATA_END, Opcode.FOOTER):
                scan.complete = True
                scan.end_offset = pos
                return
        except Exception as exc:  # a record whose content cannot be parsed: corrupted bytes
            if op == Opcode.CHUNK:
                scan.damages.append(Damage(pos, f"corrupted Chunk record: {exc}"))
            else:
                scan.damages.append(Damage(pos, f"corrupted {_opcode_name(op)} record: {exc}"))
                return
        pos = body_start + length


def _scan_chunk(chunk: Chunk, pos: int, scan: McapScan) -> None:
    try:
        records = breakup_chunk(chunk, validate_crc=True)
    except Exception as exc:  # bad compression stream or CRC mismatch: skip this chunk
        scan.damages.append(Damage(pos, f"corrupted Chunk record ({type(exc).__name__}: {exc})"))
        return
    for rec in records:
        if isinstance(rec, Schema):
            scan.schemas[rec.id] = rec
        elif isinstance(rec, Channel):
            scan.channels[rec.id] = rec
        elif isinstance(rec, Message):
            scan.messages.append(rec)
            scan.message_offsets.append(pos)


def find_mcap_files(path: str | os.PathLike[str]) -> list[Path]:
    """The .mcap files of a bare file or a bag directory (metadata.yaml order when present)."""
    p = Path(path)
    if p.is_file():
        return [p]
    if not p.is_dir():
        raise BagError(f"{p} does not exist (expected a rosbag2 directory or an .mcap file)")
    files = sorted(p.glob("*.mcap"))
    if not files:
        raise BagError(f"{p} holds no .mcap file")
    return files


@dataclass(frozen=True)
class RecoverReport:
    """What `recover_bag` did."""

    out_dir: Path
    messages: int
    topics: dict[str, int]
    damages: list[Damage]
    complete: bool


def recover_bag(
    broken: str | os.PathLike[str],
    out_dir: str | os.PathLike[str] | None = None,
    compression: Compression | str = Compression.ZSTD,
) -> RecoverReport:
    """Write every intact message of `broken` (.mcap or bag directory) into a clean bag.

    The default output is `<name>_recovered` beside the input. Raises BagError when nothing in
    the file is usable (not an MCAP file, no channel).
    """
    files = find_mcap_files(broken)
    src = Path(broken)
    out = Path(out_dir) if out_dir is not None else src.with_name(f"{src.stem}_recovered")
    scans = [scan_mcap(f) for f in files]
    for s in scans:
        if s.damages and s.damages[0].offset == 0:
            raise BagError(f"{s.path}: {s.damages[0].reason}; nothing to recover")
    writer = BagWriter(out, compression=compression, config=WriterConfig())
    counts: dict[str, int] = {}
    try:
        for s in scans:
            for msg in _ordered(s):
                ch = s.channels.get(msg.channel_id)
                if ch is None:
                    continue  # a message whose channel record was lost: cannot be typed
                schema = s.schemas.get(ch.schema_id)
                if schema is None:
                    continue
                qos = qos_from_yaml(ch.metadata.get("offered_qos_profiles", ""))
                writer.add_topic(ch.topic, schema.name, qos)
                writer.write_raw(ch.topic, msg.data, msg.log_time)
                counts[ch.topic] = counts.get(ch.topic, 0) + 1
    finally:
        writer.close()
    damages = [d for s in scans for d in s.damages]
    return RecoverReport(
        out, sum(counts.values()), counts, damages, all(s.complete for s in scans)
    )


def _ordered(scan: McapScan) -> Iterator[Message]:
    return iter(sorted(scan.messages, key=lambda m: m.log_time))
