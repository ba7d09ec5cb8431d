# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Virtual sensing I/O: multi-sensor bags <-> arrays, station messages, CLI --bag/--report/--out-bag."""
from __future__ import annotations

import argparse
import json
import struct
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

import msg_adapters as ma
from rotor_estimator.io.bags import bag_topics, iter_bag_messages
from rotor_estimator.core.errors import BagError, InputError
from rotor_estimator.core.flexible import build_state_space, load_rotor_description, simulate
from rotor_estimator.cli.virtual_sensing import add_parser, pulses_from_inputs
from rotor_estimator.virtual_sensing.inputs import read_sensor_bag, write_sensor_bag

T0_NS = 1_700_000_000_000_000_007


@pytest.fixture(scope="module")
def mixed():
    """Probes and housing accelerometers (neisi_2022_like), 750 samples."""
    rotor = load_rotor_description("neisi_2022_like")
    ss = build_state_space(rotor)
    sim = simulate(ss, 750, seed=2)
    stamps = T0_NS + np.rint(sim.t * 1e9).astype(np.int64)
    return rotor, ss, sim, stamps, pulses_from_inputs(stamps, sim.u, rotor.speed_rad_s)


def _mcap(bag: Path) -> Path:
    return next(bag.glob("*.mcap"))


def test_sensor_bag_round_trip_is_exact_for_probes_and_accelerometers(tmp_path, mixed):
    rotor, ss, sim, stamps, pulses = mixed
    bag = write_sensor_bag(tmp_path / "bag", rotor, stamps, sim.z, pulses, block_size=100)
    assert "storage_identifier: mcap" in (bag / "metadata.yaml").read_text()
    topics = bag_topics(bag)
    assert topics["/rotor/acc1"] == topics["/rotor/probe3"] == "sensor_msgs/msg/PointCloud2"
    assert topics["/rotor/keyphasor"] == "sensor_msgs/msg/TimeReference"
    got = read_sensor_bag(bag, rotor)
    assert got.stamps_ns.dtype == np.int64 and np.array_equal(got.stamps_ns, stamps)
    assert got.channel_names == ss.channel_names and np.array_equal(got.z, sim.z)
    assert np.array_equal(got.pulse_stamps_ns, pulses) and len(pulses) > 3
    assert got.counters["released"] == 750 and got.counters["gap_samples"] == 0
    assert not any(v for k, v in got.counters.items() if k.startswith(("late", "missing", "duplicate")))


def test_sensor_bag_read_with_independent_mcap_ros2_decoder_gives_same_values(tmp_path, mixed):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    rotor, ss, sim, stamps, pulses = mixed
    bag = write_sensor_bag(tmp_path / "bag", rotor, stamps[:300], sim.z[:300], pulses[:3], block_size=64)
    samples: dict[str, list] = {}
    fields: dict[str, list] = {}
    got_pulses = []
    with _mcap(bag).open("rb") as f:
        for schema, channel, message, msg in make_reader(f, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages():
            if channel.topic == "/rotor/keyphasor":
                got_pulses.append(msg.time_ref.sec * 10**9 + msg.time_ref.nanosec)
                continue
            assert schema.name == "sensor_msgs/msg/PointCloud2" and msg.point_step == 20
            fields[channel.topic] = [fd.name for fd in msg.fields]
            t0 = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            data = bytes(msg.data)
            for i in range(msg.width):  # plain struct parsing, independent of msg_adapters
                a, b, off = struct.unpack_from("<ddI", data, i * msg.point_step)
                samples.setdefault(channel.topic, []).append((t0 + off, a, b))
            assert message.log_time == samples[channel.topic][-1][0]
    assert fields["/rotor/probe1"] == ["x_m", "y_m", "t_offset_ns"]
    assert fields["/rotor/acc2"] == ["ax_m_s2", "ay_m_s2", "t_offset_ns"]
    assert got_pulses == pulses[:3].tolist()
    for s in rotor.sensors:
        rows = samples[f"/rotor/{s.name}"]
        assert [r[0] for r in rows] == stamps[:300].tolist()
        j = ss.channel_names.index(f"{s.name}_x")
        assert np.array_equal(np.array([r[1:] for r in rows]), sim.z[:300, j:j + 2])


def _write_raw(path: Path, items: list[tuple[str, int, object]]) -> None:
    ts = ma.default_typestore()
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns: dict[str, object] = {}
        for topic, log_ns, msg in items:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msg.__msgtype__, typestore=ts)
            w.write(conns[topic], log_ns, ts.serialize_cdr(msg, msg.__msgtype__))


