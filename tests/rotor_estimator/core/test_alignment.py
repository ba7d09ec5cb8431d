# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Properties of the one alignment queue (rotor_estimator.core.alignment.StreamAligner): N named
streams, and the estimator's configuration of it (two probe planes plus the held impact force)."""
from __future__ import annotations

import numpy as np
import pytest

from rotor_estimator.core.alignment import (IMPACT_COUNTERS, PROBE_COUNTERS, AlignedBlock, AlignmentConfig,
                                            StreamAligner, StreamSpec, probe_aligner)
from rotor_estimator.core.errors import ConfigError, InputError

PERIOD_NS = 50_000          # 20 kHz
BLOCK = 200
T0_NS = 1_700_000_000_000_000_000
REJECTIONS = ("unmatched", "duplicate", "late", "non_finite", "partner_rejected")


# --------------------------------------------------------------------------- N streams
def accounted_n(al: StreamAligner, name: str) -> int:
    """Emitted + every rejection + pending for one stream (the accounting identity's right side)."""
    c = al.counters
    return (c[f"emitted_{name}"] + sum(c.get(f"{r}_{name}", 0) for r in REJECTIONS)
            + al.pending_count[name])


def three(release_complete: bool = False, required=(True, True, True), window_periods: int = 20,
          **kw) -> StreamAligner:
    """Streams a (width 2), b (3), c (1); tolerance a quarter period."""
    specs = [StreamSpec("a", 2, required[0]), StreamSpec("b", 3, required[1]), StreamSpec("c", 1, required[2])]
    return StreamAligner(specs, match_tolerance_ns=PERIOD_NS // 4, reorder_window_ns=window_periods * PERIOD_NS,
                         release_complete=release_complete, **kw)


def values(k: np.ndarray, width: int, scale: float) -> np.ndarray:
    return scale * np.repeat(k[:, None].astype(float), width, axis=1) + np.arange(width)


def collect_n(outs):
    return (np.concatenate([o.stamps_ns for o in outs]), np.concatenate([o.values for o in outs]),
            np.concatenate([o.present for o in outs]))


@pytest.mark.parametrize("release_complete", [False, True])
def test_n_streams_are_matched_within_the_tolerance_and_not_beyond(release_complete):
    """Three streams of widths 2, 3, 1: stamps within the tolerance (12.5 us) of the first
    stream's are one sample, stamped with the first stream's stamp; 13 us away they are not."""
    k = np.arange(100)
    t = T0_NS + k * PERIOD_NS
    skew = np.where(k < 50, 12_000, 13_000)
    al = three(release_complete, required=(True, False, False))
    al.add_block("c", t - skew, values(k, 1, 3.0))
    al.add_block("b", t + skew, values(k, 3, 2.0))
    al.add_block("a", t, values(k, 2, 1.0))
    out = al.flush()
    head = out.stamps_ns < t[50]
    assert np.array_equal(out.stamps_ns[head], t[:50])
    assert np.array_equal(out.values[head], np.concatenate([values(k[:50], w, sc) for w, sc in
                                                            ((2, 1.0), (3, 2.0), (1, 3.0))], axis=1))
    assert out.present[head].all() and not out.present[~head][:, 1:].any()
    assert al.counters["missing_b"] == al.counters["missing_c"] == 50
    assert al.counters["unmatched_b"] == al.counters["unmatched_c"] == 50    # a is required


@pytest.mark.parametrize("release_complete", [False, True])
def test_n_stream_output_is_never_reordered(release_complete):
    """Blocks of three streams shuffled in arrival (within the reorder window) and inside
    each block: every sample comes out once, in strictly increasing stamp order."""
    rng = np.random.default_rng(3)
    k = np.arange(3000)
    t = T0_NS + k * PERIOD_NS
    items = [(name, t[i:i + 20], values(k[i:i + 20], w, 1.0)) for name, w in (("a", 2), ("b", 3), ("c", 1))
             for i in range(0, k.size, 20)]
    items.sort(key=lambda it: it[1][0] + rng.integers(0, 30 * PERIOD_NS))   # blocks overtake blocks
    al = three(release_complete, window_periods=60)
    outs = []
    for name, tb, vb in items:
        perm = rng.permutation(tb.size)
        al.add_block(name, tb[perm], vb[perm])
        outs.append(al.pop_ready())
        if outs[-1].stamps_ns.size:
            assert np.all(np.diff(outs[-1].stamps_ns) > 0)
    stamps, vals, present = collect_n(outs + [al.flush()])
    assert np.all(np.diff(stamps) > 0) and al.counters["reordered_a"] > 0
    if not release_complete:          # reordering within the window loses nothing
        assert np.array_equal(stamps, t) and present.all()
        assert np.array_equal(vals[:, :2], values(k, 2, 1.0))


