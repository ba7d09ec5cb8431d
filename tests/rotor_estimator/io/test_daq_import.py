# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""DAQ import: real exports (volts, 45-degree probes, pre-trigger times, raw keyphasor, HDF5) become the
right recording in metres and the rig frame; anything that would give wrong numbers is refused."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rotor_estimator.io.bags import read_input_bag
from rotor_estimator.cli.main import main
from rotor_estimator.io.daq_import import (ImportConfig, keyphasor_from_voltage, read_table, recording_from_table,
                                        rotate_probes)
from rotor_estimator.core.errors import InputError

FS = 20_000.0
RPM = 12_000.0


def _truth(n: int = 4000, t0: float = -0.02):
    """Rig-frame displacements (m), times starting pre-trigger, true pulse times (one before t0)."""
    t = t0 + np.arange(n) / FS
    w = RPM / 60 * 2 * np.pi
    xy = np.column_stack([3e-5 * np.cos(w * t), 2e-5 * np.sin(w * t), 4e-5 * np.cos(w * t + 0.3),
                          1e-5 * np.sin(w * t + 0.3)])
    pulses = np.arange(-1, int((t[-1] - t0) * w / (2 * np.pi)) + 1) * (2 * np.pi / w) + t0 + 1.234e-4
    return t, xy, pulses


def test_keyphasor_from_a_raw_voltage_matches_the_true_pulse_times_to_a_small_fraction_of_a_sample():
    """Rising crossings interpolated between samples: with 0.2 V noise on a 3.3 V-per-sample edge (0.06
    sample std), every pulse within 0.3 sample and no bias above 0.03 sample; hysteresis makes one pulse
    of each noisy edge."""
    rng = np.random.default_rng(0)
    t = np.arange(20000) / FS
    true = 0.0031 + np.arange(0, 0.99, 0.005)
    v = np.zeros_like(t)
    for p in true:  # 0 -> 10 V ramps of 3 samples, 0.5 ms high
        v += np.clip((t - p) * FS / 3 + 1 / 3 * 0, 0, 1) * (t < p + 5e-4) * 10
    v += rng.normal(scale=0.2, size=t.size)
    got = keyphasor_from_voltage(t, v, threshold_v=5.0)
    assert got.size == true.size
    expected = true + 1.5 / FS  # the 3-sample ramp crosses 5 V half-way up
    assert np.max(np.abs(got - expected)) < 0.3 / FS and abs(np.mean(got - expected)) < 0.03 / FS


def test_rotate_probes_recovers_the_rig_frame_for_any_two_directions():
    """m = x cos a + y sin a for each probe, inverted exactly (45/135 and non-orthogonal 30/100)."""
    rng = np.random.default_rng(1)
    xy = rng.normal(size=(50, 2))
    for a, b in ((45.0, 135.0), (30.0, 100.0)):
        m = np.column_stack([xy @ [math.cos(math.radians(a)), math.sin(math.radians(a))],
                             xy @ [math.cos(math.radians(b)), math.sin(math.radians(b))]])
        np.testing.assert_allclose(rotate_probes(m, (a, b)), xy, atol=1e-12)


def test_semicolon_csv_in_volts_from_45_degree_probes_with_pre_trigger_times_imports_exactly(tmp_path, capsys):
    """Mapped columns, sensitivity V/m, 45-degree mounting, t from -20 ms, a raw tach channel and a pulse
    before the first sample: the bag holds the rig-frame metres and the shaft's pulses, shifted together."""
    t, xy, pulses = _truth()
    sens = 7870.0
    a, b = 45.0, 135.0
    volts = []
    for plane in (slice(0, 2), slice(2, 4)):
        p = xy[:, plane]
        volts += [sens * (p @ [math.cos(math.radians(a)), math.sin(math.radians(a))]),
                  sens * (p @ [math.cos(math.radians(b)), math.sin(math.radians(b))])]
    tach = np.zeros_like(t)
    for p in pulses:
        tach[(t >= p) & (t < p + 3e-4)] = 5.0
    rows = ["Time;CH1;CH2;CH3;CH4;KP"] + [";".join(f"{v:.17g}" for v in r)
                                          for r in zip(t, *volts, tach)]
    (tmp_path / "daq.csv").write_text("\n".join(rows) + "\n")
    code = main(["import", str(tmp_path / "daq.csv"), "--columns", "t=Time,xp1=CH1,yp1=CH2,xp2=CH3,yp2=CH4",
                 "--tach-column", "KP", "--tach-threshold-v", "2.5", "--sensitivity-v-per-m", str(sens),
                 "--probe-angles-deg", "45,135", "--out", str(tmp_path / "bag")])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "pre-trigger" in err
    rec = read_input_bag(tmp_path / "bag")
    np.testing.assert_allclose(rec.probes_m, xy, atol=1e-15)
    shift = 0.02
    np.testing.assert_array_equal(rec.stamps_ns, np.round((t + shift) * 1e9).astype(np.int64))
    inside = pulses[pulses >= t[0]]  # a pulse before the first sample cannot be seen in a tach channel
    assert np.max(np.abs(rec.pulse_stamps_ns * 1e-9 - (inside + shift)[:rec.pulse_stamps_ns.size])) < 1 / FS


