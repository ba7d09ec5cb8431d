# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Nothing read from or written to a bag is lost silently: CRCs, damage detection and localization,
--salvage, and all-or-nothing writes (no normal-looking partial bag after an error or Ctrl-C)."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from rosbags.rosbag2 import StoragePlugin, Writer

import msg_adapters as ma
from rotor_estimator.io.bags import (BagWriter, bag_damage, read_input_bag, write_input_bag)
from rotor_estimator.core.errors import BagError
from rotor_estimator.core.recording import RigRecording

T0_NS = 1_700_000_000_000_000_000
DT_NS = 50_000  # 20 kHz
N = 20_000      # 1 s, ~850 kB: 13 chunks of 64 KiB


def _recording(n: int = N) -> RigRecording:
    rng = np.random.default_rng(5)
    stamps = T0_NS + np.arange(n, dtype=np.int64) * DT_NS
    force = np.zeros((n, 2))
    force[n // 3:n // 3 + 2] = [0.0, -515.0]
    return RigRecording(stamps, rng.normal(scale=1e-5, size=(n, 4)), stamps[::60] + 17, force, {"scenario": "test"})


def _mcap(bag: Path) -> Path:
    return next(bag.glob("*.mcap"))


def _damage(bag: Path, fraction: float, nbytes: int = 4096) -> None:
    f = _mcap(bag)
    with open(f, "r+b") as fh:
        fh.seek(int(fraction * f.stat().st_size))
        fh.write(b"\0" * nbytes)


def _write_without_crcs(path: Path, rec: RigRecording) -> Path:
    """The same messages through rosbags' own MCAP writer (1 MiB chunks, every CRC 0): the bags of
    earlier versions and of other tools."""
    ts = ma.default_typestore()
    fac = ma.TypestoreFactory(ts)
    w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    w.open()
    c1 = w.add_connection("/rotor/probe1", "sensor_msgs/msg/PointCloud2", typestore=ts)
    c2 = w.add_connection("/rotor/probe2", "sensor_msgs/msg/PointCloud2", typestore=ts)
    ck = w.add_connection("/rotor/keyphasor", "sensor_msgs/msg/TimeReference", typestore=ts)
    pulses = list(rec.pulse_stamps_ns)
    for i in range(0, len(rec), 200):
        j = min(i + 200, len(rec))
        log = int(rec.stamps_ns[j - 1])
        while pulses and pulses[0] <= log:
            p = int(pulses.pop(0))
            w.write(ck, p, ts.serialize_cdr(ma.pulse_to_msg(fac, p), "sensor_msgs/msg/TimeReference"))
        for conn, cols, frame in ((c1, slice(0, 2), "probe1"), (c2, slice(2, 4), "probe2")):
            msg = ma.probe_block_to_msg(fac, rec.stamps_ns[i:j], rec.probes_m[i:j, cols], frame_id=frame)
            w.write(conn, log, ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))
    w.close()
    return path


@pytest.fixture(scope="module")
def good_bag(tmp_path_factory) -> Path:
    return write_input_bag(tmp_path_factory.mktemp("bags") / "good", _recording())


def test_written_bags_carry_chunk_data_and_summary_crcs_in_small_chunks(good_bag):
    """Every chunk has a non-zero CRC that the independent `mcap` reader validates, as does the
    data-section CRC; chunks are <= ~64 KiB so damage costs a fraction of a second, not 1 MiB."""
    with open(_mcap(good_bag), "rb") as f:
        records = list(StreamReader(f, validate_crcs=True, emit_chunks=True).records)  # raises on a bad CRC
    chunks = [r for r in records if type(r).__name__ == "Chunk"]
    data_end = [r for r in records if type(r).__name__ == "DataEnd"]
    assert len(chunks) >= 10 and all(c.uncompressed_crc != 0 for c in chunks)
    assert all(c.uncompressed_size <= 64 * 1024 + 20_000 for c in chunks)
    assert data_end and data_end[0].data_section_crc != 0
    with open(_mcap(good_bag), "rb") as f:
        assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) > 0
    assert bag_damage(good_bag) is None


