# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator bench live``: the estimator node through real rclpy, in one process.

A publisher (its own executor thread, publishing from a third thread on wall-clock due
times) sends simulated probe blocks of 200 samples per plane plus keyphasor pulses at a
stepped sample rate; the estimator node runs in its own executor thread. Per step:

* **loss**: published samples not accounted as processed (or gated as outliers) by the
  node's pipeline after the input stops (DDS drops, late or unmatched samples, samples
  rejected because the keyphasor fell behind);
* **latency**: wall time from publishing the probe message that completes the sample an
  estimate refers to (the later of the two planes) to receiving that estimate on
  ``~/coefficients``.

Stamps are wall-clock based, so the node's falling-behind monitor works as in the field.
Stepping stops at the first rate with loss.
"""
from __future__ import annotations

import random
import threading
import time
from dataclasses import replace
from typing import Any

import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

import msg_adapters as ma

from rotor_estimator.core.config import with_overrides
from rotor_estimator.core.pipeline import EstimatorPipeline
from rotor_estimator.core.simulator import Scenario, simulate
from rotor_estimator.ros.estimator_node import EstimatorNode

BLOCK = 200


def _messages(rate_hz: float, step_s: float, base_ns: int, rig) -> tuple[list, np.ndarray, np.ndarray]:
    """Due-time-ordered ``(due_ns, stream, msg)`` and the first and last stamps of the probe blocks."""
    fac = ma.RclpyFactory()
    rig_r = with_overrides(rig, sample_rate_hz=float(rate_hz))
    rec = simulate(rig_r, Scenario(duration_s=step_s + 0.03, impacts=(), substeps=2, name="bench"), seed=3,
                   epoch_ns=base_ns - 30_000_000).recording
    n = len(rec)
    items = []
    firsts, lasts = [], []
    for i in range(0, n - BLOCK + 1, BLOCK):
        st = rec.stamps_ns[i:i + BLOCK]
        firsts.append(int(st[0]))
        lasts.append(int(st[-1]))
        for plane, cols in ((1, slice(0, 2)), (2, slice(2, 4))):
            items.append((int(st[-1]), plane, ma.probe_block_to_msg(fac, st, rec.probes_m[i:i + BLOCK, cols],
                                                                   frame_id=f"probe{plane}")))
    for p in rec.pulse_stamps_ns.tolist():
        items.append((int(p), 0, ma.pulse_to_msg(fac, int(p))))
    items.sort(key=lambda x: (x[0], x[1]))
    return items, np.asarray(firsts, dtype=np.int64), np.asarray(lasts, dtype=np.int64)


def _step(est: EstimatorNode, bench, pubs, rate_hz: float, step_s: float, rig, est_cfg) -> dict[str, Any]:
    clock = est.get_clock()
    base = clock.now().nanoseconds + 500_000_000
    items, firsts, lasts = _messages(rate_hz, step_s, base, rig)
    rig_r = with_overrides(rig, sample_rate_hz=float(rate_hz))
    with est.lock:
        est.pipeline = EstimatorPipeline(rig_r, est_cfg, est.pipeline.tach_config,
                                         replace(est.pipeline.align_config, sample_rate_hz=float(rate_hz)),
                                         est.pipeline.publish_period_ns * 1e-9, options=est.pipeline.options)
    bench["received"].clear()
    bench["diag"].clear()
    pub_time: dict[int, dict[int, int]] = {1: {}, 2: {}}
    published = 0
    lead = min(i[0] for i in items) - 30_000_000
    for due, plane, msg in items:
        wait = (due - lead if plane == 0 and due < base else due) - clock.now().nanoseconds
        if wait > 0:
            time.sleep(wait * 1e-9)
        (pubs[plane]).publish(msg)
        if plane:
            pub_time[plane][due] = clock.now().nanoseconds
            published += BLOCK
    time.sleep(1.0)                              # drain + idle release
    with est.lock:
        acc = est.pipeline.accounting()
    published //= 2
    lost = published - acc.processed - acc.ekf_rejected["gated_outlier"]
    lat = []
    final_ns = int(lasts[-1]) if len(lasts) else -1
    for recv_ns, stamp in list(bench["received"]):
        if stamp >= final_ns:
            continue                      # the end-of-input estimate is released by the idle timeout
        k = int(np.searchsorted(firsts, stamp, side="right")) - 1
        if k < 0 or k >= len(firsts):
            continue
        last = int(lasts[k])
        t1, t2 = pub_time[1].get(last), pub_time[2].get(last)
        if t1 is not None and t2 is not None:
            lat.append((recv_ns - max(t1, t2)) * 1e-6)
    diag = list(bench["diag"])
    return {"rate_hz": rate_hz, "published_samples": published, "processed": acc.processed,
            "lost_samples": int(max(lost, 0)), "rejected": acc.summary()["rejected"],
            "rejected_by_reason": {k: v for k, v in acc.rejected_by_reason().items() if v},
            "received": dict(acc.received), "pending": dict(acc.pending), "missing": dict(acc.missing),
            "latency_p50_ms": float(np.percentile(lat, 50)) if lat else float("nan"),
            "latency_p99_ms": float(np.percentile(lat, 99)) if lat else float("nan"),
            "estimates": len(lat), "falling_behind_reported": any(d[1] for d in diag),
            "max_diagnostics_level": max((d[0] for d in diag), default=-1)}


def run(step_s: float = 3.0, rates_hz: tuple[float, ...] = (5e3, 1e4, 2e4, 4e4, 8e4), progress: bool = True,
        stop_at_loss: bool = True) -> dict[str, Any]:
    """Step the rate up; return the highest lossless rate and the latency at it."""
    ctx = Context()
    rclpy.init(context=ctx, domain_id=random.randint(1, 200))
    est = bench_node = None
    executors: list[SingleThreadedExecutor] = []
    threads: list[threading.Thread] = []
    try:
        est = EstimatorNode(context=ctx)
        rig, est_cfg = est.rig_file.rig, est.rig_file.estimator
        bench_node = rclpy.create_node("rotor_bench", context=ctx)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        fac = ma.RclpyFactory()
        cloud = fac.message_class("sensor_msgs/msg/PointCloud2")
        time_ref = fac.message_class("sensor_msgs/msg/TimeReference")
        pubs = {1: bench_node.create_publisher(cloud, est.topics.probe1, qos),
                2: bench_node.create_publisher(cloud, est.topics.probe2, qos),
                0: bench_node.create_publisher(time_ref, est.topics.keyphasor, qos)}
        state: dict[str, list] = {"received": [], "diag": []}
        clock = bench_node.get_clock()
        bench_node.create_subscription(
            fac.message_class("sensor_msgs/msg/JointState"),
            ma.output_topic(ma.COEFFICIENTS_TOPIC, est.get_fully_qualified_name()),
            lambda m: state["received"].append((clock.now().nanoseconds, ma.stamp_to_ns(m.header.stamp))), 1000)

        def on_diag(m: Any) -> None:
            for s in ma.diagnostics_from_msg(m).statuses:
                state["diag"].append((s.level, s.values.get("falling_behind") == "true"))

        bench_node.create_subscription(fac.message_class("diagnostic_msgs/msg/DiagnosticArray"), ma.DIAGNOSTICS_TOPIC,
                                       on_diag, 100)
        for node in (est, bench_node):
            ex = SingleThreadedExecutor(context=ctx)
            ex.add_node(node)
            executors.append(ex)
            threads.append(threading.Thread(target=ex.spin, daemon=True))
            threads[-1].start()
        time.sleep(1.0)                                  # discovery
        steps = []
        for rate in rates_hz:
            r = _step(est, state, pubs, float(rate), step_s, rig, est_cfg)
            steps.append(r)
            if progress:
                print(f"  {rate:8.0f} Hz: lost {r['lost_samples']} of {r['published_samples']}, latency p50 "
                      f"{r['latency_p50_ms']:.1f} ms p99 {r['latency_p99_ms']:.1f} ms"
                      f"{', falling behind reported' if r['falling_behind_reported'] else ''}", flush=True)
            if stop_at_loss and r["lost_samples"] > 0:
                break
    finally:
        for ex in executors:
            ex.shutdown(timeout_sec=2.0)
        for t in threads:
            t.join(timeout=5.0)
        for node in (est, bench_node):
            if node is not None:
                node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    ok = [s for s in steps if s["lost_samples"] == 0]
    best = max(ok, key=lambda s: s["rate_hz"]) if ok else None
    return {"max_rate_hz_without_loss": best["rate_hz"] if best else 0.0,
            "latency_p50_ms": best["latency_p50_ms"] if best else float("nan"),
            "latency_p99_ms": best["latency_p99_ms"] if best else float("nan"),
            "block_samples": BLOCK, "step_s": step_s, "steps": steps}


def format_result(r: dict[str, Any]) -> str:
    return (f"live rclpy (Fast DDS, one process): max probe rate without loss {r['max_rate_hz_without_loss']:.0f} Hz "
            f"per plane ({r['block_samples']}-sample blocks); latency p50 {r['latency_p50_ms']:.1f} ms, "
            f"p99 {r['latency_p99_ms']:.1f} ms at that rate")