def test_reading_aligns_out_of_order_blocks_and_marks_missing_samples_and_gaps(tmp_path):
    rotor = load_rotor_description("three_probe_rig")
    n, fac = 400, ma.TypestoreFactory()
    rng = np.random.default_rng(0)
    stamps = T0_NS + np.rint(np.arange(n) * 1e9 / rotor.sample_rate_hz).astype(np.int64)
    z = rng.normal(scale=1e-5, size=(n, 6))
    keep = np.ones(n, bool)
    keep[200:205] = False  # no sensor has these samples: a gap
    items = []
    for j, s in enumerate(rotor.sensors):
        sel = keep.copy()
        if s.name == "probe2":
            sel[100:110] = False  # probe2 drops 10 samples
        idx = np.flatnonzero(sel)
        blocks = [idx[i:i + 50] for i in range(0, len(idx), 50)]
        if s.name == "probe1":
            blocks[2], blocks[3] = blocks[3], blocks[2]  # out of order, within the reorder window
        for b in blocks:
            msg = ma.sensor_block_to_msg(fac, "probe", stamps[b], z[b, 2 * j:2 * j + 2], frame_id=s.name)
            items.append((f"/rotor/{s.name}", int(stamps[b[-1]]), msg))
    _write_raw(tmp_path / "bag", items)
    got = read_sensor_bag(tmp_path / "bag", rotor)
    assert np.array_equal(got.stamps_ns[keep], stamps[keep])
    assert np.abs(got.stamps_ns[~keep] - stamps[~keep]).max() <= 1  # gap rows on the sample grid
    assert got.counters["gap_samples"] == 5 and got.counters["missing_probe2"] == 10
    assert np.isnan(got.z[200:205]).all() and np.isnan(got.z[100:110, 2:4]).all()
    ok = keep.copy()
    assert np.array_equal(got.z[ok][:, [0, 1, 4, 5]], z[ok][:, [0, 1, 4, 5]])
    assert got.pulse_stamps_ns.size == 0


def test_missing_sensor_topic_is_a_bag_error_naming_it(tmp_path, mixed):
    rotor, ss, sim, stamps, pulses = mixed
    small = load_rotor_description("three_probe_rig")
    bag = write_sensor_bag(tmp_path / "bag", small, stamps[:50], sim.z[:50, -6:], pulses[:1])
    with pytest.raises(BagError, match=r"\['/rotor/acc1', '/rotor/acc2', '/rotor/acc3', '/rotor/acc4'\]"):
        read_sensor_bag(bag, rotor)
    with pytest.raises(InputError, match="not in rotor"):
        write_sensor_bag(tmp_path / "b2", rotor, stamps[:5], {"nope_x": np.zeros(5)}, pulses[:1])


@pytest.mark.parametrize("kind", ["probe", "accelerometer"])
def test_sensor_block_and_station_messages_round_trip_for_rclpy_and_rosbags(factory, wire, kind):
    stamps = np.array([5, 10, 2**32 + 4], dtype=np.int64) + T0_NS
    vals = np.array([[1e-6, -2e-6], [np.nan, 3.5], [0.25, -1e300]])
    s_got, v_got = ma.sensor_block_from_msg(wire(ma.sensor_block_to_msg(factory, kind, stamps, vals, frame_id="a")),
                                            kind)
    assert np.array_equal(s_got, stamps) and np.array_equal(v_got, vals, equal_nan=True)
    mean, std = np.arange(6.0) - 2.5, np.arange(1.0, 7.0) * 1e-6
    cov = np.array([[std[0] ** 2, 0.3 * std[0] * std[1]], [0.3 * std[0] * std[1], std[1] ** 2]])
    msg = wire(ma.station_to_msg(factory, T0_NS, "disk1", mean, std, cov))
    assert list(msg.name)[:6] == list(ma.STATION_NAMES) and msg.header.frame_id == "disk1"
    st = ma.station_from_msg(msg)
    assert st.stamp_ns == T0_NS and st.station == "disk1"
    assert np.array_equal(st.mean, mean) and np.array_equal(st.std, std)
    np.testing.assert_allclose(st.disp_cov, cov, rtol=1e-12)


@pytest.fixture
def factory(request):
    return request.param


def pytest_generate_tests(metafunc):
    if "factory" in metafunc.fixturenames:
        params = [ma.TypestoreFactory()]
        try:
            import rclpy  # noqa: F401
            params.append(ma.RclpyFactory())
        except ImportError:
            pass
        metafunc.parametrize("factory", params, ids=[type(p).__name__ for p in params], indirect=True)


