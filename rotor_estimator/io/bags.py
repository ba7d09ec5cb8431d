# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Rosbag2 (MCAP) bags: write and read a :class:`RigRecording`, stream messages, record outputs.

Input bags carry the estimator's input topics (see :mod:`msg_adapters.inputs`):
probe PointCloud2 blocks, one TimeReference per keyphasor pulse, and impact
PointCloud2 blocks only where the force is non-zero (absent = 0 N).

Log time convention: each message's log time is the time it would have been
published live, i.e. the stamp of the LAST sample it carries (a block's header
stamp is its FIRST sample's). Stamps round-trip exactly as integer ns.

Only the I/O layer imports rosbags; the numerical core never imports this module.
"""
from __future__ import annotations

import heapq
import json
import os
import shutil
import struct
import sys
import tempfile
import zlib
from pathlib import Path
from types import TracebackType
from typing import Any, Iterable, Iterator, Literal, NamedTuple

import numpy as np
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2 import ReaderError, WriterError
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.serde import SerdeError

from msg_adapters import (DEFAULT_INPUT_TOPICS, IMPACT_TYPES, PROBE_TYPES, PULSE_TYPES, InputTopics,
                          TypestoreFactory, default_typestore, impact_block_from_msg, impact_block_to_msg,
                          msg_typename, probe_block_from_msg, probe_block_to_msg, pulse_stamp_from_msg,
                          pulse_to_msg)

from rotor_estimator.core.errors import BagError, InputError
from rotor_estimator.core.recording import RigRecording

ROSBAG2_VERSION: Literal[9] = 9
META_KEY = "rotor_estimator.meta"
_RECOVER_HINT = ("if the recording was interrupted, recover it with `mcap recover IN.mcap -o OUT.mcap` "
                 "or `ros2 bag reindex`, otherwise re-record it")
# Whatever the bag library raises on damaged bytes (seen: OverflowError, struct.error, IndexError...)
# is a damaged bag, not a bug of ours: every read turns it into a BagError naming the bag.
_DECODE_ERRORS = (ReaderError, SerdeError, OSError, struct.error, ValueError, IndexError, KeyError, TypeError,
                  AssertionError, EOFError, UnicodeDecodeError, OverflowError, MemoryError, ArithmeticError)
CHUNK_BYTES = 64 * 1024  # MCAP chunk size we write: damage then costs ~0.1 s of a 4-probe 10 kHz record, not 1 MiB


class BagMessage(NamedTuple):
    """One message of a bag: topic, full type name, log time (ns) and the rosbags message object."""

    topic: str
    typename: str
    log_time_ns: int
    msg: Any


# --------------------------------------------------------------------------- writing
def _require_new(path: Path) -> None:
    if path.exists():
        raise BagError(f"bag {path} already exists; remove it or choose another output path")


class _CheckedMcapWriter(McapWriter):
    """rosbags' MCAP storage writer with CRCs and small chunks, so that readers (ours, ``mcap``,
    ``ros2 bag``) can detect and localize damage: each chunk's ``uncompressed_crc``, the DataEnd
    ``data_section_crc`` and the footer's ``summary_crc`` (MCAP spec), all left 0 by rosbags 0.11."""

    _CHUNK_CRC_OFFSET = 1 + 8 + 8 + 8 + 8  # opcode, record length, start time, end time, uncompressed size

    def close_chunk(self) -> None:
        records = self.chunk.bio.getvalue()
        start = self.bio.tell()
        super().close_chunk()
        end = self.bio.tell()
        self.bio.seek(start + self._CHUNK_CRC_OFFSET)
        self.bio.write(struct.pack("<I", zlib.crc32(records)))
        self.bio.seek(end)

    def write(self, connection: Any, timestamp: int, data: bytes | memoryview) -> None:
        super().write(connection, timestamp, data)
        if self.chunk.bio.tell() > CHUNK_BYTES:
            self.close_chunk()

    def close(self, version: int, metadata: str) -> None:
        super().close(version, metadata)
        _seal_mcap_crcs(self.path)


