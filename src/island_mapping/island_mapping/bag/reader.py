"""Read rosbag2 directories (metadata.yaml + .mcap) or bare .mcap files.

`open_bag(path)` gives a BagReader with the topics (name, type, count, QoS), start/end times and
the messages in log-time order as CDR bytes; `BagMessage.deserialize()` turns one into the
installed rclpy message class. A truncated or corrupted file raises BagCorruptError naming the
file and byte offset; `open_bag(path, allow_damaged=True)` reads the intact part instead.
Importing this module does not import rclpy (deserialization imports it lazily).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from island_msgs_py.inputs import load_yaml, read_text
from mcap.reader import make_reader

from island_mapping.bag.errors import BagCorruptError, BagError
from island_mapping.bag.qos import QosDict, qos_from_yaml
from island_mapping.bag.recover import McapScan, scan_mcap
from island_mapping.bag.schema import full_type_name, message_class
from island_mapping.bag.writer import METADATA_FILE


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a recording."""

    name: str
    type_name: str
    message_count: int
    qos_profiles: list[QosDict] = field(default_factory=list)


@dataclass(frozen=True)
class BagMessage:
    """One recorded message: CDR bytes and its log time [ns]."""

    topic: str
    type_name: str
    log_time_ns: int
    data: bytes

    def deserialize(self) -> Any:
        """The message as an instance of the installed rclpy message class."""
        from rclpy.serialization import deserialize_message

        cls = message_class(self.type_name)
        try:
            return deserialize_message(self.data, cls)
        except Exception as exc:
            raise BagError(
                f"cannot deserialize a {self.type_name} message on {self.topic} at "
                f"{self.log_time_ns} ns: {exc}"
            ) from None


@dataclass
class _FileSource:
    path: Path
    topics: dict[str, TopicInfo]
    start_ns: int
    end_ns: int
    count: int
    scan: McapScan | None  # set when the file was read by a sequential scan (damaged)