@pytest.fixture
def wire(factory):
    if isinstance(factory, ma.RclpyFactory):
        from rclpy.serialization import deserialize_message, serialize_message
        return lambda msg: deserialize_message(serialize_message(msg), type(msg))
    ts = ma.default_typestore()
    return lambda msg: ts.deserialize_cdr(ts.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


# --------------------------------------------------------------------------- CLI
def _run(argv: list[str], capsys) -> tuple[int, str]:
    parser = argparse.ArgumentParser(prog="rotor-estimator")
    add_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["virtual-sensing", *argv])
    code = args.func(args)
    return code, capsys.readouterr().out


@pytest.fixture(scope="module")
def rig_data(tmp_path_factory):
    """The same 1024 synthetic samples as an NPZ (no shaft angle: speed x t) and as a bag
    (pulses where that angle crosses 0)."""
    rotor = load_rotor_description("three_probe_rig")
    ss = build_state_space(rotor)
    sim = simulate(ss, 1024, seed=8)
    d = tmp_path_factory.mktemp("vs")
    np.savez(d / "run.npz", t=sim.t, **{c: sim.z[:, j] for j, c in enumerate(ss.channel_names)})
    stamps = np.rint(sim.t * 1e9).astype(np.int64)
    write_sensor_bag(d / "bag", rotor, stamps, sim.z, pulses_from_inputs(stamps, sim.u, rotor.speed_rad_s))
    return d, ss, sim


def _table(out: str) -> list[str]:
    lines = out.splitlines()
    return lines[lines.index(next(x for x in lines if x.startswith("leave-one-station-out"))):]


def test_virtual_sensing_bag_gives_the_same_table_as_npz_on_the_same_data(rig_data, capsys):
    d, ss, sim = rig_data
    code_npz, out_npz = _run(["--data", str(d / "run.npz")], capsys)
    code_bag, out_bag = _run(["--bag", str(d / "bag")], capsys)
    assert code_npz == code_bag == 0
    assert _table(out_bag) == _table(out_npz)
    assert "bag: pulses" in out_bag
    j_npz = json.loads(_run(["--data", str(d / "run.npz"), "--json"], capsys)[1])
    j_bag = json.loads(_run(["--bag", str(d / "bag"), "--json"], capsys)[1])
    for a, b in zip(j_npz["channels"], j_bag["channels"]):
        assert a["coverage_measured"] == b["coverage_measured"]
        assert a["rms_error"] == pytest.approx(b["rms_error"], rel=1e-6)


