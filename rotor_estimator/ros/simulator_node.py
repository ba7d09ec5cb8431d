# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``simulator_node``: publishes the estimator's input topics from the model or from a bag.

* ``mode: simulate`` (default): simulates the rig (default: the bundled seed rig, the paper's
  imbalance+impact scenario) and publishes probe blocks (PointCloud2, ``block_size`` samples)
  or one PointStamped per sample, one TimeReference per keyphasor pulse and the impact force
  (PointCloud2 blocks where it is non-zero), each when its last sample is due: in real time
  times ``rate_factor``. ``repeat`` publishes the recording again and again with continuing
  stamps (the motion has a seam at each repetition); ``impact_period_s`` adds a hammer
  impact every that many seconds to long scenarios.
* ``mode: replay``: publishes the input topics of a recorded MCAP bag (``bag_path``) at
  their log times times ``rate_factor``, from ``start_offset_s``, optionally in a ``loop``.

Stamps are shifted so that the first sample is stamped with the node's clock at start
(``restamp``); relative timing is exact (integer ns).
"""
from __future__ import annotations

import bisect
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

import msg_adapters as ma

from rotor_estimator.ros.params import ParamSpec, declare_parameters
from rotor_estimator.ros.spin import run_node
from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.errors import ConfigError
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.core.simulator import Impact, paper_scenario, simulate


@dataclass(frozen=True)
class Event:
    """Something to publish ``due_ns`` after the start (relative, ns), built by ``make(shift_ns)``."""

    due_ns: int
    stream: str
    make: Callable[[int], Any]


_PARAMS: tuple[tuple[str, Any, str, float | None, float | None], ...] = (
    ("mode", "simulate", "simulate (from the model) or replay (a recorded MCAP bag)", None, None),
    ("rig_file", "", "Rig YAML; empty: the bundled seed rig", None, None),
    ("scenario", "imbalance+impact", "imbalance+impact or imbalance (Miller & Howard's two cases)", None, None),
    ("duration_s", 0.125, "Simulated time from rest, s (0.03 s are dropped as in the paper)", 0.04, 3600.0),
    ("impact_period_s", 0.0, "Add a hammer impact (the paper's -515 N, 50 us) every this many s; 0: none", 0.0,
     3600.0),
    ("seed", 1, "Noise seed", 0, 2**31 - 1),
    ("rate_factor", 1.0, "Playback speed: 1 real time, 2 twice as fast", 0.001, 1000.0),
    ("block_size", 200, "Samples per PointCloud2 probe block", 1, 100_000),
    ("probe_message_type", "sensor_msgs/msg/PointCloud2", "PointCloud2 blocks or geometry_msgs/msg/PointStamped "
     "per sample", None, None),
    ("repeat", False, "Publish the simulated recording again and again (stamps continue)", None, None),
    ("bag_path", "", "Bag to replay (mode replay)", None, None),
    ("start_offset_s", 0.0, "Skip this much of the bag, s (mode replay)", 0.0, 1e6),
    ("loop", False, "Replay the bag again and again (stamps continue)", None, None),
    ("restamp", True, "Shift stamps so that the first sample is stamped with the start time", None, None),
    ("start_delay_s", 0.5, "Wait this long before publishing (discovery), s", 0.0, 60.0),
    ("tick_rate_hz", 500.0, "Publishing timer rate, Hz", 1.0, 10_000.0),
    ("probe1_topic", "/rotor/probe1", "Probe plane 1 topic", None, None),
    ("probe2_topic", "/rotor/probe2", "Probe plane 2 topic", None, None),
    ("keyphasor_topic", "/rotor/keyphasor", "Keyphasor topic", None, None),
    ("impact_topic", "/rotor/impact", "Impact force topic", None, None),
)


#: The same table as :class:`~rotor_estimator.ros.params.ParamSpec` records (declared read-only).
PARAMETERS: tuple[ParamSpec, ...] = tuple(ParamSpec(name, default, text, low, high)
                                          for name, default, text, low, high in _PARAMS)


def recording_events(rec: RigRecording, factory: ma.MessageFactory, block_size: int,
                     point_stamped: bool) -> tuple[list[Event], int]:
    """Publish events for a recording, due at their last sample (relative to the first sample),
    and the period (ns) after which a repetition continues the stamps."""
    t = rec.stamps_ns
    t0 = int(t[0])
    n = len(rec)
    events: list[Event] = []
    step = 1 if point_stamped else block_size
    for plane, cols, frame in ((1, slice(0, 2), "probe1"), (2, slice(2, 4), "probe2")):
        stream = f"probe{plane}"
        for i in range(0, n, step):
            j = min(i + step, n)
            st, xy = t[i:j], rec.probes_m[i:j, cols]
            if point_stamped:
                def make(s, st=st, xy=xy, frame=frame):
                    return ma.probe_sample_to_msg(factory, int(st[0]) + s, xy[0, 0], xy[0, 1], frame_id=frame)
            else:
                def make(s, st=st, xy=xy, frame=frame):
                    return ma.probe_block_to_msg(factory, st + s, xy, frame_id=frame)
            events.append(Event(int(st[-1]) - t0, stream, make))
    for p in rec.pulse_stamps_ns.tolist():
        events.append(Event(int(p) - t0, "keyphasor", lambda s, p=p: ma.pulse_to_msg(factory, int(p) + s)))
    nz = np.any(rec.impact_force_n != 0.0, axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], nz.astype(np.int8), [0]))))
    for a, b in zip(edges[0::2], edges[1::2]):
        for i in range(int(a), int(b), block_size):
            j = min(i + block_size, int(b))
            st, f = t[i:j], rec.impact_force_n[i:j]
            events.append(Event(int(st[-1]) - t0, "impact",
                                lambda s, st=st, f=f: ma.impact_block_to_msg(factory, st + s, f)))
    events.sort(key=lambda e: e.due_ns)
    period = int(t[-1] - t0) + (int(np.median(np.diff(t))) if n > 1 else 1)
    return events, period


def _shift_stamps(msg: Any, shift_ns: int) -> Any:
    """A copy of a rosbags message with ``header.stamp`` (and ``time_ref``) moved by ``shift_ns``."""
    from msg_adapters import make_time, stamp_to_ns

    fac = ma.TypestoreFactory()
    header = dataclasses.replace(msg.header, stamp=make_time(fac, stamp_to_ns(msg.header.stamp) + shift_ns))
    changes: dict[str, Any] = {"header": header}
    if hasattr(msg, "time_ref"):
        changes["time_ref"] = make_time(fac, stamp_to_ns(msg.time_ref) + shift_ns)
    return dataclasses.replace(msg, **changes)


def bag_events(path: str | Path, topics: ma.InputTopics, start_offset_s: float) -> tuple[list[Event], int, int]:
    """Events for a bag's input topics (as rclpy messages via CDR), its first stamp and loop period."""
    from rclpy.serialization import deserialize_message

    from rotor_estimator.io.bags import iter_bag_messages

    ts = ma.default_typestore()
    by_topic = {getattr(ma.DEFAULT_INPUT_TOPICS, s): s for s in ("probe1", "probe2", "keyphasor", "impact")}
    by_topic.update({getattr(topics, s): s for s in ("probe1", "probe2", "keyphasor", "impact")})
    msgs = [(m.log_time_ns, by_topic[m.topic], m.typename, m.msg) for m in iter_bag_messages(path, list(by_topic))]
    if not msgs:
        raise ConfigError(f"parameter bag_path: {path} has no input topic messages ({sorted(by_topic)})")
    first = msgs[0][0]
    cls_cache: dict[str, type] = {}
    fac = ma.RclpyFactory()
    events = []
    offset = int(start_offset_s * 1e9)
    for log_ns, stream, typename, msg in msgs:
        if log_ns - first < offset:
            continue
        cls = cls_cache.setdefault(typename, fac.message_class(typename))

        def make(shift: int, msg=msg, typename=typename, cls=cls) -> Any:
            m = _shift_stamps(msg, shift) if shift else msg
            return deserialize_message(ts.serialize_cdr(m, typename), cls)

        events.append(Event(log_ns - first - offset, stream, make))
    period = msgs[-1][0] - first - offset + 1
    return events, first + offset, period