class BagReader:
    """A recording opened for reading (see module docstring). Use `open_bag`."""

    def __init__(self, path: str | os.PathLike[str], allow_damaged: bool = False) -> None:
        self.path = Path(path)
        self.allow_damaged = allow_damaged
        self.metadata: dict[str, Any] | None = None
        self.damage: list[BagCorruptError] = []
        files = self._files()
        self._sources = [self._open_file(f) for f in files]
        self.topics: dict[str, TopicInfo] = {}
        for src in self._sources:
            for name, info in src.topics.items():
                prev = self.topics.get(name)
                if prev is None:
                    self.topics[name] = info
                else:
                    self.topics[name] = TopicInfo(
                        name, prev.type_name, prev.message_count + info.message_count,
                        prev.qos_profiles,
                    )
        counted = [s for s in self._sources if s.count]
        self.message_count = sum(s.count for s in self._sources)
        self.start_ns = min((s.start_ns for s in counted), default=0)
        self.end_ns = max((s.end_ns for s in counted), default=0)

    @property
    def duration_ns(self) -> int:
        return max(0, self.end_ns - self.start_ns)

    @property
    def files(self) -> list[Path]:
        return [s.path for s in self._sources]

    def _files(self) -> list[Path]:
        p = self.path
        if p.is_file():
            return [p]
        if not p.is_dir():
            raise BagError(f"{p} does not exist (expected a rosbag2 directory or an .mcap file)")
        meta_path = p / METADATA_FILE
        if meta_path.is_file():
            meta = load_yaml(read_text(meta_path, error=BagError, what="rosbag2 metadata"),
                             str(meta_path), BagError)
            try:
                info = meta["rosbag2_bagfile_information"]
                rel = [str(x) for x in info["relative_file_paths"]]
                storage = info.get("storage_identifier", "mcap")
            except (KeyError, TypeError, AttributeError) as exc:
                raise BagError(f"{meta_path}: not a rosbag2 metadata file ({exc})") from None
            if storage != "mcap":
                raise BagError(f"{meta_path}: storage {storage!r} is not supported (only mcap)")
            self.metadata = meta
            files = [p / Path(r).name for r in rel]
            missing = [str(f) for f in files if not f.is_file()]
            if missing:
                raise BagError(f"{meta_path} lists files that are missing: {missing}")
            return files
        files = sorted(p.glob("*.mcap"))
        if not files:
            raise BagError(f"{p} holds neither metadata.yaml nor an .mcap file")
        return files

    def _open_file(self, f: Path) -> _FileSource:
        try:
            with f.open("rb") as fh:
                summary = make_reader(fh).get_summary()
        except OSError as exc:
            raise BagError(f"cannot read {f}: {exc.strerror or exc}") from None
        except Exception:
            summary = None  # no footer/summary, or a damaged one: fall back to a scan
        if summary is None or summary.statistics is None:
            return self._scan_source(f)
        topics: dict[str, TopicInfo] = {}
        counts = summary.statistics.channel_message_counts
        for cid, ch in summary.channels.items():
            schema = summary.schemas.get(ch.schema_id)
            if schema is None:
                continue
            topics[ch.topic] = TopicInfo(
                ch.topic,
                full_type_name(schema.name),
                int(counts.get(cid, 0)),
                qos_from_yaml(ch.metadata.get("offered_qos_profiles", "")),
            )
        st = summary.statistics
        return _FileSource(f, topics, st.message_start_time, st.message_end_time,
                           st.message_count, None)

    def _scan_source(self, f: Path) -> _FileSource:
        scan = scan_mcap(f)
        err = scan.first_error()
        if err is not None:
            if not self.allow_damaged:
                raise err
            self.damage.append(err)
        counts: dict[int, int] = {}
        for m in scan.messages:
            counts[m.channel_id] = counts.get(m.channel_id, 0) + 1
        topics: dict[str, TopicInfo] = {}
        for cid, ch in scan.channels.items():
            schema = scan.schemas.get(ch.schema_id)
            if schema is None:
                continue
            topics[ch.topic] = TopicInfo(
                ch.topic, full_type_name(schema.name), counts.get(cid, 0),
                qos_from_yaml(ch.metadata.get("offered_qos_profiles", "")),
            )
        times = [m.log_time for m in scan.messages]
        return _FileSource(f, topics, min(times, default=0), max(times, default=0),
                           len(scan.messages), scan)

    def messages(
        self,
        topics: Iterable[str] | None = None,
        start_ns: int | None = None,
        end_ns: int | None = None,
    ) -> Iterator[BagMessage]:
        """Messages of the chosen topics (all when None) in log-time order, [start, end) ns."""
        wanted = set(topics) if topics is not None else None
        if wanted is not None:
            unknown = sorted(wanted - set(self.topics))
            if unknown:
                raise BagError(
                    f"{self.path} has no topic {', '.join(unknown)} "
                    f"(topics: {', '.join(sorted(self.topics))})"
                )
        for src in self._sources:
            if src.scan is not None:
                yield from self._scan_messages(src.scan, wanted, start_ns, end_ns)
            else:
                yield from self._indexed_messages(src, wanted, start_ns, end_ns)

    def _indexed_messages(
        self, src: _FileSource, wanted: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        with src.path.open("rb") as fh:
            reader = make_reader(fh, validate_crcs=True)
            it = reader.iter_messages(
                topics=sorted(wanted) if wanted is not None else None,
                starting_at=start_ns,
                ending_before=end_ns,
                log_time_order=True,
            )
            while True:
                try:
                    schema, channel, msg = next(it)
                except StopIteration:
                    return
                except Exception as exc:
                    # A chunk failed decompression or CRC: locate it by a sequential scan.
                    err = scan_mcap(src.path).first_error()
                    if err is None:
                        raise BagError(f"{src.path}: cannot read messages: {exc}") from None
                    if self.allow_damaged:
                        self.damage.append(err)
                        return
                    raise err from None
                if schema is None:
                    continue
                yield BagMessage(channel.topic, full_type_name(schema.name), msg.log_time,
                                 msg.data)

    def _scan_messages(
        self, scan: McapScan, wanted: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        for m in sorted(scan.messages, key=lambda m: m.log_time):
            ch = scan.channels.get(m.channel_id)
            if ch is None or (wanted is not None and ch.topic not in wanted):
                continue
            if (start_ns is not None and m.log_time < start_ns) or (
                end_ns is not None and m.log_time >= end_ns
            ):
                continue
            schema = scan.schemas.get(ch.schema_id)
            if schema is None:
                continue
            yield BagMessage(ch.topic, full_type_name(schema.name), m.log_time, m.data)


def open_bag(path: str | os.PathLike[str], allow_damaged: bool = False) -> BagReader:
    """Open a rosbag2 directory or a bare .mcap file for reading."""
    return BagReader(path, allow_damaged=allow_damaged)
