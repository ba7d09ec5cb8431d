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
import struct
from pathlib import Path
from types import TracebackType
from typing import Any, Iterable, Iterator, NamedTuple

import numpy as np
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2 import ReaderError, WriterError
from rosbags.serde import SerdeError

from msg_adapters import (DEFAULT_INPUT_TOPICS, IMPACT_TYPES, PROBE_TYPES, PULSE_TYPES, InputTopics,
                          TypestoreFactory, default_typestore, impact_block_from_msg, impact_block_to_msg,
                          msg_typename, probe_block_from_msg, probe_block_to_msg, pulse_stamp_from_msg,
                          pulse_to_msg)

from .errors import BagError, InputError
from .recording import RigRecording

ROSBAG2_VERSION = 9
META_KEY = "rotor_estimator.meta"
_RECOVER_HINT = ("if the recording was interrupted, recover it with `mcap recover IN.mcap -o OUT.mcap` "
                 "or `ros2 bag reindex`, otherwise re-record it")
_DECODE_ERRORS = (ReaderError, SerdeError, OSError, struct.error, ValueError, IndexError, KeyError, TypeError,
                  AssertionError, EOFError, UnicodeDecodeError)


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


def _open_writer(path: Path, meta: dict | None = None) -> Writer:
    _require_new(path)
    writer = Writer(path, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP)
    if meta:
        writer.set_custom_data(META_KEY, json.dumps(meta, default=str, sort_keys=True))
    try:
        writer.open()
    except (WriterError, OSError) as exc:
        raise BagError(f"cannot create bag {path}: {exc}") from exc
    return writer


def _nonzero_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` index ranges where ``mask`` is True."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def _tag(topic: str, stream: Iterator[tuple[int, Any]]) -> Iterator[tuple[int, int, str, Any]]:
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
    writer = _open_writer(path, recording.meta)
    try:
        conns = {topic: writer.add_connection(topic, typename, typestore=ts)
                 for topic, (typename, _) in streams.items()}
        tagged = [_tag(topic, gen) for topic, (_, gen) in streams.items()]
        for log_time_ns, _, topic, msg in heapq.merge(*tagged, key=lambda item: (item[0], item[1])):
            writer.write(conns[topic], log_time_ns, ts.serialize_cdr(msg, msg.__msgtype__))
    finally:
        writer.close()
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
        self._writer: Writer | None = None
        self._connections: dict[tuple[str, str], Any] = {}

    def open(self) -> "OutputBagWriter":
        self._writer = _open_writer(self.path)
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
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> "OutputBagWriter":
        return self.open()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()  # also on error, so what was written stays readable


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


def iter_bag_messages(path: str | Path, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
    """Yield the bag's messages on ``topics`` (all if None) in log-time order, deserialized.

    Topics absent from the bag are skipped (see :func:`bag_topics`). A truncated or
    corrupt bag raises :class:`BagError`, possibly after some messages were yielded.
    """
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
        try:
            for conn, log_time_ns, raw in reader.messages(connections=conns):
                yield BagMessage(conn.topic, conn.msgtype, log_time_ns, ts.deserialize_cdr(raw, conn.msgtype))
        except _DECODE_ERRORS as exc:
            raise BagError(f"bag {path} is truncated or corrupt ({type(exc).__name__}: {exc}); "
                           f"{_RECOVER_HINT}") from exc
    finally:
        reader.close()


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


def read_input_bag(path: str | Path, topics: InputTopics = DEFAULT_INPUT_TOPICS) -> RigRecording:
    """Decode a bag's input topics into a :class:`RigRecording` (exact, integer-ns stamps).

    Samples are sorted by stamp (duplicates dropped); only stamps present on both
    probes are kept (the count dropped goes to ``meta['unpaired_probe_samples']``).
    Impact samples are held from their stamp: each is assigned to the probe sample
    interval it falls in; no impact message means 0 N.
    """
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
    for m in iter_bag_messages(path, [topics.probe1, topics.probe2, topics.keyphasor, topics.impact]):
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
    unpaired = s1.size + s2.size - 2 * stamps.size
    if unpaired:
        meta["unpaired_probe_samples"] = int(unpaired)
    return RigRecording(stamps, probes, np.unique(np.asarray(pulses, dtype=np.int64)), force, meta)
