# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Live virtual sensing through real rclpy: sensor blocks in, station estimates out.

Own Context on a random ROS_DOMAIN_ID, one executor thread, timeouts everywhere and a
clean shutdown in ``finally``.
"""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from live_helpers import random_domain_id, wait_for

rclpy = pytest.importorskip("rclpy")

from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

import msg_adapters as ma  # noqa: E402
from rotor_estimator.core.errors import ConfigError  # noqa: E402
from rotor_estimator.core.flexible import simulate, station_outputs  # noqa: E402
from rotor_estimator.ros.virtual_sensing_node import VirtualSensingNode, pipeline_from_parameters  # noqa: E402

T0_NS = 1_700_000_000_000_000_000
N_SAMPLES = 480
BLOCK = 32



@pytest.fixture
def ros():
    ctx = Context()
    rclpy.init(context=ctx, domain_id=random_domain_id())
    ex = SingleThreadedExecutor(context=ctx)
    nodes = []

    def add(node):
        nodes.append(node)
        ex.add_node(node)
        return node

    th = threading.Thread(target=ex.spin, daemon=True)
    try:
        yield ctx, add, th
    finally:
        ex.shutdown(timeout_sec=2.0)
        if th.is_alive() or th.ident is not None:
            th.join(timeout=5.0)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        assert not th.is_alive(), "the executor thread did not stop"


def test_node_publishes_station_estimates_at_sample_stamps_whose_intervals_cover_the_truth(ros):
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState, PointCloud2, TimeReference

    ctx, add, thread = ros
    node = add(VirtualSensingNode(context=ctx, parameter_overrides=[
        Parameter("rotor_file", value="three_probe_rig"), Parameter("diagnostics_rate_hz", value=5.0),
        Parameter("stations", value=["disk1", "midspan", "gap=0.2"])]))
    ss = node.pipeline.ss
    sim = simulate(ss, N_SAMPLES, seed=21)
    stamps = T0_NS + np.rint(sim.t * 1e9).astype(np.int64)
    period_ns = 2 * np.pi / ss.rotor.speed_rad_s * 1e9
    pulses = T0_NS + np.rint(np.arange(int(sim.t[-1] * 1e9 / period_ns) + 2) * period_ns).astype(np.int64)

    io = add(Node("vs_test_io", context=ctx))
    fac = ma.RclpyFactory()
    got: dict[str, list] = {name: [] for name, _ in node.pipeline.stations}
    diags: list = []
    lock = threading.Lock()

    def on_station(msg):
        with lock:
            st = ma.station_from_msg(msg)
            got[st.station].append(st)

    for name in got:
        io.create_subscription(JointState, f"/virtual_sensing/stations/{name}", on_station, 1000)
    io.create_subscription(DiagnosticArray, "/diagnostics", lambda m: diags.append(ma.diagnostics_from_msg(m)), 10)
    pubs = {s.name: io.create_publisher(PointCloud2, ma.sensor_topic(s.name), 100) for s in ss.rotor.sensors}
    pulse_pub = io.create_publisher(TimeReference, "/rotor/keyphasor", 100)
    thread.start()
    assert wait_for(lambda: all(p.get_subscription_count() > 0 for p in pubs.values())
                    and pulse_pub.get_subscription_count() > 0, 10.0), "node did not subscribe"
    assert wait_for(lambda: io.count_publishers("/virtual_sensing/stations/gap") > 0, 10.0)

    for p in pulses.tolist():
        pulse_pub.publish(ma.pulse_to_msg(fac, p))
    assert wait_for(lambda: node.pipeline.counters["pulses"] == len(pulses), 10.0), node.pipeline.counters
    for i in range(0, N_SAMPLES, BLOCK):
        for j, s in enumerate(ss.rotor.sensors):  # probe j: channels 2j, 2j+1
            block = sim.z[i:i + BLOCK, 2 * j:2 * j + 2]
            pubs[s.name].publish(ma.sensor_block_to_msg(fac, s.kind, stamps[i:i + BLOCK], block, frame_id=s.name))
        time.sleep(0.005)
    assert wait_for(lambda: all(len(v) >= N_SAMPLES for v in got.values()), 20.0), \
        ({k: len(v) for k, v in got.items()}, node.pipeline.status())
    assert wait_for(lambda: any(int(d.statuses[0].values.get("samples_filtered", 0)) == N_SAMPLES
                                for d in list(diags)), 10.0)

    inside = []
    for name, axial in node.pipeline.stations:
        msgs = sorted(got[name], key=lambda m: m.stamp_ns)
        assert [m.stamp_ns for m in msgs] == stamps.tolist()  # every sample, stamped with its own time
        C, D, _ = station_outputs(ss, axial)
        truth = sim.x @ C.T + sim.u @ D.T
        mean = np.array([m.mean for m in msgs])
        std = np.array([m.std for m in msgs])
        assert np.all(std > 0)
        inside.append(np.abs(truth - mean) <= 1.96 * std)
    coverage = float(np.mean(inside))
    print(f"coverage of the truth by the live 95% intervals: {coverage:.3f}")
    assert 0.88 <= coverage <= 0.99, coverage
    status = [d for d in diags if int(d.statuses[0].values.get("samples_filtered", 0)) == N_SAMPLES][-1].statuses[0]
    assert status.name == "virtual_sensing: three_probe_rig"
    assert abs(float(status.values["nis_coverage"]) - 0.95) < 0.05
    assert status.values["late_probe1"] == "0" and status.values["missing_probe3"] == "0"


def test_node_parameters_are_validated_and_name_the_bad_one():
    with pytest.raises(ConfigError, match="parameter filter"):
        pipeline_from_parameters({"filter": "pf"})
    with pytest.raises(ConfigError, match="parameter stations"):
        pipeline_from_parameters({"stations": ["nowhere"]})
