# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Properties of the probe/impact alignment queue (rotor_estimator.core.alignment)."""
from __future__ import annotations


import numpy as np
import pytest

from rotor_estimator.core.alignment import AlignedBlock, AlignmentConfig, SampleAligner
from rotor_estimator.core.errors import ConfigError, InputError

PERIOD_NS = 50_000          # 20 kHz
BLOCK = 200
T0_NS = 1_700_000_000_000_000_000


def stream(n: int, start: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps and the two planes' values; values encode the sample index and channel."""
    k = np.arange(start, start + n)
    t = T0_NS + k * PERIOD_NS
    p1 = np.stack([k * 1e-9, -k * 1e-9], axis=1)
    p2 = np.stack([k * 2e-9, -k * 2e-9], axis=1)
    return t.astype(np.int64), p1, p2


def blocks(t, v, size=BLOCK):
    return [(t[i:i + size], v[i:i + size]) for i in range(0, t.size, size)]


def collect(out: list[AlignedBlock]) -> AlignedBlock:
    return AlignedBlock(np.concatenate([o.stamps_ns for o in out]),
                        np.concatenate([o.probes_m for o in out]),
                        np.concatenate([o.impact_force_n for o in out]))


def accounted(al: SampleAligner, plane: int) -> int:
    c = al.counters
    rejected = sum(c[f"{r}_plane{plane}"] for r in ("unmatched", "duplicate", "late", "non_finite", "partner_rejected"))
    return c[f"emitted_plane{plane}"] + rejected + al.pending_count[f"plane{plane}"]


def run_in_order(al, t, p1, p2, size=BLOCK):
    out = []
    for (ta, va), (tb, vb) in zip(blocks(t, p1, size), blocks(t, p2, size)):
        al.add_probe_block(1, ta, va)
        al.add_probe_block(2, tb, vb)
        out.append(al.pop_ready())
    out.append(al.flush())
    return collect(out)


def test_in_order_blocks_are_aligned_sample_exactly():
    t, p1, p2 = stream(2000)
    al = SampleAligner()
    res = run_in_order(al, t, p1, p2)
    assert np.array_equal(res.stamps_ns, t)
    assert np.array_equal(res.probes_m, np.concatenate([p1, p2], axis=1))
    assert np.all(res.impact_force_n == 0.0)
    assert al.counters["emitted_plane1"] == al.counters["emitted_plane2"] == 2000


def test_samples_wait_for_the_reorder_window():
    t, p1, p2 = stream(1000)
    al = SampleAligner(AlignmentConfig(reorder_window_ns=10_000_000))
    al.add_probe_block(1, t, p1)
    al.add_probe_block(2, t, p2)
    out = al.pop_ready()
    # decided: stamps <= newest - 10 ms; the newest decided one is held back for impacts
    assert out.stamps_ns[-1] == t[-1] - 10_000_000 - PERIOD_NS
    assert al.pending_count["plane1"] == 201


def test_shuffled_blocks_are_reordered():
    t, p1, p2 = stream(4000)
    rng = np.random.default_rng(0)
    items = [(1, tb, vb) for tb, vb in blocks(t, p1, 100)] + [(2, tb, vb) for tb, vb in blocks(t, p2, 100)]
    items.sort(key=lambda it: it[1][0] + rng.integers(0, 15_000_000))   # up to 15 ms out of order
    al = SampleAligner(AlignmentConfig(reorder_window_ns=20_000_000))
    out = []
    for plane, tb, vb in items:
        perm = rng.permutation(tb.size)                                 # and shuffled inside blocks
        al.add_probe_block(plane, tb[perm], vb[perm])
        out.append(al.pop_ready())
    res = collect(out + [al.flush()])
    assert np.array_equal(res.stamps_ns, t)
    assert np.array_equal(res.probes_m, np.concatenate([p1, p2], axis=1))
    assert al.counters["reordered_plane1"] > 0 and al.counters["reordered_plane2"] > 0
    assert all(accounted(al, p) == 4000 == al.counters[f"emitted_plane{p}"] for p in (1, 2))


def test_duplicated_samples_are_counted_and_ignored():
    t, p1, p2 = stream(1000)
    al = SampleAligner()
    al.add_probe_block(1, t[:600], p1[:600])
    al.add_probe_block(1, t[500:600], p1[500:600] + 1.0)                 # re-sent while pending
    al.add_probe_block(2, t[:600], p2[:600])
    first = al.pop_ready()
    al.add_probe_block(1, t[:10], p1[:10] + 1.0)                        # re-sent after emission
    al.add_probe_block(1, np.r_[t[600:], t[999]], np.r_[p1[600:], p1[999:] + 1.0])  # repeat in block
    al.add_probe_block(2, t[600:], p2[600:])
    res = collect([first, al.flush()])
    assert np.array_equal(res.stamps_ns, t)
    assert np.array_equal(res.probes_m[:, :2], p1)                      # first copy wins
    assert al.counters["duplicate_plane1"] == 111 and al.counters["late_plane1"] == 0
    assert accounted(al, 1) == 1111


def test_late_samples_are_counted_and_rejected():
    t, p1, p2 = stream(1000)
    al = SampleAligner(AlignmentConfig(reorder_window_ns=1_000_000, duplicate_memory_ns=0))
    al.add_probe_block(1, t[:500], p1[:500])
    al.add_probe_block(2, t[:400], p2[:400])
    a = al.pop_ready()                                                  # horizon at sample 479
    al.add_probe_block(2, t[400:], p2[400:])                            # 400..479 are too late
    al.add_probe_block(1, t[500:], p1[500:])
    res = collect([a, al.flush()])
    assert al.counters["late_plane2"] == 80
    assert al.counters["unmatched_plane1"] == 80
    assert np.array_equal(res.stamps_ns, np.r_[t[:400], t[480:]])
    assert np.all(np.diff(res.stamps_ns) > 0)
    assert accounted(al, 1) == accounted(al, 2) == 1000


def test_nan_rejects_the_whole_four_channel_sample():
    t, p1, p2 = stream(500)
    p1[10, 0] = np.nan
    p2[20, 1] = np.inf
    p1[30, 1] = p2[30, 0] = np.nan
    al = SampleAligner()
    res = run_in_order(al, t, p1, p2)
    assert np.array_equal(res.stamps_ns, np.delete(t, [10, 20, 30]))
    assert np.isfinite(res.probes_m).all()
    c = al.counters
    assert (c["non_finite_plane1"], c["non_finite_plane2"]) == (2, 2)
    assert (c["partner_rejected_plane1"], c["partner_rejected_plane2"]) == (1, 1)
    assert accounted(al, 1) == accounted(al, 2) == 500


def test_missing_plane_sample_is_counted_unmatched_not_dropped():
    t, p1, p2 = stream(1000)
    drop = np.array([5, 6, 7, 700])
    al = SampleAligner()
    al.add_probe_block(1, t, p1)
    al.add_probe_block(2, np.delete(t, drop), np.delete(p2, drop, axis=0))
    res = collect([al.pop_ready(), al.flush()])
    assert al.counters["unmatched_plane1"] == 4 and al.counters["unmatched_plane2"] == 0
    assert np.array_equal(res.stamps_ns, np.delete(t, drop))


def test_stamps_within_quarter_period_match_and_further_do_not():
    t, p1, p2 = stream(400)
    skew = np.where(np.arange(400) < 200, 12_000, 13_000)               # tolerance 12.5 us
    al = SampleAligner()
    al.add_probe_block(1, t, p1)
    al.add_probe_block(2, t + skew, p2)
    res = al.flush()
    assert np.array_equal(res.stamps_ns, t[:200])                       # plane-1 stamps
    assert al.counters["unmatched_plane1"] == al.counters["unmatched_plane2"] == 200


def test_every_input_sample_is_processed_or_counted_rejected():
    rng = np.random.default_rng(7)
    t, p1, p2 = stream(20_000)
    p1[rng.choice(20_000, 30)] = np.nan
    al = SampleAligner(AlignmentConfig(reorder_window_ns=5_000_000))
    received = {1: 0, 2: 0}
    emitted = []
    for b, ((ta, va), (tb, vb)) in enumerate(zip(blocks(t, p1), blocks(t, p2))):
        for plane, tt, vv in ((1, ta, va), (2, tb, vb)):
            keep = rng.random(tt.size) > 0.01                             # lost samples
            tt, vv = tt[keep], vv[keep]
            if rng.random() < 0.1:                                       # duplicated block
                tt, vv = np.r_[tt, tt[:50]], np.r_[vv, vv[:50]]
            if rng.random() < 0.1:                                       # shuffled
                perm = rng.permutation(tt.size)
                tt, vv = tt[perm], vv[perm]
            if rng.random() < 0.05 and b > 2:                            # stale resend
                tt, vv = t[(b - 2) * BLOCK:(b - 2) * BLOCK + 40] + 7, vv[:40]
            al.add_probe_block(plane, tt, vv)
            received[plane] += tt.size
        emitted.append(al.pop_ready())
        for p in (1, 2):
            assert accounted(al, p) == received[p] == al.counters[f"received_plane{p}"]
    emitted.append(al.flush())
    res = collect(emitted)
    assert np.all(np.diff(res.stamps_ns) > 0) and np.isfinite(res.probes_m).all()
    for p in (1, 2):
        assert al.pending_count[f"plane{p}"] == 0
        assert accounted(al, p) == received[p]
        assert al.counters[f"emitted_plane{p}"] == res.stamps_ns.size


def test_per_sample_and_block_inputs_give_identical_output():
    t, p1, p2 = stream(1200)
    t_imp = t[[100, 450, 451]] + np.array([0, 20_000, 0])
    f_imp = np.array([[10.0, -5.0], [3.0, 1.0], [4.0, 2.0]])
    results = []
    for size in (1, 7, 200, 1200):
        al = SampleAligner()
        al.add_impact_block(t_imp, f_imp)
        results.append(run_in_order(al, t, p1, p2, size))
    for r in results[1:]:
        assert all(np.array_equal(a, b) for a, b in zip(results[0], r))


def test_impact_attaches_to_sample_at_or_before_it_zero_order_hold():
    t, p1, p2 = stream(1000)
    al = SampleAligner()
    al.add_impact_block(np.array([t[10], t[20] + 30_000, t[30] + 10_000, t[30] + 20_000]),
                        np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0], [7.0, 8.0]]))
    res = run_in_order(al, t, p1, p2)
    f = res.impact_force_n
    assert f[10].tolist() == [1.0, 2.0] and f[20].tolist() == [3.0, 4.0]
    assert f[30].tolist() == [6.0, 7.0]                                 # two in one period: mean
    assert np.count_nonzero(f.any(axis=1)) == 3
    c = al.counters
    assert (c["attached_impact"], c["merged_impact"], c["late_impact"]) == (4, 1, 0)


