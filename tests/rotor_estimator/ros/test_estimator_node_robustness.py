# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The live node survives the unexpected and says what it dropped (real rclpy, no spinning needed)."""
from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")
from rclpy.context import Context  # noqa: E402

import msg_adapters as ma  # noqa: E402
from rotor_estimator.ros.estimator_node import EstimatorNode  # noqa: E402
from rotor_estimator.core.pipeline import LEVEL_ERROR, LEVEL_WARN  # noqa: E402

from live_helpers import random_domain_id  # noqa: E402


@pytest.fixture
def node():
    context = Context()
    rclpy.init(context=context, domain_id=random_domain_id())
    n = EstimatorNode(context=context)
    published = []
    n._diag_pub.publish = published.append
    n.published_diagnostics = published
    yield n
    n.destroy_node()
    rclpy.try_shutdown(context=context)


def test_an_exception_inside_the_pipeline_is_logged_counted_and_survived(node, monkeypatch):
    """pipeline.process() raising (a bug, a corrupt message) no longer escapes the callback and kills
    the node: the next message is handled, and /diagnostics goes ERROR naming the count."""
    calls = {"n": 0}
    real = node.pipeline.process

    def flaky(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("boom")
        return real(*args, **kwargs)

    monkeypatch.setattr(node.pipeline, "process", flaky)
    fac = ma.RclpyFactory()
    node._on_input("probe1", ma.probe_sample_to_msg(fac, 1_000_000, 1e-6, 2e-6, frame_id="probe1"))  # raises inside
    node._on_input("probe1", ma.probe_sample_to_msg(fac, 1_050_000, 1e-6, 2e-6, frame_id="probe1"))  # handled
    assert calls["n"] == 2 and node.unexpected_errors == 1
    node._publish_diagnostics()
    status = node.published_diagnostics[-1].status[0]
    assert status.level == bytes([LEVEL_ERROR]) or status.level == LEVEL_ERROR
    assert "1 unexpected error(s)" in status.message


def test_messages_dropped_by_the_middleware_are_counted_and_reported(node):
    """A message-lost event (e.g. a keyphasor flood beyond the queue) is counted per stream and named
    on /diagnostics at WARN or worse, not hidden behind 'falling behind'."""
    class Info:
        total_count = 990
        total_count_change = 990

    node._on_lost("keyphasor", Info())
    node._publish_diagnostics()
    status = node.published_diagnostics[-1].status[0]
    level = status.level if isinstance(status.level, int) else status.level[0]
    assert level >= LEVEL_WARN and "'keyphasor': 990" in status.message
    assert any(kv.key == "messages_lost_keyphasor" and kv.value == "990" for kv in status.values)
