"""Write rosbag2-compatible MCAP recordings: a directory with `<name>_0.mcap` and metadata.yaml.

MCAP profile `ros2`, schemas `ros2msg` (schema.py), channels `cdr` with rosbag2's channel metadata
(`offered_qos_profiles` YAML text, `topic_type_hash`), chunked with zstd/lz4/no compression.
log_time = publish_time = the message's sim-time stamp in ns: the leading header stamp (or the
Clock's time) when the type starts with one (a zero stamp counts only while the clock is at 0),
else the latest /clock time seen.

Crash safety: every finished chunk goes straight to the operating system (no Python-side
buffering), and a chunk is finished once it holds `chunk_size_bytes` or spans
`max_chunk_duration_s` of log time, so a recorder killed with SIGKILL leaves at most that much
unwritten; `islands bag recover` restores the rest. metadata.yaml is written atomically on close.
Importing this module does not import rclpy (serialization of message objects imports it lazily).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from types import TracebackType
from typing import Any

import yaml
from mcap.writer import CompressionType, Writer

from island_mapping.bag.errors import BagError
from island_mapping.bag.qos import QosDict, default_qos, qos_to_yaml
from island_mapping.bag.schema import (
    full_type_name,
    schema_text,
    stamp_is_first_field,
    stamp_ns_from_cdr,
    type_description_hash,
    type_name_of,
)

ROSBAG2_VERSION = 9
"""metadata.yaml version written by rosbag2 in Jazzy."""
ROS_DISTRO = "jazzy"
CLOCK_TOPIC = "/clock"
METADATA_FILE = "metadata.yaml"
FILE_MODE = 0o644
"""Permissions of written files (rw-r--r--, like any file a tool writes)."""


class Compression(StrEnum):
    """Chunk compression inside the MCAP file."""

    ZSTD = "zstd"
    LZ4 = "lz4"
    NONE = "none"


_MCAP_COMPRESSION = {
    Compression.ZSTD: CompressionType.ZSTD,
    Compression.LZ4: CompressionType.LZ4,
    Compression.NONE: CompressionType.NONE,
}


@dataclass(frozen=True)
class WriterConfig:
    """How a recording is written (the single source of the recorder's defaults)."""

    compression: Compression = field(
        default=Compression.ZSTD,
        metadata={"help": "chunk compression: zstd, lz4 or none"},
    )
    chunk_size_bytes: int = field(
        default=1024 * 1024,
        metadata={"help": "finish a chunk once its uncompressed messages exceed this [bytes]"},
    )
    max_chunk_duration_s: float = field(
        default=2.0,
        metadata={
            "help": "finish a chunk once it spans this much log (sim) time, bounding what a "
            "killed recorder loses [s]"
        },
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "compression", Compression(self.compression))
        if self.chunk_size_bytes <= 0:
            raise BagError(f"chunk_size_bytes must be positive, got {self.chunk_size_bytes}")
        if not self.max_chunk_duration_s > 0:
            raise BagError(
                f"max_chunk_duration_s must be positive, got {self.max_chunk_duration_s}"
            )


class _DirectFile:
    """A write-only file whose writes go straight to the OS (survive SIGKILL of the writer).

    Deliberately not an io.RawIOBase, which mcap's Writer would wrap in a buffer: a plain object
    with write/tell/flush/close.
    """

    def __init__(self, path: Path) -> None:
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, FILE_MODE)
        self._pos = 0

    def write(self, data: Any) -> int:
        view = memoryview(data).cast("B")
        done = 0
        while done < len(view):
            done += os.write(self._fd, view[done:])
        self._pos += done
        return done

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        return None

    def fsync(self) -> None:
        os.fsync(self._fd)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


@dataclass
class TopicRecord:
    """One recorded topic: its channel and how many messages it got."""

    topic: str
    type_name: str
    qos_profiles: list[QosDict]
    channel_id: int
    message_count: int = 0
    stamp_first: bool = False


