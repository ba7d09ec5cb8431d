# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Properties of the keyphasor tracker (rotor_estimator.core.tachometer)."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from rotor_estimator.core.errors import ConfigError, InputError
from rotor_estimator.core.tachometer import (PULSE_COUNTERS, ShaftAngleTracker, ShaftStates, TachometerConfig,
                                        shaft_states_from_pulses)

RPM = 2.0 * math.pi / 60.0
SAMPLE_NS = 50_000          # 20 kHz
BLOCK = 200


# --------------------------------------------------------------------------- helpers
def sweep(w0_rad_s: float, w1_rad_s: float, t0_s: float, dur_s: float):
    """Speed constant w0 until t0, linear to w1 over dur, then constant w1: (angle, speed)."""
    a = (w1_rad_s - w0_rad_s) / dur_s

    def angle(t):
        t = np.asarray(t, float)
        ts = np.clip(t - t0_s, 0.0, dur_s)
        return w0_rad_s * np.minimum(t, t0_s) + w0_rad_s * ts + 0.5 * a * ts ** 2 \
            + w1_rad_s * np.maximum(t - t0_s - dur_s, 0.0)

    def speed(t):
        return w0_rad_s + a * np.clip(np.asarray(t, float) - t0_s, 0.0, dur_s)

    return angle, speed


def pulse_times_s(angle, speed, t_end_s: float) -> np.ndarray:
    """Exact times where angle = 2*pi*k (Newton on an interpolated guess)."""
    k = np.arange(0, int(angle(t_end_s) / (2 * np.pi)) + 1)
    grid = np.linspace(0.0, t_end_s, 400_001)
    t = np.interp(2 * np.pi * k, angle(grid), grid)
    for _ in range(6):
        t = t - (angle(t) - 2 * np.pi * k) / speed(t)
    return t