class SimulatorNode(Node):
    """Publishes input topics on a wall-clock timer; :attr:`done` when finished (not repeating)."""

    def __init__(self, node_name: str = "rotor_simulator", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        v = declare_parameters(self, PARAMETERS)  # ints for doubles accepted; bad values: one line
        self.topics = ma.InputTopics(v["probe1_topic"], v["probe2_topic"], v["keyphasor_topic"], v["impact_topic"])
        fac = ma.RclpyFactory()
        if v["probe_message_type"] not in ma.PROBE_TYPES:
            raise ConfigError(f"parameter probe_message_type: must be one of {ma.PROBE_TYPES}")
        point_stamped = v["probe_message_type"] == "geometry_msgs/msg/PointStamped"
        if v["mode"] == "simulate":
            rig = load_rig_file(v["rig_file"] or None).rig
            base = paper_scenario(v["scenario"])
            impacts = base.impacts
            if v["impact_period_s"] > 0:
                proto = base.impacts[0] if base.impacts else paper_scenario().impacts[0]
                starts = np.arange(proto.start_s, v["duration_s"] - proto.duration_s, v["impact_period_s"])
                impacts = tuple(Impact(float(s), proto.duration_s, proto.force_x_n, proto.force_y_n) for s in starts)
            scenario = dataclasses.replace(base, duration_s=float(v["duration_s"]),
                                           impacts=tuple(i for i in impacts if i.start_s < v["duration_s"]))
            rec = simulate(rig, scenario, seed=int(v["seed"])).recording
            self.events, period = recording_events(rec, fac, int(v["block_size"]), point_stamped)
            first_stamp = int(rec.stamps_ns[0])
            self.repeat = bool(v["repeat"])
            self.samples_per_plane = len(rec)
        elif v["mode"] == "replay":
            if not v["bag_path"]:
                raise ConfigError("parameter bag_path: required in mode replay")
            self.events, first_stamp, period = bag_events(v["bag_path"], self.topics, float(v["start_offset_s"]))
            self.repeat = bool(v["loop"])
            self.samples_per_plane = -1
        else:
            raise ConfigError(f"parameter mode: must be simulate or replay, got {v['mode']!r}")
        self.period_ns = period
        self.rate_factor = float(v["rate_factor"])
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self._pubs: dict[str, Any] = {}
        self._qos = qos
        self._fac = fac
        now = self.get_clock().now().nanoseconds
        self._start_ns = now + int(float(v["start_delay_s"]) * 1e9)
        self._shift0 = (self._start_ns - first_stamp) if v["restamp"] else 0
        # every publisher exists from the start, so discovery has start_delay_s to match it
        # with the subscribers before its first message (a late-created one loses its first)
        for stream in ("probe1", "probe2", "keyphasor", "impact"):
            first = next((e for e in self.events if e.stream == stream), None)
            if first is not None:
                self._publisher(stream, first.make(self._shift0))
        self._due = [e.due_ns for e in self.events]
        self._next = 0
        self._cycle = 0
        self.published = {"probe1": 0, "probe2": 0, "keyphasor": 0, "impact": 0}
        self.done = False
        self.create_timer(1.0 / float(v["tick_rate_hz"]), self._tick)
        self.get_logger().info(f"{v['mode']}: {len(self.events)} messages per pass, rate factor {self.rate_factor:g}"
                               f"{', repeating' if self.repeat else ''}")

    def _publisher(self, stream: str, msg: Any) -> Any:
        pub = self._pubs.get(stream)
        if pub is None:
            pub = self.create_publisher(type(msg), getattr(self.topics, stream), self._qos)
            self._pubs[stream] = pub
        return pub

    def _tick(self) -> None:
        if self.done:
            return
        elapsed = (self.get_clock().now().nanoseconds - self._start_ns) * self.rate_factor
        if elapsed < 0:
            return
        while True:
            rel = int(elapsed) - self._cycle * self.period_ns
            stop = bisect.bisect_right(self._due, rel)
            for e in self.events[self._next:stop]:
                msg = e.make(self._shift0 + self._cycle * self.period_ns)
                self._publisher(e.stream, msg).publish(msg)
                self.published[e.stream] += 1
            self._next = max(self._next, stop)
            if self._next < len(self.events):
                return
            if not self.repeat:
                self.done = True
                self.get_logger().info("all messages published")
                return
            self._cycle += 1
            self._next = 0


def main(args: list[str] | None = None) -> int:
    """``ros2 run rotor_estimator simulator_node [--ros-args -p rate_factor:=0.5 ...]``."""
    return run_node(SimulatorNode, "simulator_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
