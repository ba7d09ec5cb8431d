# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Bag I/O: RigRecording <-> MCAP rosbag2 bag, streaming, outputs, and broken bags."""
from __future__ import annotations

import struct
import time
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

import msg_adapters as ma
from rotor_estimator.io.bags import (BagMessage, OutputBagWriter, bag_topics, iter_bag_messages, read_input_bag,
                                   write_input_bag)
from rotor_estimator.core.errors import BagError, InputError
from rotor_estimator.core.recording import RigRecording

T0_NS = 1_700_000_000_000_000_007
DT_NS = 50_000  # 20 kHz
TOPICS = ma.DEFAULT_INPUT_TOPICS


def _impacts(n: int) -> tuple[int, int]:
    """Index of the 2-sample impact and of the 1-sample tap in a recording of n samples."""
    return n * 8 // 25, n * 3 // 5


def _recording(n: int = 2500, seed: int = 3) -> RigRecording:
    """n samples at 20 kHz (default 0.125 s), a 2-sample impact, a 1-sample tap, a pulse every 8 ms."""
    rng = np.random.default_rng(seed)
    stamps = T0_NS + np.arange(n, dtype=np.int64) * DT_NS
    force = np.zeros((n, 2))
    i, j = _impacts(n)
    force[i:i + 2] = [12.5, -515.0]
    force[j, 0] = 3.0
    return RigRecording(stamps, rng.normal(scale=1e-5, size=(n, 4)), stamps[::160] + 1234, force,
                        {"scenario": "test", "seed": seed})


def _assert_same(a: RigRecording, b: RigRecording) -> None:
    assert a.stamps_ns.dtype == np.int64 and np.array_equal(a.stamps_ns, b.stamps_ns)
    assert np.array_equal(a.probes_m, b.probes_m)
    assert np.array_equal(a.pulse_stamps_ns, b.pulse_stamps_ns)
    assert np.array_equal(a.impact_force_n, b.impact_force_n)


def _mcap_file(bag: Path) -> Path:
    return next(bag.glob("*.mcap"))


def _write_raw(path: Path, items: list[tuple[str, int, object]]) -> Path:
    """Write (topic, log_time_ns, rosbags message) in the given order with rosbags' Writer."""
    ts = ma.default_typestore()
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns: dict[tuple[str, str], object] = {}
        for topic, log_ns, msg in items:
            key = (topic, msg.__msgtype__)
            if key not in conns:
                conns[key] = w.add_connection(topic, msg.__msgtype__, typestore=ts)
            w.write(conns[key], log_ns, ts.serialize_cdr(msg, msg.__msgtype__))
    return path


def _probe_items(rec: RigRecording, keep2: slice = slice(None)) -> list[tuple[str, int, object]]:
    """Both probes of ``rec`` as one block each (probe2 limited to ``keep2``) plus the first pulse."""
    fac = ma.TypestoreFactory()
    last = int(rec.stamps_ns[-1])
    return [(TOPICS.probe1, last, ma.probe_block_to_msg(fac, rec.stamps_ns, rec.probes_m[:, :2], frame_id="p1")),
            (TOPICS.probe2, last, ma.probe_block_to_msg(fac, rec.stamps_ns[keep2], rec.probes_m[keep2, 2:],
                                                        frame_id="p2")),
            (TOPICS.keyphasor, T0_NS, ma.pulse_to_msg(fac, T0_NS))]


def test_recording_to_bag_to_recording_is_exact(tmp_path):
    rec = _recording()
    back = read_input_bag(write_input_bag(tmp_path / "bag", rec))
    _assert_same(back, rec)
    assert back.meta == rec.meta


def test_block_size_not_dividing_length_still_round_trips(tmp_path):
    rec = _recording(n=1001)
    _assert_same(read_input_bag(write_input_bag(tmp_path / "bag", rec, block_size=64)), rec)