@pytest.mark.parametrize("release_complete", [False, True])
def test_every_sample_of_every_stream_is_emitted_or_counted_rejected_once(release_complete):
    """Drops, repeats, stale resends and NaN on three streams: after every block,
    received == emitted + rejections + pending for each stream; after flush nothing is pending."""
    rng = np.random.default_rng(11)
    k = np.arange(4000)
    t = T0_NS + k * PERIOD_NS
    al = three(release_complete, required=(True, True, False), duplicate_memory_ns=5 * PERIOD_NS)
    received = dict.fromkeys("abc", 0)
    for i in range(0, k.size, 100):
        for name, w in rng.permutation([("a", 2), ("b", 3), ("c", 1)]).tolist():
            w = int(w)
            tt, vv = t[i:i + 100], values(k[i:i + 100], w, 1.0)
            keep = rng.random(tt.size) > 0.02
            tt, vv = tt[keep], vv[keep]
            if rng.random() < 0.2:
                vv[rng.integers(0, tt.size)] = np.nan
            if rng.random() < 0.2:
                tt, vv = np.r_[tt, tt[:7]], np.r_[vv, vv[:7]]
            if rng.random() < 0.1 and i >= 300:
                tt, vv = np.r_[tt, t[i - 300:i - 290]], np.r_[vv, vv[:10]]
            al.add_block(name, tt, vv)
            received[name] += tt.size
        out = al.pop_ready()
        assert np.isfinite(out.values[:, :5]).all()                   # c is optional: NaN where absent
        assert np.array_equal(np.isfinite(out.values[:, 5]), out.present[:, 2])
        for name in "abc":
            assert accounted_n(al, name) == received[name] == al.counters[f"received_{name}"]
    al.flush()
    assert al.pending_samples == 0 and not any(al.pending_count.values())
    for name in "abc":
        assert accounted_n(al, name) == received[name]
    rej = sum(al.counters[f"{r}_{n}"] for r in ("duplicate", "late", "non_finite") for n in "abc")
    assert rej > 0


def test_flush_empties_the_queue_and_releases_everything_decidable():
    """flush(): every pending sample is decided (complete ones released, optional streams
    absent counted missing), nothing stays pending, and a second flush returns nothing."""
    k = np.arange(500)
    t = T0_NS + k * PERIOD_NS
    al = three(required=(True, False, False))
    al.add_block("a", t, values(k, 2, 1.0))
    al.add_block("b", t[:400], values(k[:400], 3, 1.0))
    assert al.pop_ready().stamps_ns.size < 500
    out = al.flush()
    assert al.pending_samples == 0 and sum(al.pending_count.values()) == 0
    assert al.counters["emitted_a"] == 500 and al.counters["missing_c"] == 500
    assert np.isnan(out.values[-100:, 2:5]).all()
    assert al.flush().stamps_ns.size == 0