def test_report_directory_has_orbit_and_leave_one_out_pngs_and_out_bag_has_station_topics(rig_data, tmp_path,
                                                                                          capsys):
    d, ss, sim = rig_data
    code, out = _run(["--bag", str(d / "bag"), "--hide", "probe2", "--report", str(tmp_path / "rep"),
                      "--out-bag", str(tmp_path / "est_bag"), "--estimates-out", str(tmp_path / "est.npz")], capsys)
    assert code == 0 and "report: 5 files" in out
    pngs = sorted(p.name for p in (tmp_path / "rep").glob("*.png"))
    assert pngs == ["loo_probe2.png", "orbit_disk1.png", "orbit_disk2.png", "orbit_midspan.png"]
    for p in pngs:
        assert (tmp_path / "rep" / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "probe2_x" in (tmp_path / "rep" / "leave_one_out.txt").read_text()
    topics = bag_topics(tmp_path / "est_bag")
    assert {"/virtual_sensing/stations/disk1", "/virtual_sensing/stations/midspan",
            "/virtual_sensing/leave_one_out/probe2", "/diagnostics"} <= set(topics)
    est = np.load(tmp_path / "est.npz")
    msgs = [ma.station_from_msg(m.msg) for m in iter_bag_messages(tmp_path / "est_bag",
                                                                  ["/virtual_sensing/stations/midspan"])]
    assert len(msgs) == 1024 and msgs[7].stamp_ns == int(np.rint(sim.t[7] * 1e9))
    assert np.array_equal([m.mean[0] for m in msgs], est["midspan_displacement_x"])
    assert np.array_equal([m.std[5] for m in msgs], est["midspan_acceleration_y_std"])


# --------------------------------------------------------------------------- hostile --data files
def _hostile_npz(d: Path, good: dict) -> dict[str, tuple[Path, str]]:
    """name -> (file, the refusal it must give)."""
    np.savez(d / "ok.npz", **good)
    raw = (d / "ok.npz").read_bytes()
    (d / "truncated.npz").write_bytes(raw[:len(raw) // 2])
    np.savez_compressed(d / "okc.npz", **good)
    flipped = bytearray((d / "okc.npz").read_bytes())
    flipped[len(flipped) // 3] ^= 0xFF
    (d / "corrupt.npz").write_bytes(bytes(flipped))
    np.save(d / "single.npy", good["t"])
    (d / "renamed.npz").write_bytes((d / "single.npy").read_bytes())
    np.savez(d / "object.npz", **{**good, "probe1_x": np.array([{"x": 1}] * len(good["t"]), dtype=object)})
    np.savez(d / "strings.npz", **{**good, "t": good["t"].astype(str)})
    np.savez(d / "complex.npz", **{**good, "t": good["t"].astype(complex)})
    np.savez(d / "nan_t.npz", **{**good, "t": np.where(np.arange(len(good["t"])) == 5, np.nan, good["t"])})
    np.savez(d / "angle.npz", **good, shaft_angle_rad=np.zeros(3))
    (d / "text.npz").write_text("t,probe1_x\n0,1\n")
    (d / "folder.npz").mkdir()
    return {
        "truncated": (d / "truncated.npz", "truncated or corrupt NPZ archive"),
        "corrupt member": (d / "corrupt.npz", r"array '\w+' cannot be read: truncated or corrupt"),
        ".npy renamed": (d / "renamed.npz", "is a single .npy array, not an NPZ archive"),
        "object array": (d / "object.npz", r"array 'probe1_x' holds Python objects \(dtype=object\)"),
        "string t": (d / "strings.npz", r"array 't' has dtype <U\d+; expected real numbers"),
        "complex t": (d / "complex.npz", "array 't' has dtype complex128; expected real numbers"),
        "NaN in t": (d / "nan_t.npz", "'t' must be 1-D, finite and strictly increasing"),
        "short angle": (d / "angle.npz", "'shaft_angle_rad' must be finite with the shape of 't'"),
        "not a zip": (d / "text.npz", r"not an NPZ archive \(numpy.savez\)"),
        "directory": (d / "folder.npz", "is a directory; expected an NPZ file"),
    }


@pytest.fixture(scope="module")
def hostile(tmp_path_factory):
    rotor = load_rotor_description("three_probe_rig")
    ss = build_state_space(rotor)
    sim = simulate(ss, 64, seed=3)
    good = {"t": sim.t, **{c: sim.z[:, j] for j, c in enumerate(ss.channel_names)}}
    return ss, _hostile_npz(tmp_path_factory.mktemp("hostile"), good)


CASES = ["truncated", "corrupt member", ".npy renamed", "object array", "string t", "complex t", "NaN in t",
         "short angle", "not a zip", "directory"]


@pytest.mark.parametrize("case", CASES)
def test_hostile_npz_is_refused_with_an_input_error_naming_the_cause(hostile, case):
    """Each broken --data file (truncated, corrupt member, renamed .npy, object array, non-numeric
    or complex or non-finite time, wrong-length shaft angle, not a zip, a directory) raises one
    InputError line naming the cause, never a numpy/zipfile traceback."""
    from rotor_estimator.cli.virtual_sensing import load_npz_channels

    ss, files = hostile
    path, message = files[case]
    with pytest.raises(InputError, match=message) as info:
        load_npz_channels(path, ss)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_object_arrays_are_never_unpickled(tmp_path, monkeypatch):
    """An object array in --data is refused from its header: pickle.loads is never called."""
    import pickle

    from rotor_estimator.cli.virtual_sensing import read_npz_arrays

    np.savez(tmp_path / "o.npz", t=np.arange(3.0), x=np.array([1, "a", None], dtype=object))
    calls = []
    monkeypatch.setattr(pickle, "load", lambda *a, **k: calls.append(a))
    monkeypatch.setattr(pickle, "loads", lambda *a, **k: calls.append(a))
    with pytest.raises(InputError, match="holds Python objects"):
        read_npz_arrays(tmp_path / "o.npz", ["t", "x"])
    assert calls == []


@pytest.mark.parametrize("case", ["truncated", "object array", ".npy renamed"])
def test_cli_exits_2_with_one_error_line_on_hostile_npz(hostile, case, capsys):
    """`rotor-estimator virtual-sensing --data BAD` prints one 'rotor-estimator: error: ...' line
    on stderr and exits 2."""
    from rotor_estimator.cli.main import main

    _, files = hostile
    path, message = files[case]
    assert main(["virtual-sensing", "--rotor", "three_probe_rig", "--data", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rotor-estimator: error: --data ")