def test_bag_is_mcap_and_readable_from_its_mcap_file(tmp_path):
    rec = _recording(400)
    bag = write_input_bag(tmp_path / "bag", rec)
    assert "storage_identifier: mcap" in (bag / "metadata.yaml").read_text()
    mcap = _mcap_file(bag)
    assert mcap.read_bytes()[:8] == b"\x89MCAP0\r\n"
    _assert_same(read_input_bag(mcap), rec)


def test_125ms_20khz_recording_bag_is_under_200kb(tmp_path):
    bag = write_input_bag(tmp_path / "bag", _recording(2500))
    size = sum(f.stat().st_size for f in bag.iterdir())
    assert size < 200_000, size


def test_log_time_is_last_sample_stamp_and_messages_come_in_log_time_order(tmp_path):
    rec = _recording(1000)
    msgs = list(iter_bag_messages(write_input_bag(tmp_path / "bag", rec, block_size=200)))
    assert all(isinstance(m, BagMessage) for m in msgs)
    assert [m.log_time_ns for m in msgs] == sorted(m.log_time_ns for m in msgs)
    for m in msgs:
        if m.topic == TOPICS.keyphasor:
            assert m.log_time_ns == ma.pulse_stamp_from_msg(m.msg)
        elif m.topic in (TOPICS.probe1, TOPICS.probe2):
            assert m.log_time_ns == ma.probe_block_from_msg(m.msg)[0][-1]
        else:
            assert m.log_time_ns == ma.impact_block_from_msg(m.msg)[0][-1]


def test_impact_is_published_only_where_force_is_nonzero(tmp_path):
    rec = _recording()
    msgs = list(iter_bag_messages(write_input_bag(tmp_path / "bag", rec), [TOPICS.impact]))
    stamps = np.concatenate([ma.impact_block_from_msg(m.msg)[0] for m in msgs])
    i, j = _impacts(len(rec))
    assert len(msgs) == 2
    assert np.array_equal(stamps, rec.stamps_ns[[i, i + 1, j]])