def test_hdf5_export_round_trips(tmp_path):
    """An HDF5 file with one dataset per column (in a group) reads like the CSV."""
    h5py = pytest.importorskip("h5py")
    t, xy, pulses = _truth(t0=0.0)
    with h5py.File(tmp_path / "rec.h5", "w") as f:
        g = f.create_group("run1")
        for name, col in zip(("t", "xp1", "yp1", "xp2", "yp2"), (t, *xy.T)):
            g[name] = col
    table = read_table(tmp_path / "rec.h5", hdf5_group="run1")
    rec, warnings = recording_from_table(table, ImportConfig(), pulses[1:])
    np.testing.assert_array_equal(rec.probes_m, xy)
    assert warnings == []


@pytest.mark.parametrize("make,message", [
    (lambda d: (d / "dup.csv").write_text("t,xp1,yp1,xp2,yp2,XP1\n0,0,0,0,0,0\n"), "appears twice"),
    (lambda d: (d / "trunc.npz").write_bytes(open(d / "ok.npz", "rb").read()[:9000]), "NPZ"),
    (lambda d: np.save(d / "x.npy", np.zeros(5)) or (d / "x.npy").rename(d / "renamed.npz"), "not an NPZ"),
    (lambda d: (d / "adir").mkdir(), "is a directory"),
    (lambda d: np.savez(d / "obj.npz", t=np.array([object()] * 3, dtype=object)), "not a readable NPZ|numbers only"),
])
def test_unreadable_signals_are_one_clear_line_and_exit_2(tmp_path, capsys, make, message):
    """Duplicate columns, truncated or renamed archives, a directory, object arrays: exit 2, one line, no bag."""
    np.savez(tmp_path / "ok.npz", t=np.arange(2000.0), xp1=np.zeros(2000))
    before = set(tmp_path.iterdir())
    make(tmp_path)
    target = next(iter(set(tmp_path.iterdir()) - before))
    code = main(["import", str(target), "--out", str(tmp_path / "bag")])
    err = capsys.readouterr().err
    import re
    assert code == 2 and re.search(message, err) and "Traceback" not in err and err.count("\n") == 1
    assert not (tmp_path / "bag").exists()


@pytest.mark.parametrize("pulses,message", [
    (None, "no keyphasor"),
    (lambda p: p * 1e3, "do not overlap"),                # pulse times in ms
    (lambda p: p[:1], "1 keyphasor pulse"),
    (lambda p: np.sort(np.concatenate([p, p + 1e-3, p + 2e-3])), "outside the tracked range"),  # 3 per rev
])
def test_keyphasor_that_cannot_be_the_shafts_is_refused(pulses, message):
    t, xy, true = _truth(t0=0.0)
    table = {"t": t, "xp1": xy[:, 0], "yp1": xy[:, 1], "xp2": xy[:, 2], "yp2": xy[:, 3]}
    config = ImportConfig(rig_speed_range_rad_s=(10.0, 2 * RPM / 60 * 2 * np.pi))  # twice the running speed
    with pytest.raises(InputError, match=message):
        recording_from_table(table, config, None if pulses is None else pulses(true[1:]))


def test_sample_rate_different_from_the_rig_is_warned():
    """A 10 kHz recording against a 20 kHz rig file: a warning naming both rates."""
    t, xy, pulses = _truth(t0=0.0)
    table = {"t": t * 2, "xp1": xy[:, 0], "yp1": xy[:, 1], "xp2": xy[:, 2], "yp2": xy[:, 3]}
    _, warnings = recording_from_table(table, ImportConfig(rig_sample_rate_hz=FS), pulses[1:] * 2)
    assert any("10000 Hz differs from the rig file's 20000 Hz" in w for w in warnings)