def _crc_of_range(f: Any, start: int, stop: int) -> int:
    crc = 0
    f.seek(start)
    while start < stop:
        piece = f.read(min(1 << 20, stop - start))
        crc = zlib.crc32(piece, crc)
        start += len(piece)
    return crc


def _seal_mcap_crcs(path: Path) -> None:
    """Fill the data-section and summary CRCs of a finished MCAP file written by rosbags
    (DataEnd sits right before the summary; the footer is the last record before the magic)."""
    with open(path, "r+b") as f:
        f.seek(0, os.SEEK_END)
        footer = f.tell() - 8 - 29
        f.seek(footer)
        opcode, _, summary_start, _ = struct.unpack("<BQQQ", f.read(25))
        if opcode != 0x02 or summary_start == 0:
            return
        data_end = summary_start - 13
        f.seek(data_end)
        if f.read(1) != b"\x0f":
            return
        data_crc = _crc_of_range(f, 0, data_end)
        f.seek(data_end + 9)
        f.write(struct.pack("<I", data_crc))
        summary_crc = _crc_of_range(f, summary_start, footer + 25)
        f.seek(footer + 25)
        f.write(struct.pack("<I", summary_crc))


class _Rosbag2Writer(Writer):
    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _CheckedMcapWriter}


class BagWriter:
    """A new MCAP rosbag2 bag at ``path``, written all-or-nothing.

    The bag is written into a hidden staging directory beside ``path`` and moved to ``path`` only by
    :meth:`close`; :meth:`abort` (called on any error or Ctrl-C by the ``with`` block and by every
    writer of this package) removes it. So an interrupted ``simulate --out`` or ``replay --out``
    leaves no normal-looking partial bag, and a rerun does not fail with "already exists".
    """

    def __init__(self, path: str | Path, meta: dict | None = None) -> None:
        self.path = Path(path)
        _require_new(self.path)
        try:
            self._staging: Path | None = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.partial-",
                                                               dir=self.path.parent))
        except OSError as exc:
            raise BagError(f"cannot create bag {self.path}: {exc.strerror or exc}") from exc
        self._writer = _Rosbag2Writer(self._staging / self.path.name, version=ROSBAG2_VERSION,
                                      storage_plugin=StoragePlugin.MCAP)
        if meta:
            self._writer.set_custom_data(META_KEY, json.dumps(meta, default=str, sort_keys=True))
        try:
            self._writer.open()
        except (WriterError, OSError) as exc:
            self.abort()
            raise BagError(f"cannot create bag {self.path}: {exc}") from exc

    def add_connection(self, topic: str, typename: str, **kwargs: Any) -> Any:
        return self._writer.add_connection(topic, typename, **kwargs)

    def write(self, connection: Any, log_time_ns: int, data: bytes | memoryview) -> None:
        self._writer.write(connection, log_time_ns, data)

    def close(self) -> Path:
        """Finish the bag and move it to ``path``."""
        if self._staging is None:
            return self.path
        try:
            self._writer.close()
            _require_new(self.path)
            os.rename(self._staging / self.path.name, self.path)
        except BaseException:
            self.abort()
            raise
        shutil.rmtree(self._staging, ignore_errors=True)
        self._staging = None
        return self.path

    def abort(self) -> None:
        """Drop everything written so far (nothing appears at ``path``)."""
        if self._staging is None:
            return
        storage = getattr(self._writer, "storage", None)
        if storage is not None:
            try:
                storage.abort()
            except Exception:  # already closed or never opened: the directory goes anyway
                pass
        shutil.rmtree(self._staging, ignore_errors=True)
        self._staging = None

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def _nonzero_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` index ranges where ``mask`` is True."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def tag_stream(topic: str, stream: Iterator[tuple[int, Any]]) -> Iterator[tuple[int, int, str, Any]]:
    """``(stamp_ns, index, topic, message)`` for each message of one topic: the key that heap-merges streams."""
    return ((t, k, topic, m) for k, (t, m) in enumerate(stream))


def write_input_bag(path: str | Path, recording: RigRecording, *, block_size: int = 200,
                    topics: InputTopics = DEFAULT_INPUT_TOPICS) -> Path:
    """Write ``recording`` as an MCAP rosbag2 bag (a new directory at ``path``); return ``path``.

    Probes go out as PointCloud2 blocks of ``block_size`` samples, pulses as
    TimeReference, impact force as PointCloud2 blocks covering its non-zero
    stretches only. ``recording.meta`` is stored as JSON in the bag's custom data.
    """
    path = Path(path)
    if block_size < 1:
        raise InputError(f"block_size must be >= 1, got {block_size}")
    if (len(recording) and recording.stamps_ns[0] < 0) or (recording.pulse_stamps_ns < 0).any():
        raise InputError("bag log times are unsigned: stamps_ns and pulse_stamps_ns must be >= 0 ns")
    ts = default_typestore()
    fac = TypestoreFactory(ts)
    stamps = recording.stamps_ns
    n = len(recording)

    def probe_msgs(cols: slice, frame_id: str) -> Iterator[tuple[int, Any]]:
        for i in range(0, n, block_size):
            j = min(i + block_size, n)
            yield int(stamps[j - 1]), probe_block_to_msg(fac, stamps[i:j], recording.probes_m[i:j, cols],
                                                         frame_id=frame_id)

    def pulse_msgs() -> Iterator[tuple[int, Any]]:
        for stamp_ns in np.sort(recording.pulse_stamps_ns).tolist():
            yield stamp_ns, pulse_to_msg(fac, stamp_ns)

    def impact_msgs() -> Iterator[tuple[int, Any]]:
        force = recording.impact_force_n
        for a, b in _nonzero_runs(np.any(force != 0.0, axis=1)):
            for i in range(a, b, block_size):
                j = min(i + block_size, b)
                yield int(stamps[j - 1]), impact_block_to_msg(fac, stamps[i:j], force[i:j])

    streams = {
        topics.probe1: ("sensor_msgs/msg/PointCloud2", probe_msgs(slice(0, 2), "probe1")),
        topics.probe2: ("sensor_msgs/msg/PointCloud2", probe_msgs(slice(2, 4), "probe2")),
        topics.keyphasor: ("sensor_msgs/msg/TimeReference", pulse_msgs()),
        topics.impact: ("sensor_msgs/msg/PointCloud2", impact_msgs()),
    }
    with BagWriter(path, recording.meta) as writer:
        conns = {topic: writer.add_connection(topic, typename, typestore=ts)
                 for topic, (typename, _) in streams.items()}
        tagged = [tag_stream(topic, gen) for topic, (_, gen) in streams.items()]
        for log_time_ns, _, topic, msg in heapq.merge(*tagged, key=lambda item: (item[0], item[1])):
            writer.write(conns[topic], log_time_ns, ts.serialize_cdr(msg, msg.__msgtype__))
    return path


class OutputBagWriter:
    """Context manager writing the estimator's output topics into a new MCAP rosbag2 bag.

    Build messages with :attr:`factory` and the ``msg_adapters`` encoders, e.g.
    ``w.write("/rotor_estimator/coefficients", coefficients_to_msg(w.factory, t, x, s), t)``.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.typestore = default_typestore()
        self.factory = TypestoreFactory(self.typestore)
        self._writer: BagWriter | None = None
        self._connections: dict[tuple[str, str], Any] = {}

    def open(self) -> "OutputBagWriter":
        self._writer = BagWriter(self.path)
        return self

    def write(self, topic: str, msg: Any, log_time_ns: int) -> None:
        """Append ``msg`` (a rosbags message from :attr:`factory`) on ``topic`` at ``log_time_ns``."""
        if self._writer is None:
            raise BagError("OutputBagWriter is not open; use it in a `with` block")
        typename = msg_typename(msg)
        if getattr(type(msg), "__msgtype__", None) != typename:
            raise InputError(f"OutputBagWriter.write needs a rosbags message built with .factory, got {typename}")
        key = (topic, typename)
        conn = self._connections.get(key)
        if conn is None:
            conn = self._writer.add_connection(topic, typename, typestore=self.typestore)
            self._connections[key] = conn
        if log_time_ns < 0:
            raise InputError(f"log_time_ns must be >= 0, got {log_time_ns}")
        self._writer.write(conn, int(log_time_ns), self.typestore.serialize_cdr(msg, typename))

    def close(self) -> None:
        """Finish the bag: only now does it appear at ``path``."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def abort(self) -> None:
        """Drop the bag (an interrupted or failed run leaves nothing that looks complete)."""
        if self._writer is not None:
            self._writer.abort()
            self._writer = None

    def __enter__(self) -> "OutputBagWriter":
        return self.open()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


# --------------------------------------------------------------------------- reading
def _resolve(path: str | Path) -> Path:
    p = Path(path)
    if not p.exists():
        raise BagError(f"bag {p} not found; pass a rosbag2 directory (with metadata.yaml) or its .mcap file")
    if p.is_dir() and not (p / "metadata.yaml").exists():
        mcaps = sorted(p.glob("*.mcap"))
        if len(mcaps) != 1:
            raise BagError(f"{p} is a directory without metadata.yaml and with {len(mcaps)} .mcap files; "
                           f"pass the .mcap file itself")
        p = mcaps[0]
    if p.is_file() and p.suffix not in (".mcap", ".db3"):
        raise BagError(f"{p} is not a bag: expected a rosbag2 directory or an .mcap (or .db3) file")
    return p


def _open_reader(path: str | Path) -> Reader:
    p = _resolve(path)
    try:
        reader = Reader(p)
        reader.open()
    except _DECODE_ERRORS as exc:
        raise BagError(f"cannot open bag {p}: it is truncated or corrupt ({exc}); {_RECOVER_HINT}") from exc
    return reader


def bag_topics(path: str | Path) -> dict[str, str]:
    """Topics of a bag mapped to their type name (``"<several>"`` if a topic has mixed types)."""
    reader = _open_reader(path)
    try:
        return {topic: info.msgtype or "<several>" for topic, info in reader.topics.items()}
    finally:
        reader.close()


def iter_bag_messages(path: str | Path, topics: Iterable[str] | None = None, *,
                      salvage: bool = False, warn: bool = True) -> Iterator[BagMessage]:
    """Yield the bag's messages on ``topics`` (all if None) in log-time order, deserialized.

    Topics absent from the bag are skipped (see :func:`bag_topics`). What was read is checked
    against the bag's own per-topic message counts (metadata.yaml / MCAP statistics) and chunk
    CRCs: a damaged, truncated or short bag raises :class:`BagError` naming the topics, the
    counts lost and the damaged time spans, possibly after some messages were yielded (so a
    command fails before it reports anything). With ``salvage=True`` a damaged MCAP bag is read
    chunk by chunk instead, every intact chunk is used, and a loud warning with the counts lost
    goes to stderr (``warn=False``: the caller has already warned, e.g. on a second pass).
    """
    if salvage:
        damage = bag_damage(path)
        if damage is not None:
            yield from _salvaged_messages(path, topics, damage, warn)
            return
    reader = _open_reader(path)
    ts = default_typestore()
    try:
        wanted = None if topics is None else set(topics)
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        for conn in conns:
            if conn.msgtype not in ts.types:
                raise BagError(f"topic {conn.topic} has type {conn.msgtype}, which is not a standard ROS 2 "
                               f"type; rotor_estimator reads standard types only")
        if not conns:
            return
        read = {c.id: 0 for c in conns}
        try:
            for conn, log_time_ns, raw in reader.messages(connections=conns):
                read[conn.id] += 1
                yield BagMessage(conn.topic, conn.msgtype, log_time_ns, ts.deserialize_cdr(raw, conn.msgtype))
        except _DECODE_ERRORS as exc:
            raise _damaged(path, f"{type(exc).__name__}: {exc}") from exc
        short = {c.topic: (read[c.id], c.msgcount) for c in conns if c.msgcount and read[c.id] != c.msgcount}
        if short:
            raise _damaged(path, "; ".join(f"{topic}: read {got} of the {want} messages its index lists"
                                           for topic, (got, want) in short.items()))
    finally:
        reader.close()


# --------------------------------------------------------------------------- damage
class BagDamage(NamedTuple):
    """Where an MCAP file is damaged: the chunks that fail (time span, in ns) and whether the
    summary (index) at the end could be read."""

    mcap_file: Path
    bad_chunks: tuple[tuple[int, int], ...]
    summary_readable: bool
    expected_counts: dict  # topic -> messages the bag's index lists (empty when unknown)
    start_ns: int          # first log time of the bag (the spans are given from it)
    index_damage: str = ""  # damage outside the chunks (message indexes, metadata), located

    def describe(self) -> str:
        spans = ", ".join(f"{(a - self.start_ns) * 1e-9:.3f}-{(b - self.start_ns) * 1e-9:.3f} s"
                          for a, b in self.bad_chunks[:5])
        more = f" and {len(self.bad_chunks) - 5} more" if len(self.bad_chunks) > 5 else ""
        parts = []
        if self.bad_chunks:
            parts.append(f"{len(self.bad_chunks)} damaged chunk(s) at {spans}{more} from the start")
        if self.index_damage:
            parts.append(self.index_damage)
        if not self.summary_readable:
            parts.append("the index at the end of the file is missing or damaged (truncated file?)")
        return "; ".join(parts)


def _damaged(path: str | Path, what: str) -> BagError:
    try:
        damage = bag_damage(path)
    except BagError:
        damage = None
    where = f"; {damage.describe()}" if damage is not None else ""
    return BagError(f"bag {path} is damaged ({what}){where}. Pass --salvage to use the intact part "
                    f"(the messages lost are counted and reported), or {_RECOVER_HINT}")


def _mcap_file(path: str | Path) -> Path | None:
    p = _resolve(path)
    if p.is_dir():
        files = sorted(p.glob("*.mcap"))
        return files[0] if len(files) == 1 else None
    return p if p.suffix == ".mcap" else None


def _expected_counts(path: str | Path) -> tuple[dict, int]:
    """Per-topic message counts and first log time (ns) the bag's metadata.yaml states."""
    p = _resolve(path)
    meta_file = p / "metadata.yaml" if p.is_dir() else p.parent / "metadata.yaml"
    try:
        import yaml

        info = yaml.safe_load(meta_file.read_text())["rosbag2_bagfile_information"]
        counts: dict = {}
        for entry in info.get("topics_with_message_count") or []:
            topic = entry["topic_metadata"]["name"]
            counts[topic] = counts.get(topic, 0) + int(entry["message_count"])
        return counts, int(info["starting_time"]["nanoseconds_since_epoch"])
    except Exception:  # no or unreadable metadata.yaml: counts unknown, not an error of its own
        return {}, 0


def _chunks_from_summary(f: Any, size: int, definitions: dict | None = None) -> list | None:
    """The chunk index records of an MCAP file, or None when its footer/summary is unreadable.
    ``definitions`` (if given) receives the summary's Schema and Channel records by id."""
    from mcap.records import Channel, ChunkIndex, Schema
    from mcap.data_stream import ReadDataStream
    import io

    try:
        footer = size - 8 - 29
        f.seek(footer)
        opcode, _, summary_start, _, summary_crc = struct.unpack("<BQQQI", f.read(29))
        if opcode != 0x02 or not 0 < summary_start < footer:
            return None
        if summary_crc and _crc_of_range(f, summary_start, footer + 25) != summary_crc:
            return None
        f.seek(summary_start)
        section = f.read(footer - summary_start)
        stream = ReadDataStream(io.BytesIO(section))
        chunks = []
        while stream.count < len(section):
            op = stream.read1()
            length = stream.read8()
            if op == 0 or op > 0x10 or stream.count + length > len(section):
                return None  # zeroed or garbled summary (a CRC-less file)
            if op == 0x08:
                chunks.append(ChunkIndex.read(stream))
            elif op == 0x03 and definitions is not None:
                schema = Schema.read(stream)
                definitions[("schema", schema.id)] = schema
            elif op == 0x04 and definitions is not None:
                channel = Channel.read(stream)
                definitions[("channel", channel.id)] = channel
            else:
                stream.read(length)
        return chunks
    except Exception:
        return None


def _read_chunk(f: Any, offset: int, size: int, ci: Any = None) -> Any:
    """The Chunk record at ``offset`` with its records, or None when it is damaged (CRC, structure,
    or a header that disagrees with its index entry ``ci``)."""
    from mcap.records import Chunk
    from mcap.stream_reader import breakup_chunk
    from mcap.data_stream import ReadDataStream
    import io

    try:
        f.seek(offset)
        op, length = struct.unpack("<BQ", f.read(9))
        if op != 0x06 or offset + 9 + length > size:
            return None
        chunk = Chunk.read(ReadDataStream(io.BytesIO(f.read(length))))
        if ci is not None and (chunk.message_start_time, chunk.message_end_time, chunk.uncompressed_size,
                               len(chunk.data)) != (ci.message_start_time, ci.message_end_time,
                                                    ci.uncompressed_size, ci.compressed_size):
            return None
        return chunk, breakup_chunk(chunk, validate_crc=True)
    except Exception:
        return None


def _walk_chunks(f: Any, size: int) -> Iterator[tuple[int, Any]]:
    """(offset, parsed-or-None) of each chunk: from the summary's index when it is readable,
    else by walking the records from the start until the first unreadable one."""
    index = _chunks_from_summary(f, size)
    if index is not None:
        for ci in index:
            yield ci.chunk_start_offset, (ci, _read_chunk(f, ci.chunk_start_offset, size, ci))
        return
    offset = 8
    while offset + 9 <= size:
        f.seek(offset)
        op, length = struct.unpack("<BQ", f.read(9))
        if op == 0 or op > 0x10 or offset + 9 + length > size:
            return
        if op == 0x06:
            yield offset, (None, _read_chunk(f, offset, size))
        offset += 9 + length


def bag_damage(path: str | Path) -> BagDamage | None:
    """Check an MCAP bag's chunks (CRC where written, structure always) and its index; None when
    intact. Reads the file once; no message is deserialized."""
    mcap_path = _mcap_file(path)
    if mcap_path is None:
        return None  # SQLite3 bags: the database checks itself
    size = mcap_path.stat().st_size
    bad = []
    with open(mcap_path, "rb") as f:
        index = _chunks_from_summary(f, size)
        for _, (ci, parsed) in _walk_chunks(f, size):
            if parsed is None:
                bad.append((ci.message_start_time, ci.message_end_time) if ci is not None else (0, 0))
        index_damage = _damage_between_chunks(f, size, index) if index is not None and not bad else None
    if not bad and index is not None and index_damage is None:
        return None
    counts, start_ns = _expected_counts(path)
    starts = [a for a, _ in bad if a]
    start_ns = start_ns or (min(starts) if starts else 0)
    where = ""
    if index_damage is not None:
        offset, ci = index_damage
        where = (f"damaged records at byte {offset}" + (
            f", after the chunk of {(ci.message_start_time - start_ns) * 1e-9:.3f}-"
            f"{(ci.message_end_time - start_ns) * 1e-9:.3f} s (its message index)" if ci is not None else ""))
    return BagDamage(mcap_path, tuple(bad), index is not None, counts, start_ns, where)


def _damage_between_chunks(f: Any, size: int, index: list) -> tuple[int, Any] | None:
    """Where the data section's CRC (when written) fails outside the chunks: the first record whose
    header is implausible, with the chunk it follows. None when the CRC holds or is not written."""
    f.seek(size - 8 - 29 + 1 + 8)
    summary_start = struct.unpack("<Q", f.read(8))[0]
    data_end = summary_start - 13
    f.seek(data_end)
    if f.read(1) != b"\x0f":
        return (data_end, None)
    crc = struct.unpack("<I", f.read(12)[8:12])[0]
    if crc == 0 or _crc_of_range(f, 0, data_end) == crc:
        return None
    offset = 8
    while offset < data_end:
        f.seek(offset)
        op, length = struct.unpack("<BQ", f.read(9))
        if op == 0 or op > 0x10 or offset + 9 + length > data_end:
            break
        offset += 9 + length
    before = [ci for ci in index if ci.chunk_start_offset < offset]
    return offset, (max(before, key=lambda ci: ci.chunk_start_offset) if before else None)


def _salvaged_messages(path: str | Path, topics: Iterable[str] | None, damage: BagDamage,
                       warn: bool = True) -> Iterator[BagMessage]:
    """Every message of the intact chunks, in log-time order, with a loud warning of what is lost."""
    from mcap.records import Channel, Message, Schema

    ts = default_typestore()
    wanted = None if topics is None else set(topics)
    size = damage.mcap_file.stat().st_size
    channels: dict[int, Any] = {}
    schemas: dict[int, str] = {}
    messages = []
    with open(damage.mcap_file, "rb") as f:
        definitions: dict = {}
        _chunks_from_summary(f, size, definitions)  # channels survive a damaged first chunk
        for (kind, key), rec in definitions.items():
            if kind == "schema":
                schemas[key] = rec.name
            else:
                channels[key] = rec
        for _, (_, parsed) in _walk_chunks(f, size):
            if parsed is None:
                continue
            for rec in parsed[1]:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec.name
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Message):
                    messages.append((rec.log_time, rec.channel_id, rec.sequence, rec.data))
    messages.sort(key=lambda m: (m[0], m[1]))
    read: dict[str, int] = {}
    out = []
    for log_time_ns, cid, _, data in messages:
        channel = channels.get(cid)
        if channel is None or (wanted is not None and channel.topic not in wanted):
            continue
        typename = schemas.get(channel.schema_id, "")
        if typename not in ts.types:
            continue
        try:
            msg = ts.deserialize_cdr(data, typename)
        except _DECODE_ERRORS:
            continue
        read[channel.topic] = read.get(channel.topic, 0) + 1
        out.append(BagMessage(channel.topic, typename, log_time_ns, msg))
    lost = {t: (read.get(t, 0), n) for t, n in damage.expected_counts.items()
            if (wanted is None or t in wanted) and read.get(t, 0) != n}
    counts = "; ".join(f"{t}: {got} of {n} messages read" for t, (got, n) in lost.items())
    if not counts:
        counts = ("every message the index lists was recovered (the damage lies outside the messages)"
                  if damage.expected_counts else "per-topic counts unknown (no readable index)")
    if warn:
        print(f"rotor-estimator: WARNING: bag {path} is damaged ({damage.describe()}); --salvage: using the intact "
              f"chunks only; {counts}. Results describe the salvaged data, not the whole recording.",
              file=sys.stderr)
    yield from out


def _check_topics(available: dict[str, set[str]], topics: InputTopics) -> None:
    required = {topics.probe1: PROBE_TYPES, topics.probe2: PROBE_TYPES, topics.keyphasor: PULSE_TYPES}
    optional = {topics.impact: IMPACT_TYPES}
    missing = [t for t in required if t not in available]
    if missing:
        raise BagError(f"bag lacks input topic(s) {missing}; it has {sorted(available)}. "
                       f"Pass topics=InputTopics(...) (or the CLI's topic options) if they were renamed")
    for topic, allowed in {**required, **optional}.items():
        wrong = available.get(topic, set()) - set(allowed)
        if wrong:
            raise BagError(f"topic {topic} has type {sorted(wrong)}, expected {' or '.join(allowed)}")


def _sorted_unique(stamps: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(stamps, kind="stable")
    stamps, values = stamps[order], values[order]
    keep = np.concatenate(([True], np.diff(stamps) != 0)) if stamps.size else np.zeros(0, bool)
    return stamps[keep], values[keep]


def _concat(blocks: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    if not blocks:
        return np.zeros(0, np.int64), np.zeros((0, 2))
    return np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks])


def _stored_meta(path: str | Path) -> dict:
    p = Path(path)
    meta_file = p / "metadata.yaml" if p.is_dir() else None
    if meta_file is None or not meta_file.exists():
        return {}
    try:
        import yaml
        info = yaml.safe_load(meta_file.read_text()).get("rosbag2_bagfile_information", {})
        return json.loads((info.get("custom_data") or {}).get(META_KEY, "{}"))
    except Exception:  # provenance only: never fail a read over it
        return {}


def read_input_bag(path: str | Path, topics: InputTopics = DEFAULT_INPUT_TOPICS, *,
                   salvage: bool = False) -> RigRecording:
    """Decode a bag's input topics into a :class:`RigRecording` (exact, integer-ns stamps).

    Samples are sorted by stamp (duplicates dropped); only stamps present on both
    probes are kept (the count dropped goes to ``meta['unpaired_probe_samples']``).
    Impact samples are held from their stamp: each is assigned to the probe sample
    interval it falls in; no impact message means 0 N. A damaged bag is an error unless
    ``salvage`` (see :func:`iter_bag_messages`); ``meta['salvaged']`` then says so.
    """
    damage = bag_damage(path) if salvage else None
    if damage is None:
        reader = _open_reader(path)
        try:
            available: dict[str, set[str]] = {}
            for conn in reader.connections:
                available.setdefault(conn.topic, set()).add(conn.msgtype)
        finally:
            reader.close()
        _check_topics(available, topics)

    probe1: list = []
    probe2: list = []
    impact: list = []
    pulses: list[int] = []
    for m in iter_bag_messages(path, [topics.probe1, topics.probe2, topics.keyphasor, topics.impact],
                               salvage=salvage):
        try:
            if m.topic == topics.probe1:
                probe1.append(probe_block_from_msg(m.msg))
            elif m.topic == topics.probe2:
                probe2.append(probe_block_from_msg(m.msg))
            elif m.topic == topics.keyphasor:
                pulses.append(pulse_stamp_from_msg(m.msg))
            else:
                impact.append(impact_block_from_msg(m.msg))
        except InputError as exc:
            raise BagError(f"bag {path}, topic {m.topic} at log time {m.log_time_ns} ns: {exc}") from exc

    s1, xy1 = _sorted_unique(*_concat(probe1))
    s2, xy2 = _sorted_unique(*_concat(probe2))
    stamps, i1, i2 = np.intersect1d(s1, s2, assume_unique=True, return_indices=True)
    if stamps.size == 0:
        raise BagError(f"bag {path}: no probe sample has the same stamp on {topics.probe1} and {topics.probe2} "
                       f"({s1.size} and {s2.size} samples); both planes must be sampled simultaneously")
    probes = np.hstack((xy1[i1], xy2[i2]))
    force = np.zeros((stamps.size, 2))
    fs, fv = _sorted_unique(*_concat(impact))
    idx = np.searchsorted(stamps, fs, side="right") - 1
    last = np.concatenate((idx[1:] != idx[:-1], [True])) if idx.size else np.zeros(0, bool)
    keep = (idx >= 0) & last  # idx is sorted: keep the last force sample of each probe interval
    force[idx[keep]] = fv[keep]
    meta = _stored_meta(path) or {"source_bag": str(path)}
    if damage is not None:
        meta["salvaged"] = damage.describe()
    unpaired = s1.size + s2.size - 2 * stamps.size
    if unpaired:
        meta["unpaired_probe_samples"] = int(unpaired)
    return RigRecording(stamps, probes, np.unique(np.asarray(pulses, dtype=np.int64)), force, meta)