def to_ns(t_s: np.ndarray, jitter_s: float = 0.0, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.round((t_s + jitter_s * rng.standard_normal(np.shape(t_s))) * 1e9).astype(np.int64)


def wrap(x):
    return (np.asarray(x) + np.pi) % (2 * np.pi) - np.pi


def live_states(pulses_ns: np.ndarray, samples_ns: np.ndarray, config=None) -> tuple[ShaftStates, ShaftAngleTracker]:
    """Live use: pulses added as they happen, samples queried block by block."""
    trk = ShaftAngleTracker(config)
    out, i = [], 0
    for b in range(0, samples_ns.size, BLOCK):
        blk = samples_ns[b:b + BLOCK]
        while i < pulses_ns.size and pulses_ns[i] <= blk[-1]:
            trk.add_pulse(int(pulses_ns[i]))
            i += 1
        out.append(trk.query_many(blk))
    return ShaftStates(*(np.concatenate([o[f] for o in out]) for f in range(4))), trk


def samples(t_end_s: float, t_start_s: float = 0.0) -> np.ndarray:
    return np.arange(int(t_start_s * 1e9), int(t_end_s * 1e9), SAMPLE_NS, dtype=np.int64)


def angle_errors(states: ShaftStates, angle, stamps_ns, mask=None):
    v = states.valid if mask is None else states.valid & mask
    return wrap(states.angle_rad - angle(stamps_ns * 1e-9))[v]


# --------------------------------------------------------------------------- accuracy
@pytest.mark.parametrize("rpm", [3000.0, 20000.0])
def test_constant_speed_angle_is_exact(rpm):
    angle, speed = sweep(rpm * RPM, rpm * RPM, 0.0, 1.0)
    p = to_ns(pulse_times_s(angle, speed, 0.5))
    s = samples(0.5)
    live, trk = live_states(p, s)
    off, _ = shaft_states_from_pulses(p, s)
    for st in (live, off):
        assert st.valid[s > p[2]].all()
        assert np.abs(angle_errors(st, angle, s)).max() < 1e-5      # stamps are rounded to 1 ns
        assert np.abs(st.speed_rad_s[st.valid] - rpm * RPM).max() < 1e-3
    assert trk.counters["accepted"] == (p <= s[-1]).sum() and trk.counters["model_breaks"] == 0


def test_linear_coastdown_angle_error_below_1mrad():
    # 20000 -> 3000 rpm in 0.5 s (-3560 rad/s^2), observed inside the sweep
    angle, speed = sweep(20000 * RPM, 3000 * RPM, -0.01, 0.5)
    p = to_ns(pulse_times_s(angle, speed, 0.48))
    s = samples(0.48)
    live, _ = live_states(p, s)
    off, _ = shaft_states_from_pulses(p, s)
    filled = s > p[8]                                               # live: after the window filled
    for st in (live, off):
        assert st.valid[s > p[2]].all()
        assert np.abs(angle_errors(st, angle, s, filled)).max() < 1e-3
        accel = st.accel_rad_s2[st.valid & filled]
        assert np.abs(accel - (3000 - 20000) * RPM / 0.5).max() < 1.0


def test_acceleration_step_is_a_model_break_and_offline_error_stays_small():
    # constant 20000 rpm, coast-down to 3000 rpm in 0.5 s, constant: two steps in accel
    angle, speed = sweep(20000 * RPM, 3000 * RPM, 0.1, 0.5)
    p = to_ns(pulse_times_s(angle, speed, 0.8))
    s = samples(0.8)
    live, trk = live_states(p, s)
    off, counters = shaft_states_from_pulses(p, s)
    assert trk.counters["accepted"] == (p <= s[-1]).sum()             # no true pulse rejected
    assert trk.counters["model_breaks"] >= 1 and counters == trk.counters
    e_live = angle_errors(live, angle, s)
    e_off = angle_errors(off, angle, s)
    assert np.abs(e_off).max() < 0.03
    # live: one revolution of extrapolation after the step (0.5*3560*0.02^2 = 0.7 rad at 3000 rpm)
    assert np.abs(e_live).max() < 1.0
    away = (np.abs(s * 1e-9 - 0.6) > 0.1) & (np.abs(s * 1e-9 - 0.1) > 0.01)
    assert np.abs(angle_errors(live, angle, s, away)).max() < 1e-3


def test_jitter_is_averaged_and_its_rms_estimated():
    rpm, jitter_s = 20000.0, 5e-6
    angle, speed = sweep(rpm * RPM, rpm * RPM, 0.0, 1.0)
    p = to_ns(pulse_times_s(angle, speed, 1.0), jitter_s, seed=1)
    s = samples(1.0)
    live, trk = live_states(p, s)
    off, _ = shaft_states_from_pulses(p, s)
    raw_rad = 2 * np.pi * jitter_s * rpm / 60.0                     # 0.0105 rad per pulse
    rms_off = np.sqrt(np.mean(angle_errors(off, angle, s) ** 2))
    rms_live = np.sqrt(np.mean(angle_errors(live, angle, s) ** 2))
    assert rms_off < 0.6 * raw_rad
    assert rms_live < 1.5 * raw_rad                                 # extrapolates up to 1 rev
    assert 0.7 * jitter_s < trk.jitter_rms_s < 1.3 * jitter_s


# --------------------------------------------------------------------------- robustness
def const_pulses(n: int, period_ns: int = 3_000_000, start_ns: int = 1_000_000_000) -> list[int]:
    return [start_ns + k * period_ns for k in range(n)]


def test_missing_pulse_is_counted_and_angle_continuous():
    p = const_pulses(30)
    kept = p[:12] + p[13:20] + p[22:]                                # one gap of 2, one of 3 periods
    trk = ShaftAngleTracker()
    assert all(trk.add_pulse(t) for t in kept)
    assert trk.counters["missed_pulses"] == 3
    s = np.arange(p[3], p[-1], 10_000, dtype=np.int64)
    st = trk.query_many(s)
    ref = 2 * np.pi * ((s - p[0]) % 3_000_000) / 3_000_000
    beyond_limit = (s > p[19] + 2.5 * 3_000_000) & (s < p[22])     # > max_extrapolation_revs
    assert np.array_equal(st.valid, ~beyond_limit)
    assert np.abs(wrap(st.angle_rad - ref)[st.valid]).max() < 1e-9


def test_double_pulse_is_rejected_early():
    p = const_pulses(20)
    trk = ShaftAngleTracker()
    for i, t in enumerate(p):
        assert trk.add_pulse(t)
        if i in (5, 10, 15):
            assert not trk.add_pulse(t + 200_000)                   # spurious, 0.07 rev later
    assert trk.counters["rejected_early"] == 3
    assert trk.query(p[-1] + 1_500_000).angle_rad == pytest.approx(np.pi, abs=1e-9)


def test_out_of_order_and_duplicate_pulses_are_rejected_and_counted():
    p = const_pulses(20)
    trk = ShaftAngleTracker()
    for t in p[:10]:
        trk.add_pulse(t)
    assert not trk.add_pulse(p[9])                                  # duplicate
    assert not trk.add_pulse(p[8] + 1000)                           # older than the newest
    for t in p[10:]:
        assert trk.add_pulse(t)
    c = trk.counters
    assert c["rejected_duplicate"] == 1 and c["rejected_out_of_order"] == 1 and c["resets"] == 0


def test_sustained_backward_clock_jump_resets_tracker():
    trk = ShaftAngleTracker()
    for t in const_pulses(20):
        trk.add_pulse(t)
    jumped = const_pulses(20, start_ns=500_000_000)                 # clock went back 0.5 s
    results = [trk.add_pulse(t) for t in jumped]
    n = trk.config.max_consecutive_rejections
    assert results[:n - 1] == [False] * (n - 1) and all(results[n - 1:])
    assert trk.counters["rejected_clock_jump"] == n - 1 and trk.counters["resets"] == 1
    st = trk.query(jumped[-1] + 750_000)
    assert st.valid and st.angle_rad == pytest.approx(np.pi / 2, abs=1e-9)


def test_glitch_before_first_pulse_does_not_lock_at_wrong_speed():
    p = const_pulses(20, period_ns=20_000_000)
    trk = ShaftAngleTracker()
    trk.add_pulse(p[0] - 10_000_000)                                # glitch half a revolution early
    for t in p:
        trk.add_pulse(t)
    assert trk.counters["missed_pulses"] == 0
    st = trk.query(p[-1] + 5_000_000)
    assert st.speed_rad_s == pytest.approx(3000 * RPM, rel=1e-9)


def test_stop_timeout_makes_state_invalid_with_zero_speed():
    p = const_pulses(10)
    trk = ShaftAngleTracker(TachometerConfig(stop_timeout_s=0.2, max_extrapolation_revs=100.0))
    for t in p:
        trk.add_pulse(t)
    assert trk.query(p[-1] + 150_000_000).valid
    st = trk.query(p[-1] + 250_000_000)
    assert not st.valid and st.speed_rad_s == 0.0
    assert trk.add_pulse(p[-1] + 300_000_000) and trk.counters["stop_timeouts"] == 1
    assert not trk.query(p[-1] + 301_000_000).valid                 # new track: one pulse


def test_invalid_before_first_pulse_with_one_pulse_and_beyond_extrapolation_limit():
    trk = ShaftAngleTracker()
    assert not trk.query(0).valid
    trk.add_pulse(1_000_000_000)
    assert not trk.query(1_001_000_000).valid                       # fewer than 2 pulses
    trk.add_pulse(1_003_000_000)
    assert not trk.query(999_000_000).valid                         # before the first pulse
    assert trk.query(1_003_000_000 + 7_400_000).valid               # 2.47 rev
    assert not trk.query(1_003_000_000 + 7_600_000).valid           # 2.53 rev > 2.5


def test_query_many_is_bit_identical_to_query():
    angle, speed = sweep(20000 * RPM, 3000 * RPM, 0.05, 0.3)
    p = to_ns(pulse_times_s(angle, speed, 0.5), 5e-6, seed=3)
    trk = ShaftAngleTracker(TachometerConfig(fit_history=1000))
    for t in p:
        trk.add_pulse(int(t))
    s = np.sort(np.random.default_rng(0).integers(-10_000_000, 2_000_000_000, 20_000)).astype(np.int64)
    many = trk.query_many(s)
    one = [trk.query(int(t)) for t in s]
    for f in range(4):
        assert np.array_equal(many[f], np.array([o[f] for o in one]))
    assert many.valid.any() and not many.valid.all()


def test_live_answer_does_not_depend_on_when_later_pulses_are_added():
    angle, speed = sweep(20000 * RPM, 3000 * RPM, 0.05, 0.3)
    p = to_ns(pulse_times_s(angle, speed, 0.5), 5e-6, seed=4)
    s = samples(0.5)
    early = ShaftAngleTracker()
    for t in p:
        early.add_pulse(int(t))
    live, _ = live_states(p, s)
    late_added = early.query_many(s[-2000:])
    assert all(np.array_equal(live[f][-2000:], late_added[f]) for f in range(4))


def test_every_pulse_is_accepted_or_counted_rejected():
    rng = np.random.default_rng(5)
    p = np.array(const_pulses(400), dtype=np.int64)
    p = p + rng.integers(-3000, 3000, p.size)
    p = np.delete(p, rng.choice(p.size, 20, replace=False))
    stream = list(p)
    for i in rng.choice(len(stream), 30, replace=False):
        stream.insert(int(i), int(stream[int(i)]) + int(rng.integers(-5_000_000, 5_000_000)))
    trk = ShaftAngleTracker()
    for t in stream:
        trk.add_pulse(int(t))
    c = trk.counters
    rejected = sum(v for k, v in c.items() if k.startswith("rejected_"))
    assert c["pulses_in"] == len(stream) == c["accepted"] + rejected
    assert set(c) == set(PULSE_COUNTERS)


def test_config_errors_name_the_bad_field():
    with pytest.raises(ConfigError, match="tachometer.window_pulses"):
        TachometerConfig(window_pulses=1)
    with pytest.raises(ConfigError, match="tachometer.max_speed_rad_s"):
        TachometerConfig(min_speed_rad_s=100.0, max_speed_rad_s=50.0)
    with pytest.raises(ConfigError, match="tachometer.stop_timeout_s"):
        TachometerConfig(stop_timeout_s=float("nan"))
    with pytest.raises(ConfigError, match="tachometer.fit_order"):
        TachometerConfig(fit_order=3)


def test_float_stamps_are_rejected_with_input_error():
    trk = ShaftAngleTracker()
    with pytest.raises(InputError):
        trk.add_pulse(1.5e9)
    with pytest.raises(InputError):
        trk.query_many(np.array([1.0, 2.0]))


def test_core_module_imports_no_ros():
    code = ("import sys, rotor_estimator.core.tachometer, rotor_estimator.core.alignment; "
            "print(any(m.split('.')[0] in ('rclpy', 'rosbags') for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
