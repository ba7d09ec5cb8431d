# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Time ordering and sample-exact alignment of the two probe planes and the impact force.

A plain-Python measurement queue keyed by stamp (robot_localization style), testable
without ROS. Probe blocks of plane 1 (``[xp1, yp1]``) and plane 2 (``[xp2, yp2]``) and a
sparse impact-force stream go in, in any order; :meth:`SampleAligner.pop_ready` returns
complete 4-channel samples in strictly increasing stamp order.

Rules (every input sample ends in exactly one counter, see :data:`PROBE_COUNTERS`):

* **Matching**: a plane-1 and a plane-2 sample are one sample when their stamps differ by
  at most ``match_tolerance_fraction`` of the sample period; the output stamp is the
  plane-1 stamp (plane 1 is the reference clock).
* **Ripeness**: stamps ``<= horizon`` are decided, ``horizon = newest stamp seen -
  reorder_window_ns`` (or later: ``now_ns`` given to ``pop_ready``, mapped to the stamp
  clock through the smallest ``arrival_ns - stamp`` seen, or everything on ``flush()``).
  A decided plane-1 sample without its plane-2 partner is ``unmatched_plane1`` (and vice
  versa); decided samples are never revisited.
* **Late**: an arrival with stamp ``<= horizon`` is ``late_plane{p}`` (the filter cannot go
  back in time), or ``duplicate_plane{p}`` if that stamp was already received.
* **Duplicates**: the same stamp again on the same plane, while pending or recently
  decided: ``duplicate_plane{p}``, the first copy wins.
* **Non-finite**: a sample with NaN/inf in its x or y is ``non_finite_plane{p}``; the whole
  4-channel sample is rejected, so its finite partner is ``partner_rejected_plane{q}``.
* **Reordered** (informational, not a rejection): a sample older than one already
  received on its plane, but still in time; it is put in order.
* **Impact** (zero-order hold): the force at ``t_i`` attaches to the emitted sample at or
  before ``t_i`` (several on one sample are averaged, ``merged_impact``). To allow that,
  the newest decided sample is held back until the next one is decided (one sample of
  extra delay) or ``flush()``. An impact older than the held-back sample is
  ``late_impact``; one before the first sample ever emitted is ``orphan_impact``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rotor_estimator.core.errors import ConfigError, InputError

__all__ = ["AlignmentConfig", "AlignedBlock", "SampleAligner", "PROBE_COUNTERS", "IMPACT_COUNTERS"]

#: Per plane ``p`` (1, 2): ``received_plane{p} == emitted_plane{p} + sum(rejected) + pending``.
PROBE_COUNTERS: tuple[str, ...] = (
    "received", "emitted",                                      # in / out
    "unmatched", "duplicate", "late", "non_finite", "partner_rejected",  # rejections
    "reordered",                                                # informational
)
_PROBE_REJECTIONS = ("unmatched", "duplicate", "late", "non_finite", "partner_rejected")
#: ``received_impact == attached_impact + late_impact + orphan_impact + duplicate_impact
#: + non_finite_impact + pending``; ``merged_impact`` is informational.
IMPACT_COUNTERS: tuple[str, ...] = ("received_impact", "attached_impact", "late_impact", "orphan_impact",
                                    "duplicate_impact", "non_finite_impact", "merged_impact")


