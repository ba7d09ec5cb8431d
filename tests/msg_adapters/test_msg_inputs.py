# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Input adapters: probes, keyphasor, impact; rclpy and rosbags classes through the same code."""
from __future__ import annotations


import numpy as np
import pytest

import msg_adapters as ma
from rotor_estimator.core.errors import InputError

T0_NS = 1_700_000_000_999_999_937  # exercises every nanosecond digit


def _block(n: int = 257, dt_ns: int = 50_000, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return T0_NS + np.arange(n, dtype=np.int64) * dt_ns, rng.normal(scale=1e-5, size=(n, 2))


def test_stamp_conversion_is_exact_to_the_nanosecond(factory):
    for ns in (0, 1, 999_999_999, 1_000_000_000, T0_NS, 2**31 * 10**9 - 1):
        t = ma.make_time(factory, ns)
        assert ma.stamp_to_ns(t) == ns
        assert 0 <= t.nanosec < 10**9


def test_stamp_outside_int32_seconds_is_rejected():
    with pytest.raises(InputError, match="int32"):
        ma.ns_to_sec_nanosec(2**31 * 10**9)


def test_probe_block_round_trip_is_exact(factory, wire):
    stamps, xy = _block()
    msg = ma.probe_block_to_msg(factory, stamps, xy, frame_id="probe1")
    assert ma.msg_typename(msg) == "sensor_msgs/msg/PointCloud2"
    for m in (msg, wire(msg)):
        got_stamps, got_xy = ma.probe_block_from_msg(m)
        assert got_stamps.dtype == np.int64 and np.array_equal(got_stamps, stamps)
        assert got_xy.dtype == np.float64 and np.array_equal(got_xy, xy)


def test_probe_block_has_the_documented_layout(factory):
    stamps, xy = _block(10)
    msg = ma.probe_block_to_msg(factory, stamps, xy, frame_id="probe2")
    layout = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    assert layout == [("x_m", 0, 8, 1), ("y_m", 8, 8, 1), ("t_offset_ns", 16, 6, 1)]
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 10, 20, 200)
    assert msg.is_dense is True and msg.is_bigendian is False
    assert msg.header.frame_id == "probe2" and ma.stamp_to_ns(msg.header.stamp) == stamps[0]


def test_cloud_with_nan_is_not_marked_dense(factory):
    stamps, xy = _block(4)
    xy[2, 0] = np.nan
    msg = ma.probe_block_to_msg(factory, stamps, xy, frame_id="probe1")
    assert msg.is_dense is False
    assert np.isnan(ma.probe_block_from_msg(msg)[1][2, 0])


def test_probe_point_stamped_round_trip_is_one_exact_sample(factory, wire):
    msg = ma.probe_sample_to_msg(factory, T0_NS, 1.25e-5, -3.5e-6, frame_id="probe1")
    stamps, xy = ma.probe_block_from_msg(wire(msg))
    assert stamps.tolist() == [T0_NS] and xy.tolist() == [[1.25e-5, -3.5e-6]]
    assert msg.point.z == 0.0 and msg.header.frame_id == "probe1"


def test_impact_block_and_wrench_round_trips_are_exact(factory, wire):
    stamps, f = _block(3)
    f *= 1e7
    got = ma.impact_block_from_msg(wire(ma.impact_block_to_msg(factory, stamps, f)))
    assert np.array_equal(got[0], stamps) and np.array_equal(got[1], f)
    assert [x.name for x in ma.impact_block_to_msg(factory, stamps, f).fields] == ["fx_n", "fy_n", "t_offset_ns"]
    s1, f1 = ma.impact_block_from_msg(wire(ma.impact_sample_to_msg(factory, T0_NS, 0.0, -515.0)))
    assert s1.tolist() == [T0_NS] and f1.tolist() == [[0.0, -515.0]]


def test_pulse_round_trip_is_exact_and_sets_header_and_time_ref(factory, wire):
    msg = wire(ma.pulse_to_msg(factory, T0_NS))
    assert ma.pulse_stamp_from_msg(msg) == T0_NS
    assert ma.stamp_to_ns(msg.header.stamp) == T0_NS and msg.source == "keyphasor"


def test_pulse_with_zero_time_ref_uses_header_stamp(factory):
    msg = ma.pulse_to_msg(factory, T0_NS)
    msg.time_ref = ma.make_time(factory, 0)
    assert ma.pulse_stamp_from_msg(msg) == T0_NS


@pytest.mark.parametrize("decoder", [ma.probe_block_from_msg, ma.impact_block_from_msg, ma.pulse_stamp_from_msg])
def test_wrong_message_type_raises_input_error_naming_expected_and_got(factory, decoder):
    wrong = ma.coefficients_to_msg(factory, T0_NS, np.zeros(8), np.zeros(8))
    with pytest.raises(InputError, match=r"expected .*got sensor_msgs/msg/JointState"):
        decoder(wrong)


def test_probe_message_on_impact_decoder_is_rejected(factory):
    msg = ma.probe_sample_to_msg(factory, T0_NS, 0.0, 0.0, frame_id="probe1")
    with pytest.raises(InputError, match="geometry_msgs/msg/WrenchStamped.*got geometry_msgs/msg/PointStamped"):
        ma.impact_block_from_msg(msg)


def test_block_encoder_rejects_span_beyond_uint32_offsets(factory):
    stamps = np.array([0, 2**32], dtype=np.int64)
    with pytest.raises(InputError, match="UINT32"):
        ma.probe_block_to_msg(factory, stamps, np.zeros((2, 2)), frame_id="probe1")


def test_block_encoder_rejects_empty_and_mismatched_blocks(factory):
    with pytest.raises(InputError):
        ma.probe_block_to_msg(factory, np.zeros(0, np.int64), np.zeros((0, 2)), frame_id="probe1")
    with pytest.raises(InputError, match="shape"):
        ma.probe_block_to_msg(factory, np.arange(3), np.zeros((2, 2)), frame_id="probe1")


def test_rclpy_encoded_message_decodes_as_rosbags_message_and_back():
    """Wire compatibility: rclpy CDR bytes read by the rosbags typestore and vice versa."""
    rclpy_ser = pytest.importorskip("rclpy.serialization")
    from sensor_msgs.msg import PointCloud2

    ts = ma.default_typestore()
    stamps, xy = _block(100)
    raw = rclpy_ser.serialize_message(ma.probe_block_to_msg(ma.RclpyFactory(), stamps, xy, frame_id="p"))
    got = ma.probe_block_from_msg(ts.deserialize_cdr(raw, "sensor_msgs/msg/PointCloud2"))
    assert np.array_equal(got[0], stamps) and np.array_equal(got[1], xy)
    bag_msg = ma.probe_block_to_msg(ma.TypestoreFactory(ts), stamps, xy, frame_id="p")
    back = rclpy_ser.deserialize_message(bytes(ts.serialize_cdr(bag_msg, bag_msg.__msgtype__)), PointCloud2)
    got = ma.probe_block_from_msg(back)
    assert np.array_equal(got[0], stamps) and np.array_equal(got[1], xy)