def test_impact_between_pops_attaches_to_the_held_back_sample():
    t, p1, p2 = stream(1000)
    al = SampleAligner(AlignmentConfig(reorder_window_ns=0))
    al.add_probe_block(1, t[:500], p1[:500])
    al.add_probe_block(2, t[:500], p2[:500])
    first = al.pop_ready()
    assert first.stamps_ns[-1] == t[498]                               # t[499] is held back
    al.add_impact_block(np.array([t[499] + 25_000]), np.array([[9.0, 9.0]]))
    al.add_probe_block(1, t[500:], p1[500:])
    al.add_probe_block(2, t[500:], p2[500:])
    res = collect([first, al.flush()])
    assert res.impact_force_n[499].tolist() == [9.0, 9.0]


def test_late_impact_is_counted():
    t, p1, p2 = stream(1000)
    al = SampleAligner()
    al.add_probe_block(1, t, p1)
    al.add_probe_block(2, t, p2)
    al.pop_ready()
    al.add_impact_block(np.array([t[5], T0_NS - 1]), np.array([[1.0, 1.0], [2.0, 2.0]]))
    al.add_impact_block(np.array([t[900]]), np.array([[np.nan, 1.0]]))
    res = al.flush()
    c = al.counters
    assert (c["late_impact"], c["non_finite_impact"], c["attached_impact"]) == (2, 1, 0)
    assert np.all(res.impact_force_n == 0.0)