def write_text_atomic(path: Path, text: str) -> None:
    """Write `text` to `path` via a temporary file in the same directory and os.replace."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.chmod(tmp, FILE_MODE)  # mkstemp's 0600 would make the bag unreadable to others
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def bag_metadata(
    file_names: list[str],
    topics: list[TopicRecord],
    start_ns: int,
    end_ns: int,
) -> dict[str, Any]:
    """rosbag2's metadata.yaml content (version 9) for one-file bags."""
    count = sum(t.message_count for t in topics)
    duration = max(0, end_ns - start_ns) if count else 0
    start = start_ns if count else 0
    return {
        "rosbag2_bagfile_information": {
            "version": ROSBAG2_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": t.topic,
                        "type": t.type_name,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": t.qos_profiles,
                        "type_description_hash": type_description_hash(t.type_name),
                    },
                    "message_count": t.message_count,
                }
                for t in topics
            ],
            # Compression is MCAP chunk compression inside the storage file (like rosbag2's
            # mcap storage presets), not rosbag2's file/message compression: both stay empty.
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": list(file_names),
            "files": [
                {
                    "path": name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": count,
                }
                for name in file_names
            ],
            "custom_data": None,
            "ros_distro": ROS_DISTRO,
        }
    }


class BagWriter:
    """A rosbag2 directory recording: `BagWriter(out_dir).write(topic, msg)`, then `close()`.

    `out_dir` must not exist or be empty. Messages are rclpy message objects or CDR bytes of a
    topic added with `add_topic`.
    """

    def __init__(
        self,
        path_dir: str | os.PathLike[str],
        compression: Compression | str = Compression.ZSTD,
        chunk_size: int | None = None,
        config: WriterConfig | None = None,
    ) -> None:
        base = config or WriterConfig()
        try:
            comp = Compression(compression)
        except ValueError:
            choices = ", ".join(c.value for c in Compression)
            raise BagError(f"unknown compression {compression!r}; use one of {choices}") from None
        self.config = WriterConfig(
            compression=comp,
            chunk_size_bytes=chunk_size if chunk_size is not None else base.chunk_size_bytes,
            max_chunk_duration_s=base.max_chunk_duration_s,
        )
        self.path = Path(path_dir)
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            raise BagError(f"output {self.path} already exists and is not an empty directory")
        self.path.mkdir(parents=True, exist_ok=True)
        self.file_name = f"{self.path.name or 'bag'}_0.mcap"
        self.mcap_path = self.path / self.file_name
        self._file = _DirectFile(self.mcap_path)
        self._writer = Writer(
            self._file,  # type: ignore[arg-type]
            chunk_size=self.config.chunk_size_bytes,
            compression=_MCAP_COMPRESSION[self.config.compression],
        )
        self._writer.start(profile="ros2", library="island_mapping.bag")
        self._topics: dict[str, TopicRecord] = {}
        self._schemas: dict[str, int] = {}
        self._latest_clock_ns: int | None = None
        self._last_log_ns = 0
        self._start_ns: int | None = None
        self._end_ns: int | None = None
        self._chunk_start_ns: int | None = None
        self._max_chunk_ns = int(self.config.max_chunk_duration_s * 1e9)
        self._sequence = 0
        self.closed = False

    # -- topics ---------------------------------------------------------------------------------
    def add_topic(
        self, topic: str, type_name: str, qos_profiles: list[QosDict] | None = None
    ) -> TopicRecord:
        """Register a topic (idempotent for the same type; a different type is an error)."""
        self._check_open()
        if not topic.startswith("/"):
            raise BagError(f"topic name {topic!r} must be absolute (start with '/')")
        tname = full_type_name(type_name)
        existing = self._topics.get(topic)
        if existing is not None:
            if existing.type_name != tname:
                raise BagError(
                    f"topic {topic} is recorded as {existing.type_name}, cannot add {tname}"
                )
            return existing
        schema_id = self._schemas.get(tname)
        if schema_id is None:
            schema_id = self._writer.register_schema(
                name=tname, encoding="ros2msg", data=schema_text(tname).encode("utf-8")
            )
            self._schemas[tname] = schema_id
        profiles = list(qos_profiles) if qos_profiles else [default_qos()]
        channel_id = self._writer.register_channel(
            topic=topic,
            message_encoding="cdr",
            schema_id=schema_id,
            metadata={
                "offered_qos_profiles": qos_to_yaml(profiles),
                "topic_type_hash": type_description_hash(tname),
            },
        )
        rec = TopicRecord(
            topic, tname, profiles, channel_id, stamp_first=stamp_is_first_field(tname)
        )
        self._topics[topic] = rec
        return rec

    @property
    def topics(self) -> dict[str, TopicRecord]:
        return dict(self._topics)

    @property
    def message_count(self) -> int:
        return sum(t.message_count for t in self._topics.values())

    @property
    def latest_clock_ns(self) -> int | None:
        return self._latest_clock_ns

    def observe_clock(self, clock_ns: int) -> None:
        """Tell the writer the current sim time (for stamp-less messages) [ns]."""
        self._latest_clock_ns = int(clock_ns)

    # -- messages -------------------------------------------------------------------------------
    def write(self, topic: str, msg: Any, log_time_ns: int | None = None) -> int:
        """Record an rclpy message (its type registers the topic). Returns the log time [ns]."""
        from rclpy.serialization import serialize_message

        if topic not in self._topics:
            self.add_topic(topic, type_name_of(msg))
        return self.write_raw(topic, serialize_message(msg), log_time_ns)

    def write_raw(self, topic: str, data: bytes, log_time_ns: int | None = None) -> int:
        """Record CDR bytes on an added topic. Returns the log time used [ns]."""
        self._check_open()
        rec = self._topics.get(topic)
        if rec is None:
            raise BagError(f"topic {topic} was not added (call add_topic first)")
        if len(data) < 4:
            raise BagError(f"CDR payload for {topic} is {len(data)} bytes, shorter than 4")
        stamp = stamp_ns_from_cdr(data) if rec.stamp_first else None
        if topic == CLOCK_TOPIC and stamp is not None:
            self._latest_clock_ns = stamp
        if log_time_ns is None:
            # A zero stamp is "unset" once the clock has moved on, but real at sim time 0.
            if stamp is not None and (stamp != 0 or not self._latest_clock_ns):
                log_time_ns = stamp
            elif self._latest_clock_ns is not None:
                log_time_ns = self._latest_clock_ns
            else:
                log_time_ns = self._last_log_ns
        t = int(log_time_ns)
        if t < 0:
            raise BagError(f"negative log time {t} ns on {topic}")
        if self._chunk_start_ns is not None and abs(t - self._chunk_start_ns) >= self._max_chunk_ns:
            self._writer.flush()
            self._chunk_start_ns = None
        if self._chunk_start_ns is None:
            self._chunk_start_ns = t
        self._writer.add_message(
            channel_id=rec.channel_id,
            log_time=t,
            data=bytes(data),
            publish_time=t,
            sequence=self._sequence,
        )
        self._sequence += 1
        rec.message_count += 1
        self._last_log_ns = t
        self._start_ns = t if self._start_ns is None else min(self._start_ns, t)
        self._end_ns = t if self._end_ns is None else max(self._end_ns, t)
        return t

    def flush(self) -> None:
        """Finish the chunk in progress so that it is on disk (recoverable after a crash)."""
        self._check_open()
        self._writer.flush()
        self._chunk_start_ns = None

    # -- closing --------------------------------------------------------------------------------
    def metadata(self) -> dict[str, Any]:
        return bag_metadata(
            [self.file_name],
            list(self._topics.values()),
            self._start_ns or 0,
            self._end_ns or 0,
        )

    def close(self) -> None:
        """Write the MCAP summary and footer, then metadata.yaml (atomically). Idempotent."""
        if self.closed:
            return
        meta = self.metadata()
        self._writer.add_metadata(
            "rosbag2",
            {"serialized_metadata": yaml.safe_dump(
                meta["rosbag2_bagfile_information"], sort_keys=False
            )},
        )
        self._writer.finish()
        self._file.fsync()
        self._file.close()
        self.closed = True
        write_text_atomic(self.path / METADATA_FILE, yaml.safe_dump(meta, sort_keys=False))

    def _check_open(self) -> None:
        if self.closed:
            raise BagError(f"bag {self.path} is closed")

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