def test_release_complete_releases_without_waiting_and_late_is_after_the_last_release():
    """With release_complete a sample with every stream is released at once (not after the
    window), and a stamp not newer than the last release plus the tolerance is late."""
    k = np.arange(10)
    t = T0_NS + k * PERIOD_NS
    al = three(release_complete=True, required=(False, False, False))
    al.add_block("a", t, values(k, 2, 1.0))
    al.add_block("b", t, values(k, 3, 1.0))
    assert al.pop_ready().stamps_ns.size == 0                     # c is missing, window not over
    al.add_block("c", t[:6], values(k[:6], 1, 1.0))
    assert np.array_equal(al.pop_ready().stamps_ns, t[:6])
    al.add_block("c", np.r_[t[5] + PERIOD_NS // 5, t[6]], np.zeros((2, 1)))
    assert al.counters["late_c"] == 1 and al.pop_ready().stamps_ns.tolist() == [t[6]]


def test_non_finite_values_pass_when_not_rejected():
    """reject_non_finite=False: NaN/inf are the consumer's to handle; the sample is released."""
    al = StreamAligner([StreamSpec("a"), StreamSpec("b")], 0, 0, reject_non_finite=False)
    al.add_block("a", np.array([1, 2]), np.array([[np.nan, 1.0], [2.0, 2.0]]))
    al.add_block("b", np.array([1, 2]), np.ones((2, 2)))
    out = al.flush()
    assert out.stamps_ns.tolist() == [1, 2] and np.isnan(out.values[0, 0])
    assert "non_finite_a" not in al.counters


def test_stream_aligner_refuses_bad_streams_and_blocks():
    """Unknown stream, wrong width, non-integer stamps, repeated names and a negative window
    are refused, naming the cause."""
    with pytest.raises(InputError, match="unique"):
        StreamAligner([StreamSpec("a"), StreamSpec("a")], 0, 0)
    with pytest.raises(ConfigError, match="width"):
        StreamAligner([StreamSpec("a", 0)], 0, 0)
    with pytest.raises(ConfigError, match="reorder_window_ns"):
        StreamAligner([StreamSpec("a")], 0, -1)
    al = three()
    with pytest.raises(InputError, match="unknown stream 'd'"):
        al.add_block("d", np.zeros(1, dtype=np.int64), np.zeros((1, 2)))
    with pytest.raises(InputError, match=r"b block: values must have shape \(2, 3\)"):
        al.add_block("b", np.zeros(2, dtype=np.int64), np.zeros((2, 2)))
    with pytest.raises(InputError, match="integer"):
        al.add_block("a", np.zeros(2), np.zeros((2, 2)))


# --------------------------------------------------------------------------- probe configuration
class SampleQueue:
    """The pipeline's use of :func:`probe_aligner`, returning :class:`AlignedBlock`."""

    def __init__(self, config: AlignmentConfig | None = None) -> None:
        self.al = probe_aligner(config)
        self.counters = self.al.counters

    @property
    def pending_count(self) -> dict[str, int]:
        return self.al.pending_count

    def add_probe_block(self, plane: int, t, v, arrival_ns=None) -> None:
        self.al.add_block(f"plane{plane}", t, v, arrival_ns)

    def add_impact_block(self, t, v) -> None:
        self.al.add_block("impact", t, v)

    def pop_ready(self, now_ns=None) -> AlignedBlock:
        return AlignedBlock.from_samples(self.al.pop_ready(now_ns))

    def flush(self) -> AlignedBlock:
        return AlignedBlock.from_samples(self.al.flush())


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


def accounted(al: SampleQueue, plane: int) -> int:
    return accounted_n(al.al, f"plane{plane}")


def run_in_order(al, t, p1, p2, size=BLOCK):
    out = []
    for (ta, va), (tb, vb) in zip(blocks(t, p1, size), blocks(t, p2, size)):
        al.add_probe_block(1, ta, va)
        al.add_probe_block(2, tb, vb)
        out.append(al.pop_ready())
    out.append(al.flush())
    return collect(out)


def test_probe_counters_keep_their_names_and_order():
    """/diagnostics and replay print the estimator's aligner counters: per plane the
    PROBE_COUNTERS in order, then the impact counters."""
    al = probe_aligner()
    assert list(al.counters) == [f"{r}_plane{p}" for p in (1, 2) for r in PROBE_COUNTERS] + list(IMPACT_COUNTERS)


def test_in_order_blocks_are_aligned_sample_exactly():
    """In-order blocks of both planes come out sample-exact, all 2000, without impact force."""
    t, p1, p2 = stream(2000)
    al = SampleQueue()
    res = run_in_order(al, t, p1, p2)
    assert np.array_equal(res.stamps_ns, t)
    assert np.array_equal(res.probes_m, np.concatenate([p1, p2], axis=1))
    assert np.all(res.impact_force_n == 0.0)
    assert al.counters["emitted_plane1"] == al.counters["emitted_plane2"] == 2000


def test_samples_wait_for_the_reorder_window():
    """Only stamps at least the reorder window older than the newest are released; the newest decided
    one is held back for impacts."""
    t, p1, p2 = stream(1000)
    al = SampleQueue(AlignmentConfig(reorder_window_ns=10_000_000))
    al.add_probe_block(1, t, p1)
    al.add_probe_block(2, t, p2)
    out = al.pop_ready()
    # decided: stamps <= newest - 10 ms; the newest decided one is held back for impacts
    assert out.stamps_ns[-1] == t[-1] - 10_000_000 - PERIOD_NS
    assert al.pending_count["plane1"] == 201


def test_shuffled_blocks_are_reordered():
    """Blocks up to 15 ms out of order and shuffled inside come out complete and in order; reorders are
    counted."""
    t, p1, p2 = stream(4000)
    rng = np.random.default_rng(0)
    items = [(1, tb, vb) for tb, vb in blocks(t, p1, 100)] + [(2, tb, vb) for tb, vb in blocks(t, p2, 100)]
    items.sort(key=lambda it: it[1][0] + rng.integers(0, 15_000_000))   # up to 15 ms out of order
    al = SampleQueue(AlignmentConfig(reorder_window_ns=20_000_000))
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
    """A stamp re-sent while pending, after emission (within the memory) or inside a block is a
    duplicate; the first copy wins."""
    t, p1, p2 = stream(1000)
    al = SampleQueue()
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
    """Samples arriving at or before the horizon are late; their partners are unmatched; the output
    stays increasing."""
    t, p1, p2 = stream(1000)
    al = SampleQueue(AlignmentConfig(reorder_window_ns=1_000_000, duplicate_memory_ns=0))
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
    """NaN/inf in one plane rejects the whole 4-channel sample: non_finite for it, partner_rejected for
    the other."""
    t, p1, p2 = stream(500)
    p1[10, 0] = np.nan
    p2[20, 1] = np.inf
    p1[30, 1] = p2[30, 0] = np.nan
    al = SampleQueue()
    res = run_in_order(al, t, p1, p2)
    assert np.array_equal(res.stamps_ns, np.delete(t, [10, 20, 30]))
    assert np.isfinite(res.probes_m).all()
    c = al.counters
    assert (c["non_finite_plane1"], c["non_finite_plane2"]) == (2, 2)
    assert (c["partner_rejected_plane1"], c["partner_rejected_plane2"]) == (1, 1)
    assert accounted(al, 1) == accounted(al, 2) == 500


def test_missing_plane_sample_is_counted_unmatched_not_dropped():
    """A plane-1 sample without its plane-2 partner is counted unmatched (not silently dropped)."""
    t, p1, p2 = stream(1000)
    drop = np.array([5, 6, 7, 700])
    al = SampleQueue()
    al.add_probe_block(1, t, p1)
    al.add_probe_block(2, np.delete(t, drop), np.delete(p2, drop, axis=0))
    res = collect([al.pop_ready(), al.flush()])
    assert al.counters["unmatched_plane1"] == 4 and al.counters["unmatched_plane2"] == 0
    assert np.array_equal(res.stamps_ns, np.delete(t, drop))


def test_stamps_within_quarter_period_match_and_further_do_not():
    """Plane stamps within a quarter period match (plane-1 stamp kept); 13 us apart they are unmatched."""
    t, p1, p2 = stream(400)
    skew = np.where(np.arange(400) < 200, 12_000, 13_000)               # tolerance 12.5 us
    al = SampleQueue()
    al.add_probe_block(1, t, p1)
    al.add_probe_block(2, t + skew, p2)
    res = al.flush()
    assert np.array_equal(res.stamps_ns, t[:200])                       # plane-1 stamps
    assert al.counters["unmatched_plane1"] == al.counters["unmatched_plane2"] == 200


def test_every_input_sample_is_processed_or_counted_rejected():
    """Lost, duplicated, shuffled, stale and NaN input: every sample is emitted, rejected with a reason
    or pending, at every step."""
    rng = np.random.default_rng(7)
    t, p1, p2 = stream(20_000)
    p1[rng.choice(20_000, 30)] = np.nan
    al = SampleQueue(AlignmentConfig(reorder_window_ns=5_000_000))
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
    """The output does not depend on how the input is split into blocks (1, 7, 200, 1200 samples)."""
    t, p1, p2 = stream(1200)
    t_imp = t[[100, 450, 451]] + np.array([0, 20_000, 0])
    f_imp = np.array([[10.0, -5.0], [3.0, 1.0], [4.0, 2.0]])
    results = []
    for size in (1, 7, 200, 1200):
        al = SampleQueue()
        al.add_impact_block(t_imp, f_imp)
        results.append(run_in_order(al, t, p1, p2, size))
    for r in results[1:]:
        assert all(np.array_equal(a, b) for a, b in zip(results[0], r))


def test_impact_attaches_to_sample_at_or_before_it_zero_order_hold():
    """An impact attaches to the sample at or before it (zero-order hold); two in one period are
    averaged."""
    t, p1, p2 = stream(1000)
    al = SampleQueue()
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
    """An impact arriving after a pop still attaches to the held-back newest sample."""
    t, p1, p2 = stream(1000)
    al = SampleQueue(AlignmentConfig(reorder_window_ns=0))
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
    """Impacts older than every pending sample are late, NaN impacts non_finite; none is attached."""
    t, p1, p2 = stream(1000)
    al = SampleQueue()
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
    """now_ns decides samples by the clock when the input stops (one sample stays held back)."""
    t, p1, p2 = stream(400)
    al = SampleQueue()
    arrival = t[-1] + 2_000_000                                         # 2 ms transport latency
    al.add_probe_block(1, t, p1, arrival_ns=arrival)
    al.add_probe_block(2, t, p2, arrival_ns=arrival)
    assert al.pop_ready(now_ns=arrival).stamps_ns.size == 400 - 201     # only the window's worth
    out = al.pop_ready(now_ns=arrival + 10_000_000)                     # 10 ms later, nothing new
    assert out.stamps_ns[-1] == t[-2] and al.pending_count["plane1"] == 1


def test_config_errors_name_the_bad_field():
    """Invalid alignment settings raise ConfigError naming the field."""
    with pytest.raises(ConfigError, match="alignment.match_tolerance_fraction"):
        AlignmentConfig(match_tolerance_fraction=0.5)
    with pytest.raises(ConfigError, match="alignment.reorder_window_ns"):
        AlignmentConfig(reorder_window_ns=0.01)
    with pytest.raises(ConfigError, match="alignment.sample_rate_hz"):
        AlignmentConfig(sample_rate_hz=0.0)