def test_bag_read_with_independent_mcap_ros2_decoder_gives_same_values(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    rec = _recording(600)
    bag = write_input_bag(tmp_path / "bag", rec, block_size=100)
    samples: dict[str, list] = {TOPICS.probe1: [], TOPICS.probe2: [], TOPICS.impact: []}
    pulses = []
    with _mcap_file(bag).open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            t0 = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            if channel.topic == TOPICS.keyphasor:
                assert schema.name == "sensor_msgs/msg/TimeReference"
                pulses.append(msg.time_ref.sec * 10**9 + msg.time_ref.nanosec)
                continue
            assert schema.name == "sensor_msgs/msg/PointCloud2" and msg.point_step == 20
            data = bytes(msg.data)
            for i in range(msg.width):  # plain struct parsing, independent of msg_adapters
                a, b, off = struct.unpack_from("<ddI", data, i * msg.point_step)
                samples[channel.topic].append((t0 + off, a, b))
            assert message.log_time == samples[channel.topic][-1][0]
    p1, p2 = np.array(samples[TOPICS.probe1], dtype=object), np.array(samples[TOPICS.probe2], dtype=object)
    assert p1[:, 0].astype(np.int64).tolist() == rec.stamps_ns.tolist()
    assert np.array_equal(np.column_stack((p1[:, 1:], p2[:, 1:])).astype(float), rec.probes_m)
    assert pulses == rec.pulse_stamps_ns.tolist()
    i, j = _impacts(len(rec))
    assert [s[0] for s in samples[TOPICS.impact]] == rec.stamps_ns[[i, i + 1, j]].tolist()


def test_adapters_decode_mcap_ros2_dynamic_messages(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    rec = _recording(300)
    bag = write_input_bag(tmp_path / "bag", rec)
    with _mcap_file(bag).open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = [ma.probe_block_from_msg(msg) for _, _, _, msg in reader.iter_decoded_messages(topics=[TOPICS.probe1])]
    assert np.array_equal(np.concatenate([g[0] for g in got]), rec.stamps_ns)
    assert np.array_equal(np.concatenate([g[1] for g in got]), rec.probes_m[:, :2])


def test_out_of_order_messages_are_returned_in_log_time_order(tmp_path):
    rec = _recording(1000)
    fac = ma.TypestoreFactory()
    items = []
    for a in range(0, 1000, 100):
        b = a + 100
        items.append((TOPICS.probe1, int(rec.stamps_ns[b - 1]),
                      ma.probe_block_to_msg(fac, rec.stamps_ns[a:b], rec.probes_m[a:b, :2], frame_id="probe1")))
        items.append((TOPICS.probe2, int(rec.stamps_ns[b - 1]),
                      ma.probe_block_to_msg(fac, rec.stamps_ns[a:b], rec.probes_m[a:b, 2:], frame_id="probe2")))
    i, j = _impacts(len(rec))
    items += [(TOPICS.keyphasor, int(t), ma.pulse_to_msg(fac, int(t))) for t in rec.pulse_stamps_ns]
    for a, b in ((i, i + 2), (j, j + 1)):
        items.append((TOPICS.impact, int(rec.stamps_ns[b - 1]),
                       ma.impact_block_to_msg(fac, rec.stamps_ns[a:b], rec.impact_force_n[a:b])))
    rng = np.random.default_rng(0)
    bag = _write_raw(tmp_path / "bag", [items[k] for k in rng.permutation(len(items))])
    log_times = [m.log_time_ns for m in iter_bag_messages(bag)]
    assert log_times == sorted(log_times) and len(log_times) == len(items)
    _assert_same(read_input_bag(bag), rec)


def test_single_sample_messages_read_like_blocks(tmp_path):
    """PointStamped probes and WrenchStamped impacts (one sample each) give the same recording."""
    rec = _recording(50)
    fac = ma.TypestoreFactory()
    items = []
    for k, t in enumerate(rec.stamps_ns.tolist()):
        items.append((TOPICS.probe1, t, ma.probe_sample_to_msg(fac, t, *rec.probes_m[k, :2], frame_id="probe1")))
        items.append((TOPICS.probe2, t, ma.probe_sample_to_msg(fac, t, *rec.probes_m[k, 2:], frame_id="probe2")))
    t_pulse, t_hit = int(rec.pulse_stamps_ns[0]), int(rec.stamps_ns[10])
    items.append((TOPICS.keyphasor, t_pulse, ma.pulse_to_msg(fac, t_pulse)))
    items.append((TOPICS.impact, t_hit, ma.impact_sample_to_msg(fac, t_hit, 1.0, -2.0)))
    back = read_input_bag(_write_raw(tmp_path / "bag", items))
    expected = np.zeros((50, 2))
    expected[10] = [1.0, -2.0]
    assert np.array_equal(back.probes_m, rec.probes_m) and np.array_equal(back.impact_force_n, expected)


def test_impact_between_probe_samples_is_held_in_the_interval_it_falls_in(tmp_path):
    rec = _recording(20)
    fac = ma.TypestoreFactory()
    t_ns = int(rec.stamps_ns[5]) + 10
    items = _probe_items(rec) + [(TOPICS.impact, t_ns, ma.impact_sample_to_msg(fac, t_ns, 0.0, 9.0))]
    back = read_input_bag(_write_raw(tmp_path / "bag", items))
    assert back.impact_force_n[5].tolist() == [0.0, 9.0] and np.count_nonzero(back.impact_force_n) == 1


def test_unpaired_probe_samples_are_dropped_and_counted(tmp_path):
    rec = _recording(30)
    back = read_input_bag(_write_raw(tmp_path / "bag", _probe_items(rec, slice(2, None))))
    assert np.array_equal(back.stamps_ns, rec.stamps_ns[2:]) and back.meta["unpaired_probe_samples"] == 2


def test_missing_bag_raises_bag_error_saying_what_to_pass(tmp_path):
    with pytest.raises(BagError, match="not found; pass a rosbag2 directory"):
        read_input_bag(tmp_path / "nope")


def test_garbage_file_raises_bag_error(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(np.random.default_rng(0).bytes(5000))
    with pytest.raises(BagError, match="truncated or corrupt"):
        read_input_bag(junk)
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(BagError, match="not a bag"):
        read_input_bag(tmp_path / "notes.txt")
    (tmp_path / "empty.mcap").touch()
    with pytest.raises(BagError, match="empty"):
        read_input_bag(tmp_path / "empty.mcap")


@pytest.mark.parametrize("keep", [0.5, 0.9, 0.02])
def test_truncated_bag_raises_bag_error_quickly(tmp_path, keep):
    bag = write_input_bag(tmp_path / "bag", _recording())
    mcap = _mcap_file(bag)
    data = mcap.read_bytes()
    mcap.write_bytes(data[: int(len(data) * keep)])
    t0 = time.monotonic()
    for target in (bag, mcap):
        with pytest.raises(BagError, match="mcap recover"):
            read_input_bag(target)
        with pytest.raises(BagError):
            list(iter_bag_messages(target))
    assert time.monotonic() - t0 < 10.0


def test_corrupt_message_payload_raises_bag_error(tmp_path):
    bag = write_input_bag(tmp_path / "bag", _recording(400))
    mcap = _mcap_file(bag)
    data = bytearray(mcap.read_bytes())
    # the keyphasor source string length field: find 'keyphasor' CDR strings and break their length
    k = data.find(b"\x0a\x00\x00\x00keyphasor")
    assert k > 0
    data[k:k + 4] = b"\xff\xff\xff\x7f"
    mcap.write_bytes(bytes(data))
    with pytest.raises(BagError):
        read_input_bag(bag)


def test_missing_topic_raises_bag_error_listing_available_topics(tmp_path):
    rec = _recording(100)
    bag = write_input_bag(tmp_path / "bag", rec, topics=ma.InputTopics(probe1="/other/probe1"))
    with pytest.raises(BagError, match=r"lacks input topic\(s\) \['/rotor/probe1'\].*/other/probe1"):
        read_input_bag(bag)
    _assert_same(read_input_bag(bag, ma.InputTopics(probe1="/other/probe1")), rec)


def test_wrong_message_type_on_input_topic_raises_bag_error(tmp_path):
    fac = ma.TypestoreFactory()
    items = [(TOPICS.probe1, T0_NS, ma.pulse_to_msg(fac, T0_NS)),
             (TOPICS.probe2, T0_NS, ma.probe_sample_to_msg(fac, T0_NS, 0.0, 0.0, frame_id="p2")),
             (TOPICS.keyphasor, T0_NS, ma.pulse_to_msg(fac, T0_NS))]
    with pytest.raises(BagError, match="/rotor/probe1 has type .*TimeReference.*expected"):
        read_input_bag(_write_raw(tmp_path / "bag", items))


def test_malformed_cloud_in_bag_raises_bag_error_naming_topic(tmp_path):
    fac = ma.TypestoreFactory()
    bad = ma.impact_block_to_msg(fac, np.array([T0_NS]), np.ones((1, 2)))  # fx_n/fy_n, not x_m/y_m
    items = [(TOPICS.probe1, T0_NS, bad),
             (TOPICS.probe2, T0_NS, ma.probe_sample_to_msg(fac, T0_NS, 0.0, 0.0, frame_id="p2")),
             (TOPICS.keyphasor, T0_NS, ma.pulse_to_msg(fac, T0_NS))]
    with pytest.raises(BagError, match="topic /rotor/probe1 .*no field 'x_m'"):
        read_input_bag(_write_raw(tmp_path / "bag", items))


def test_writing_over_an_existing_path_raises_bag_error(tmp_path):
    (tmp_path / "bag").mkdir()
    with pytest.raises(BagError, match="already exists"):
        write_input_bag(tmp_path / "bag", _recording(10))
    with pytest.raises(BagError, match="already exists"):
        OutputBagWriter(tmp_path / "bag").open()


def test_negative_stamps_cannot_be_written(tmp_path):
    rec = RigRecording(np.array([-10, 0]), np.zeros((2, 4)), np.array([], np.int64), np.zeros((2, 2)))
    with pytest.raises(InputError, match=">= 0"):
        write_input_bag(tmp_path / "bag", rec)


def test_output_bag_round_trips_every_output_topic(tmp_path):
    path = tmp_path / "out"
    est, std, cov = np.arange(1.0, 9.0), np.full(8, 0.5), np.diag(np.arange(1.0, 9.0))
    status = (ma.DiagnosticRecord("rotor_estimator: filter", 0, "ok", "rig", {"nis": "3.9"}),)
    with OutputBagWriter(path) as w:
        f = w.factory
        for k in range(3):
            t = T0_NS + k * 10**6
            w.write(ma.output_topic(ma.COEFFICIENTS_TOPIC), ma.coefficients_to_msg(f, t, est * k, std), t)
            w.write(ma.output_topic(ma.COVARIANCE_TOPIC), ma.covariance_to_msg(f, t, cov), t)
            w.write(ma.output_topic(ma.INNOVATION_TOPIC), ma.innovation_to_msg(f, t, np.ones(4), np.ones(4)), t)
            w.write(ma.output_topic(ma.NIS_TOPIC), ma.nis_to_msg(f, t, 1.0, 2.0, 4.0), t)
            w.write(ma.output_topic(ma.SHAFT_TOPIC), ma.shaft_to_msg(f, t, 100.0, 0.5), t)
            w.write(ma.DIAGNOSTICS_TOPIC, ma.diagnostics_to_msg(f, t, status), t)
    assert bag_topics(path)["/rotor_estimator/coefficients"] == "sensor_msgs/msg/JointState"
    assert bag_topics(path)["/diagnostics"] == "diagnostic_msgs/msg/DiagnosticArray"
    coefs = [ma.coefficients_from_msg(m.msg) for m in iter_bag_messages(path, ["/rotor_estimator/coefficients"])]
    assert [c.stamp_ns for c in coefs] == [T0_NS, T0_NS + 10**6, T0_NS + 2 * 10**6]
    assert np.array_equal(coefs[2].estimate, est * 2) and np.array_equal(coefs[0].std, std)
    cov_topic = ma.output_topic(ma.COVARIANCE_TOPIC)
    covs = [ma.covariance_from_msg(m.msg) for m in iter_bag_messages(path, [cov_topic])]
    assert np.array_equal(covs[-1].covariance, cov)
    diags = [ma.diagnostics_from_msg(m.msg) for m in iter_bag_messages(path, ["/diagnostics"])]
    assert diags[0].statuses == status


def test_output_bag_writer_rejects_rclpy_messages_and_use_when_closed(tmp_path):
    pytest.importorskip("rclpy")
    w = OutputBagWriter(tmp_path / "out")
    with pytest.raises(BagError, match="not open"):
        w.write("/x", ma.shaft_to_msg(w.factory, 0, 1.0, 2.0), 0)
    with w:
        with pytest.raises(InputError, match="factory"):
            w.write("/x", ma.shaft_to_msg(ma.RclpyFactory(), 0, 1.0, 2.0), 0)


def test_output_bag_is_all_or_nothing_when_writing_stops_on_an_error(tmp_path):
    """An estimator crash mid-write leaves no output bag that could pass for a complete run."""
    with pytest.raises(RuntimeError):
        with OutputBagWriter(tmp_path / "out") as w:
            w.write("/rotor_estimator/shaft", ma.shaft_to_msg(w.factory, 5, 1.0, 2.0), 5)
            raise RuntimeError("estimator crashed")
    assert list(tmp_path.iterdir()) == []