@dataclass(frozen=True)
class AlignmentConfig:
    """Alignment parameters (validated at construction, raises ConfigError).

    * ``sample_rate_hz``: nominal probe sample rate (Hz).
    * ``match_tolerance_fraction``: plane stamps within this fraction of a sample period
      are the same sample (0 = exact match; < 0.5).
    * ``reorder_window_ns``: how long (stamp time) samples wait for late or out-of-order
      arrivals before they are decided (ns).
    * ``duplicate_memory_ns``: how far back decided stamps are remembered to tell a
      duplicate from a late sample (ns).
    """

    sample_rate_hz: float = 20_000.0
    match_tolerance_fraction: float = 0.25
    reorder_window_ns: int = 10_000_000
    duplicate_memory_ns: int = 20_000_000

    def __post_init__(self) -> None:
        def number(name: str, low: float, high: float, low_open: bool) -> float:
            v = getattr(self, name)
            if (isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating))
                    or not math.isfinite(v) or not (v > low if low_open else v >= low) or v > high):
                op = ">" if low_open else ">="
                raise ConfigError(f"alignment.{name}: must be a finite number {op} {low:g} and <= {high:g}, "
                                  f"got {v!r}")
            return float(v)

        number("sample_rate_hz", 0.0, 1e9, True)
        number("match_tolerance_fraction", 0.0, 0.499, False)
        for name in ("reorder_window_ns", "duplicate_memory_ns"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v <= 3_600 * 10**9:
                raise ConfigError(f"alignment.{name}: must be an integer number of ns from 0 to 3.6e12, got {v!r}")

    @property
    def match_tolerance_ns(self) -> int:
        return int(self.match_tolerance_fraction * 1e9 / self.sample_rate_hz)


class AlignedBlock(NamedTuple):
    """Complete samples in strictly increasing stamp order.

    * ``stamps_ns`` (M,) int64 (plane-1 stamps)
    * ``probes_m`` (M, 4) ``[xp1, yp1, xp2, yp2]`` (m)
    * ``impact_force_n`` (M, 2) ``[fx, fy]`` (N), zero-order hold, zeros without impact
    """

    stamps_ns: np.ndarray
    probes_m: np.ndarray
    impact_force_n: np.ndarray


class _Stream:
    """Pending samples of one stream, sorted by stamp, unique stamps."""

    __slots__ = ("t", "v", "max_seen", "recent")

    def __init__(self) -> None:
        self.t = np.empty(0, dtype=np.int64)
        self.v = np.empty((0, 2))
        self.max_seen: int | None = None
        self.recent = np.empty(0, dtype=np.int64)      # decided stamps, for duplicate detection


def _member(t: np.ndarray, sorted_ref: np.ndarray) -> np.ndarray:
    """``np.isin(t, sorted_ref)`` for a sorted reference, by binary search."""
    if sorted_ref.size == 0:
        return np.zeros(t.size, dtype=bool)
    i = np.minimum(np.searchsorted(sorted_ref, t), sorted_ref.size - 1)
    return sorted_ref[i] == t


def _check_block(stamps_ns: np.ndarray, values: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(stamps_ns)
    v = np.asarray(values, dtype=float)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
        raise InputError(f"{what}: stamps_ns must be a 1-D integer array (ns), got dtype {t.dtype} shape {t.shape}")
    if v.shape != (t.shape[0], 2):
        raise InputError(f"{what}: values must have shape ({t.shape[0]}, 2), got {v.shape}")
    return t.astype(np.int64, copy=False), v


class SampleAligner:
    """Queue that turns two probe-plane streams and an impact stream into aligned samples.

    >>> al = SampleAligner(AlignmentConfig(reorder_window_ns=0))
    >>> t = np.arange(3, dtype=np.int64) * 50_000
    >>> al.add_probe_block(2, t, np.ones((3, 2)))
    >>> al.add_probe_block(1, t, np.zeros((3, 2)))
    >>> al.flush().probes_m[:, 2].tolist()
    [1.0, 1.0, 1.0]
    """

    def __init__(self, config: AlignmentConfig | None = None) -> None:
        self.config = config if config is not None else AlignmentConfig()
        self.counters: dict[str, int] = {f"{name}_plane{p}": 0 for p in (1, 2) for name in PROBE_COUNTERS}
        self.counters.update(dict.fromkeys(IMPACT_COUNTERS, 0))
        self._planes = {1: _Stream(), 2: _Stream()}
        self._impact = _Stream()
        self._horizon_ns: int | None = None          # stamps <= this are decided
        self._clock_offset_ns: int | None = None     # min(arrival_ns - stamp_ns)
        self._held: tuple[int, np.ndarray] | None = None   # newest decided sample (stamp, [x1 y1 x2 y2])
        self._held_force = np.zeros(2)
        self._held_impacts = 0
        self._last_emitted_ns: int | None = None

    # ----------------------------------------------------------------- status
    @property
    def pending_count(self) -> dict[str, int]:
        """Samples waiting, per stream (``plane1``, ``plane2``, ``impact``); the held-back
        sample counts once in each plane."""
        held = int(self._held is not None)
        return {"plane1": len(self._planes[1].t) + held, "plane2": len(self._planes[2].t) + held,
                "impact": len(self._impact.t)}

    @property
    def horizon_ns(self) -> int | None:
        """Stamps at or before this are decided (None before the first decision)."""
        return self._horizon_ns

    # ----------------------------------------------------------------- input
    def add_probe_block(self, plane: int, stamps_ns: np.ndarray, xy_m: np.ndarray,
                        arrival_ns: int | None = None) -> None:
        """Queue samples ``xy_m`` (N, 2) of probe ``plane`` (1 or 2) at ``stamps_ns`` (N,).

        ``arrival_ns``: receive time of the block on the clock ``pop_ready(now_ns)`` uses."""
        if plane not in (1, 2) or isinstance(plane, bool):
            raise InputError(f"plane must be 1 or 2, got {plane!r}")
        t, v = _check_block(stamps_ns, xy_m, f"plane {plane} block")
        if t.size == 0:
            return
        c = self.counters
        c[f"received_plane{plane}"] += t.size
        if arrival_ns is not None:
            offset = int(arrival_ns) - int(t.max())
            self._clock_offset_ns = offset if self._clock_offset_ns is None else min(self._clock_offset_ns, offset)
        s = self._planes[plane]
        increasing = t.size < 2 or bool(np.all(t[1:] > t[:-1]))
        if increasing and (s.max_seen is None or t[0] > s.max_seen) and (
                self._horizon_ns is None or t[0] > self._horizon_ns):
            # common case, no per-sample screening needed: all new, in order, in time
            s.max_seen = int(t[-1])
            self._insert(s, t, v)
            return
        kept = self._screen(s, t, f"_plane{plane}", increasing)
        t, v = t[kept], v[kept]
        # reordered: older than something already received on this plane
        prior = np.maximum.accumulate(t)
        if s.max_seen is not None:
            prior = np.maximum(prior, s.max_seen)
        older = np.empty(t.size, dtype=bool)
        if t.size:
            older[0] = s.max_seen is not None and t[0] < s.max_seen
            older[1:] = t[1:] < prior[:-1]
            c[f"reordered_plane{plane}"] += int(older.sum())
            s.max_seen = int(prior[-1])
        self._insert(s, t, v)

    def add_impact_block(self, stamps_ns: np.ndarray, f_n: np.ndarray) -> None:
        """Queue impact-force samples ``f_n`` (N, 2) [fx, fy] in newtons at ``stamps_ns`` (N,)."""
        t, v = _check_block(stamps_ns, f_n, "impact block")
        if t.size == 0:
            return
        c = self.counters
        c["received_impact"] += t.size
        finite = np.isfinite(v).all(axis=1)
        c["non_finite_impact"] += int((~finite).sum())
        t, v = t[finite], v[finite]
        s = self._impact
        # duplicates within the block or against pending impacts
        _, first = np.unique(t, return_index=True)
        dup = np.ones(t.size, dtype=bool)
        dup[first] = False
        dup |= _member(t, s.t)
        c["duplicate_impact"] += int(dup.sum())
        self._insert(s, t[~dup], v[~dup])       # late or orphan: decided in pop_ready

    def _screen(self, s: _Stream, t: np.ndarray, suffix: str, increasing: bool) -> np.ndarray:
        """Mask of samples to queue; counts duplicates and late arrivals."""
        c = self.counters
        dup = np.zeros(t.size, dtype=bool)
        if not increasing:
            _, first = np.unique(t, return_index=True)
            dup[:] = True
            dup[first] = False                              # repeats inside the block
        dup |= _member(t, s.t) | _member(t, s.recent)       # pending or recently decided
        late = ~dup & (t <= self._horizon_ns) if self._horizon_ns is not None else np.zeros(t.size, bool)
        c[f"duplicate{suffix}"] += int(dup.sum())
        c[f"late{suffix}"] += int(late.sum())
        return ~(dup | late)

    @staticmethod
    def _insert(s: _Stream, t: np.ndarray, v: np.ndarray) -> None:
        if t.size == 0:
            return
        if s.t.size == 0 and (t.size < 2 or np.all(t[1:] > t[:-1])):
            s.t, s.v = t.copy(), v.copy()
            return
        all_t = np.concatenate((s.t, t))
        order = np.argsort(all_t, kind="stable")
        s.t, s.v = all_t[order], np.concatenate((s.v, v))[order]

    # ----------------------------------------------------------------- output
    def pop_ready(self, now_ns: int | None = None) -> AlignedBlock:
        """Decide every sample at or before the horizon and return the complete ones."""
        newest = [s.max_seen for s in self._planes.values() if s.max_seen is not None]
        candidates = [max(newest) - self.config.reorder_window_ns] if newest else []
        if now_ns is not None:
            candidates.append(int(now_ns) - (self._clock_offset_ns or 0) - self.config.reorder_window_ns)
        if not candidates:
            return self._empty()
        return self._decide(max(candidates), final=False)

    def flush(self) -> AlignedBlock:
        """Decide everything pending (end of data) and return it, held-back sample included."""
        stamps = [int(s.t[-1]) for s in (*self._planes.values(), self._impact) if s.t.size]
        horizon = max(stamps) if stamps else (self._horizon_ns if self._horizon_ns is not None else 0)
        return self._decide(horizon, final=True)

    @staticmethod
    def _empty() -> AlignedBlock:
        return AlignedBlock(np.empty(0, dtype=np.int64), np.empty((0, 4)), np.empty((0, 2)))

    def _decide(self, horizon: int, final: bool) -> AlignedBlock:
        c = self.counters
        if self._horizon_ns is not None:
            horizon = max(horizon, self._horizon_ns)
        self._horizon_ns = horizon
        p1, p2 = self._planes[1], self._planes[2]
        tol = self.config.match_tolerance_ns

        # 1. Match every pending plane-1 stamp to its nearest plane-2 stamp (one-to-one).
        j = self._match(p1.t, p2.t, tol)                     # index into p2, or -1
        matched1 = j >= 0
        decided1 = p1.t <= horizon
        take1 = decided1                                     # plane-1 samples leaving the queue
        pair1 = np.flatnonzero(decided1 & matched1)
        pair2 = j[pair1]
        partner_pending = np.zeros(p2.t.size, dtype=bool)
        partner_pending[j[matched1 & ~decided1]] = True      # waits for its undecided partner
        take2 = np.zeros(p2.t.size, dtype=bool)
        take2[pair2] = True
        take2 |= (p2.t <= horizon) & ~partner_pending

        # 2. Count: unmatched, non-finite (whole 4-channel sample rejected).
        in_pair2 = np.zeros(p2.t.size, dtype=bool)
        in_pair2[pair2] = True
        fin1 = np.isfinite(p1.v).all(axis=1)
        fin2 = np.isfinite(p2.v).all(axis=1)
        lone1 = take1 & ~matched1
        lone2 = take2 & ~in_pair2
        if lone1.any() or lone2.any():
            c["non_finite_plane1"] += int((lone1 & ~fin1).sum())
            c["unmatched_plane1"] += int((lone1 & fin1).sum())
            c["non_finite_plane2"] += int((lone2 & ~fin2).sum())
            c["unmatched_plane2"] += int((lone2 & fin2).sum())
        f1, f2 = fin1[pair1], fin2[pair2]
        good = f1 & f2
        if not good.all():
            c["non_finite_plane1"] += int((~f1).sum())
            c["non_finite_plane2"] += int((~f2).sum())
            c["partner_rejected_plane1"] += int((f1 & ~f2).sum())
            c["partner_rejected_plane2"] += int((f2 & ~f1).sum())
            pair1, pair2 = pair1[good], pair2[good]
        out_t = p1.t[pair1]
        out_v = np.concatenate((p1.v[pair1], p2.v[pair2]), axis=1)

        # 3. Remember decided stamps (duplicate detection) and drop them from the queues.
        mem = horizon - self.config.duplicate_memory_ns
        for s, take in ((p1, take1), (p2, take2)):
            rec = np.concatenate((s.recent[s.recent > mem], s.t[take]))
            s.recent = rec if rec.size < 2 or np.all(rec[1:] >= rec[:-1]) else np.sort(rec)
            keep = ~take
            s.t, s.v = s.t[keep], s.v[keep]

        # 4. Put the held-back sample in front, hold back the newest unless final.
        if self._held is not None:
            out_t = np.concatenate(([self._held[0]], out_t))
            out_v = np.concatenate((self._held[1][None, :], out_v))
        force_sum = np.zeros((out_t.size, 2))
        force_cnt = np.zeros(out_t.size, dtype=np.int64)
        if self._held is not None:
            force_sum[0], force_cnt[0] = self._held_force, self._held_impacts

        # 5. Attach decided impacts to the sample at or before them (zero-order hold);
        #    one older than every candidate belongs to an already emitted sample (late)
        #    or precedes the first sample (orphan).
        imp = self._impact
        ready = imp.t <= horizon if not final else np.ones(imp.t.size, dtype=bool)
        if ready.any():
            ti, fi = imp.t[ready], imp.v[ready]
            k = np.searchsorted(out_t, ti, side="right") - 1
            ok = k >= 0
            c["late_impact" if self._last_emitted_ns is not None else "orphan_impact"] += int((~ok).sum())
            before = force_cnt.copy()
            np.add.at(force_sum, k[ok], fi[ok])
            np.add.at(force_cnt, k[ok], 1)
            c["attached_impact"] += int(ok.sum())
            c["merged_impact"] += int(ok.sum()) - int(((before == 0) & (force_cnt > 0)).sum())
            imp.t, imp.v = imp.t[~ready], imp.v[~ready]
        force = force_sum / np.maximum(force_cnt, 1)[:, None]

        if not final and out_t.size:
            self._held = (int(out_t[-1]), out_v[-1].copy())
            self._held_force, self._held_impacts = force_sum[-1].copy(), int(force_cnt[-1])
            out_t, out_v, force = out_t[:-1], out_v[:-1], force[:-1]
        else:
            self._held = None
            self._held_force, self._held_impacts = np.zeros(2), 0
        if out_t.size:
            self._last_emitted_ns = int(out_t[-1])
            c["emitted_plane1"] += out_t.size
            c["emitted_plane2"] += out_t.size
        return AlignedBlock(out_t, out_v, force)

    @staticmethod
    def _match(t1: np.ndarray, t2: np.ndarray, tol: int) -> np.ndarray:
        """For each stamp of ``t1`` the index of the nearest ``t2`` stamp within ``tol``
        (-1 if none); a ``t2`` stamp goes to the closest ``t1`` only."""
        j = np.full(t1.size, -1, dtype=np.int64)
        if t1.size == 0 or t2.size == 0:
            return j
        hi = np.searchsorted(t2, t1)
        lo = np.maximum(hi - 1, 0)
        hi = np.minimum(hi, t2.size - 1)
        d_lo, d_hi = np.abs(t2[lo] - t1), np.abs(t2[hi] - t1)
        best = np.where(d_hi < d_lo, hi, lo)
        dist = np.minimum(d_lo, d_hi)
        ok = dist <= tol
        j[ok] = best[ok]
        if tol > 0 and ok.sum() > 1:
            # one-to-one: if two t1 stamps chose the same t2, the closer keeps it
            idx = np.flatnonzero(ok)
            order = np.lexsort((dist[idx], j[idx]))
            sj = j[idx][order]
            loser = np.r_[False, sj[1:] == sj[:-1]]
            j[idx[order][loser]] = -1
        return j