@pytest.mark.parametrize("fraction", [0.25, 0.5, 0.75, 0.95])
def test_mid_file_damage_is_an_error_naming_the_lost_span_and_salvage_counts_the_loss(good_bag, tmp_path,
                                                                                     capsys, fraction):
    """4 KB zeroed inside the file (not a truncation, the footer survives): reading is a BagError that
    names the damaged time span; --salvage reads the intact chunks and warns with per-topic counts."""
    bag = tmp_path / "bag"
    shutil.copytree(good_bag, bag)
    _damage(bag, fraction)
    where = r"(damaged chunk\(s\) at [0-9.]+-[0-9.]+ s from the start|damaged records at byte \d+, after the chunk of)"
    with pytest.raises(BagError, match=r"is damaged.*" + where + ".*--salvage"):
        read_input_bag(bag)
    rec = read_input_bag(bag, salvage=True)
    err = capsys.readouterr().err
    assert "WARNING" in err and "salvaged" in rec.meta
    if "damaged chunk" in err:  # messages lost: counted per topic, and the recording is shorter
        assert "/rotor/probe1: " in err and "of 100 messages read" in err and 0.5 * N < len(rec) < N
    else:                       # only a message index was hit: every message is recovered
        assert "every message the index lists was recovered" in err and len(rec) == N


@pytest.mark.parametrize("fraction", [round(0.05 * k, 2) for k in range(1, 20)])
def test_damage_anywhere_in_a_crc_less_bag_is_a_bag_error_or_a_complete_read(tmp_path, fraction):
    """Old bags (rosbags' writer: CRC 0, 1 MiB chunks): zeroed bytes at any offset either leave every
    message readable or raise BagError (counts compared with the index) - never another exception
    (rosbags raised OverflowError) and never a silently short read."""
    rec = _recording()
    bag = _write_without_crcs(tmp_path / "bag", rec)
    _damage(bag, fraction)
    try:
        back = read_input_bag(bag)
    except BagError:
        return
    assert len(back) == len(rec) and np.array_equal(back.probes_m, rec.probes_m)


def test_truncated_bag_is_an_error_and_salvage_reads_what_precedes_the_cut(good_bag, tmp_path, capsys):
    """A file cut in half (footer and index lost): a BagError by default; --salvage walks the chunks
    from the start and says the index is missing."""
    bag = tmp_path / "bag"
    shutil.copytree(good_bag, bag)
    f = _mcap(bag)
    os.truncate(f, f.stat().st_size // 2)
    with pytest.raises(BagError):
        read_input_bag(bag)
    rec = read_input_bag(bag, salvage=True)
    assert "index at the end of the file is missing" in capsys.readouterr().err
    assert 0.3 * N < len(rec) < 0.6 * N


def test_an_error_inside_a_bag_writer_leaves_no_bag_and_a_rerun_succeeds(tmp_path):
    """All-or-nothing: an exception while writing removes the staging directory; nothing appears at
    the path, so the same command can simply be run again."""
    path = tmp_path / "out"
    with pytest.raises(RuntimeError):
        with BagWriter(path) as w:
            w.add_connection("/x", "std_msgs/msg/String", typestore=ma.default_typestore())
            raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []
    write_input_bag(path, _recording(2000))
    assert len(read_input_bag(path)) == 2000 and [p.name for p in tmp_path.iterdir()] == ["out"]


def test_sigint_during_replay_out_leaves_no_partial_output_bag(good_bag, tmp_path):
    """Ctrl-C while `replay --out` writes: exit 130, no output bag and no staging directory left
    (before: a normal-looking bag with a third of the estimates, and a rerun failed 'already exists')."""
    out = tmp_path / "estimates"
    # a shell's background job (`cmd &`, nohup) starts with SIGINT ignored and a child inherits that, so the
    # replay would never see the Ctrl-C: it gets the default disposition back (Python then raises
    # KeyboardInterrupt on it, as in a terminal)
    proc = subprocess.Popen([sys.executable, "-m", "rotor_estimator.cli.main", "replay", str(good_bag),
                             "--out", str(out), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".estimates.partial-*")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    assert proc.poll() is None, "replay finished before it could be interrupted"
    time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert list(tmp_path.iterdir()) == []


def test_replay_of_a_damaged_bag_exits_2_and_salvage_runs_with_a_warning(tmp_path, capsys):
    """The CLI: a damaged bag is `rotor-estimator: error: ... damaged ...` and exit 2 (before: rc 0 and
    'converged' on half the data); with --salvage the estimate is made and the loss is on stderr."""
    from rotor_estimator.cli.main import main
    from rotor_estimator.core.simulator import paper_scenario, simulate
    from rotor_estimator.core.config import load_rig_file

    rig = load_rig_file().rig
    bag = write_input_bag(tmp_path / "bag", simulate(rig, paper_scenario("imbalance+impact"), seed=3).recording)
    _damage(bag, 0.6)
    assert main(["replay", str(bag), "--no-progress"]) == 2
    assert "is damaged" in capsys.readouterr().err
    assert main(["replay", str(bag), "--no-progress", "--salvage", "--json"]) == 0
    captured = capsys.readouterr()
    assert "WARNING" in captured.err and "messages read" in captured.err
    assert '"salvaged": "1 damaged chunk(s)' in captured.out