def test_now_ns_releases_samples_when_the_streams_stop():
    t, p1, p2 = stream(400)
    al = SampleAligner()
    arrival = t[-1] + 2_000_000                                         # 2 ms transport latency
    al.add_probe_block(1, t, p1, arrival_ns=arrival)
    al.add_probe_block(2, t, p2, arrival_ns=arrival)
    assert al.pop_ready(now_ns=arrival).stamps_ns.size == 400 - 201     # only the window's worth
    out = al.pop_ready(now_ns=arrival + 10_000_000)                     # 10 ms later, nothing new
    assert out.stamps_ns[-1] == t[-2] and al.pending_count["plane1"] == 1


def test_invalid_input_raises_input_error():
    al = SampleAligner()
    with pytest.raises(InputError, match="plane"):
        al.add_probe_block(3, np.zeros(2, dtype=np.int64), np.zeros((2, 2)))
    with pytest.raises(InputError, match="integer"):
        al.add_probe_block(1, np.zeros(2), np.zeros((2, 2)))
    with pytest.raises(InputError, match="shape"):
        al.add_probe_block(1, np.zeros(2, dtype=np.int64), np.zeros((2, 3)))


def test_config_errors_name_the_bad_field():
    with pytest.raises(ConfigError, match="alignment.match_tolerance_fraction"):
        AlignmentConfig(match_tolerance_fraction=0.5)
    with pytest.raises(ConfigError, match="alignment.reorder_window_ns"):
        AlignmentConfig(reorder_window_ns=0.01)
    with pytest.raises(ConfigError, match="alignment.sample_rate_hz"):
        AlignmentConfig(sample_rate_hz=0.0)
