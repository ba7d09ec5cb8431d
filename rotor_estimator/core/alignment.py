# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""One time-ordering queue for N named sample streams (robot_localization style, no ROS).

:class:`StreamAligner` takes blocks of named streams of fixed width (probe planes, sensors),
in any order, and releases aligned samples in strictly increasing stamp order. Both
streaming pipelines use it: the estimator (two required probe planes plus an impact force
held on the samples, :func:`probe_aligner`) and virtual sensing (S optional sensors,
:class:`~rotor_estimator.virtual_sensing.stream.SensorAligner`).

Rules (every input sample ends in exactly one counter ``<reason>_<stream>``, or is pending):

* **Matching**: samples of different streams whose stamps differ by at most
  ``match_tolerance_ns`` are one sample (nearest first, one-to-one, streams taken in their
  listed order); the sample's stamp is that of the first listed stream present in it.
* **Screening** at arrival: a stamp already decided is ``late`` (the filter cannot go back
  in time); the same stamp again on a stream while pending is ``duplicate`` (the first copy
  wins). With ``duplicate_memory_ns`` (not None) the stamps of the last decision and those
  within that much before the horizon are remembered, and a re-sent one (or a repeat inside
  a block) is ``duplicate`` rather than ``late``. An in-time stamp older than one already
  received on its stream is put in order (``reordered``, informational).
* **Horizon**: stamps ``<= newest stamp seen - reorder_window_ns`` (or the ``now_ns`` given
  to ``pop_ready``, mapped to the stamp clock through the smallest ``arrival_ns - stamp``
  seen; or everything on ``flush()``) are decided. With ``release_complete`` a sample that
  has every stream is released at once, and the samples before it with it; "decided" is
  then "not after the last released stamp plus the tolerance".
* **Deciding** a sample: without a ``required`` stream its samples are rejected
  (``unmatched``); with ``reject_non_finite``, NaN/inf in one stream rejects the whole
  sample (``non_finite`` for that stream, ``partner_rejected`` for the finite ones);
  otherwise it is released (``emitted``) and each absent optional stream counts
  ``missing``.
* **Held stream** (``hold``, e.g. the impact force; zero-order hold): a value at ``t``
  attaches to the released sample at or before ``t`` (several are averaged, ``merged``).
  To allow that the newest decided sample is held back until the next is decided (one
  sample of delay) or ``flush()``. A value older than the held-back sample is ``late``,
  one before the first sample ever released ``orphan``; ``received == attached + late +
  orphan + duplicate + non_finite + pending``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from rotor_estimator.core.errors import ConfigError, InputError

__all__ = ["StreamSpec", "StreamAligner", "AlignedSamples", "AlignmentConfig", "AlignedBlock", "probe_aligner",
           "PROBE_COUNTERS", "IMPACT_COUNTERS"]

#: Counters of one probe plane ``p``: ``received_plane{p} == emitted_plane{p} + sum(rejected) + pending``.
PROBE_COUNTERS: tuple[str, ...] = (
    "received", "emitted",                                      # in / out
    "unmatched", "duplicate", "late", "non_finite", "partner_rejected",  # rejections
    "reordered",                                                # informational
)
#: ``received_impact == attached_impact + late_impact + orphan_impact + duplicate_impact
#: + non_finite_impact + pending``; ``merged_impact`` is informational.
IMPACT_COUNTERS: tuple[str, ...] = ("received_impact", "attached_impact", "late_impact", "orphan_impact",
                                    "duplicate_impact", "non_finite_impact", "merged_impact")
_STREAM_REASONS = ("received", "emitted", "unmatched", "missing", "duplicate", "late", "non_finite",
                   "partner_rejected", "reordered")
_HOLD_REASONS = ("received", "attached", "late", "orphan", "duplicate", "non_finite", "merged")


@dataclass(frozen=True)
class StreamSpec:
    """One input stream: ``name``, ``width`` values per sample, and whether a sample without
    it is rejected (``required``) or released with it absent (``missing``)."""

    name: str
    width: int = 2
    required: bool = True


class AlignedSamples(NamedTuple):
    """Released samples in strictly increasing stamp order.

    * ``stamps_ns`` (M,) int64
    * ``values`` (M, sum of widths): the streams' columns in their listed order, NaN where absent
    * ``present`` (M, S) bool
    * ``held`` (M, hold width): the held stream, zero-order hold, zeros where none
    """

    stamps_ns: np.ndarray
    values: np.ndarray
    present: np.ndarray
    held: np.ndarray


class _Stream:
    """Pending samples of one stream, sorted by stamp, unique stamps."""

    __slots__ = ("spec", "t", "v", "max_seen", "recent")

    def __init__(self, spec: StreamSpec) -> None:
        self.spec = spec
        self.t = np.empty(0, dtype=np.int64)
        self.v = np.empty((0, spec.width))
        self.max_seen: int | None = None
        self.recent = np.empty(0, dtype=np.int64)      # decided stamps, for duplicate detection


def _member(t: np.ndarray, sorted_ref: np.ndarray) -> np.ndarray:
    """``np.isin(t, sorted_ref)`` for a sorted reference, by binary search."""
    if sorted_ref.size == 0:
        return np.zeros(t.size, dtype=bool)
    i = np.minimum(np.searchsorted(sorted_ref, t), sorted_ref.size - 1)
    return sorted_ref[i] == t


def _increasing(t: np.ndarray) -> bool:
    return t.size < 2 or bool(np.all(t[1:] > t[:-1]))


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


class StreamAligner:
    """Queue that turns N named streams (and an optional held stream) into aligned samples
    (rules in the module docstring).

    * ``streams``: the streams, in order (the first listed present gives the stamp).
    * ``match_tolerance_ns``, ``reorder_window_ns``: ns, integers >= 0.
    * ``duplicate_memory_ns``: ns, or None to remember no decided stamp.
    * ``reject_non_finite``: NaN/inf reject the whole sample (else passed on as they are).
    * ``release_complete``: release a sample as soon as every stream is in.
    * ``hold``: a sparse stream held on the samples (zero-order hold), or None.

    >>> al = StreamAligner([StreamSpec("a"), StreamSpec("b", required=False)], match_tolerance_ns=250,
    ...                    reorder_window_ns=0)
    >>> al.add_block("b", np.array([0, 1000]), np.ones((2, 2)))
    >>> al.add_block("a", np.array([10, 1010, 2010]), np.zeros((3, 2)))
    >>> out = al.flush()
    >>> out.stamps_ns.tolist(), out.present[:, 1].tolist(), al.counters["missing_b"]
    ([10, 1010, 2010], [True, True, False], 1)
    """

    def __init__(self, streams: Sequence[StreamSpec], match_tolerance_ns: int, reorder_window_ns: int, *,
                 duplicate_memory_ns: int | None = None, reject_non_finite: bool = True, release_complete: bool = False,
                 hold: StreamSpec | None = None) -> None:
        specs = tuple(streams)
        names = [s.name for s in specs] + ([hold.name] if hold is not None else [])
        if not specs or len(set(names)) != len(names) or not all(names):
            raise InputError(f"StreamAligner: stream names must be unique and non-empty, got {names}")
        if any(isinstance(s.width, bool) or not isinstance(s.width, int) or s.width < 1 for s in specs):
            raise ConfigError(f"StreamAligner: stream widths must be positive integers, got "
                              f"{[s.width for s in specs]}")
        for name, v in (("match_tolerance_ns", match_tolerance_ns), ("reorder_window_ns", reorder_window_ns),
                        ("duplicate_memory_ns", 0 if duplicate_memory_ns is None else duplicate_memory_ns)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ConfigError(f"StreamAligner: {name} must be an integer >= 0 (ns), got {v!r}")
        self.specs = specs
        self.match_tolerance_ns = int(match_tolerance_ns)
        self.reorder_window_ns = int(reorder_window_ns)
        self.duplicate_memory_ns = None if duplicate_memory_ns is None else int(duplicate_memory_ns)
        self.reject_non_finite = reject_non_finite
        self.release_complete = release_complete
        reasons = [r for r in _STREAM_REASONS
                   if (r != "unmatched" or any(s.required for s in specs))
                   and (r != "missing" or not all(s.required for s in specs))
                   and (r not in ("non_finite", "partner_rejected") or reject_non_finite)]
        self.counters: dict[str, int] = {f"{r}_{s.name}": 0 for s in specs for r in reasons}
        if hold is not None:
            self.counters.update({f"{r}_{hold.name}": 0 for r in _HOLD_REASONS})
        self.released = 0                              # samples released (all streams together)
        self._streams = {s.name: _Stream(s) for s in specs}
        self._hold = _Stream(hold) if hold is not None else None
        self._cols = np.cumsum([0] + [s.width for s in specs])
        self._required = np.array([s.required for s in specs])
        self._horizon_ns: int | None = None          # stamps <= this are decided
        self._clock_offset_ns: int | None = None     # min(arrival_ns - stamp_ns)
        self._held: tuple[int, np.ndarray, np.ndarray] | None = None   # held-back sample (stamp, values, present)
        self._held_sum = np.zeros(hold.width if hold is not None else 0)
        self._held_n = 0
        self._last_emitted_ns: int | None = None

    # ----------------------------------------------------------------- status
    @property
    def pending_count(self) -> dict[str, int]:
        """Samples waiting, per stream; the held-back sample counts once in each stream."""
        held = int(self._held is not None)
        out = {n: len(s.t) + held for n, s in self._streams.items()}
        if self._hold is not None:
            out[self._hold.spec.name] = len(self._hold.t)
        return out

    @property
    def pending_samples(self) -> int:
        """Aligned samples waiting (pending stamps of all streams, matched)."""
        return int(self._held is not None) + self._cluster()[0].size

    @property
    def horizon_ns(self) -> int | None:
        """Stamps at or before this are decided (None before the first decision)."""
        return self._horizon_ns

    # ----------------------------------------------------------------- input
    def add_block(self, name: str, stamps_ns: np.ndarray, values: np.ndarray, arrival_ns: int | None = None) -> None:
        """Queue ``values`` (N, width) of stream ``name`` at integer ``stamps_ns`` (N,).

        ``arrival_ns``: receive time of the block on the clock ``pop_ready(now_ns)`` uses."""
        s = self._streams.get(name)
        if s is None:
            if self._hold is not None and name == self._hold.spec.name:
                return self._add_held(stamps_ns, values)
            raise InputError(f"unknown stream {name!r}; the aligner has {list(self._streams)}")
        t, v = self._check_block(s.spec, stamps_ns, values)
        if t.size == 0:
            return
        c = self.counters
        c[f"received_{name}"] += t.size
        if arrival_ns is not None:
            offset = int(arrival_ns) - int(t.max())
            self._clock_offset_ns = offset if self._clock_offset_ns is None else min(self._clock_offset_ns, offset)
        increasing = _increasing(t)
        if increasing and (s.max_seen is None or t[0] > s.max_seen) and (
                self._horizon_ns is None or t[0] > self._horizon_ns):
            # common case, no per-sample screening needed: all new, in order, in time
            s.max_seen = int(t[-1])
            self._insert(s, t, v)
            return
        kept = self._screen(s, t, increasing)
        t, v = t[kept], v[kept]
        # reordered: older than something already received on this stream
        prior = np.maximum.accumulate(t)
        if s.max_seen is not None:
            prior = np.maximum(prior, s.max_seen)
        older = np.empty(t.size, dtype=bool)
        if t.size:
            older[0] = s.max_seen is not None and t[0] < s.max_seen
            older[1:] = t[1:] < prior[:-1]
            c[f"reordered_{name}"] += int(older.sum())
            s.max_seen = int(prior[-1])
        self._insert(s, t, v)

    def _add_held(self, stamps_ns: np.ndarray, values: np.ndarray) -> None:
        h = self._hold
        name = h.spec.name
        t, v = self._check_block(h.spec, stamps_ns, values)
        if t.size == 0:
            return
        c = self.counters
        c[f"received_{name}"] += t.size
        finite = np.isfinite(v).all(axis=1)
        c[f"non_finite_{name}"] += int((~finite).sum())
        t, v = t[finite], v[finite]
        _, first = np.unique(t, return_index=True)     # duplicates in the block or pending
        dup = np.ones(t.size, dtype=bool)
        dup[first] = False
        dup |= _member(t, h.t)
        c[f"duplicate_{name}"] += int(dup.sum())
        self._insert(h, t[~dup], v[~dup])               # late or orphan: decided in pop_ready

    @staticmethod
    def _check_block(spec: StreamSpec, stamps_ns: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(stamps_ns)
        v = np.asarray(values, dtype=float)
        if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
            raise InputError(f"{spec.name} block: stamps_ns must be a 1-D integer array (ns), got dtype {t.dtype} "
                             f"shape {t.shape}")
        if v.shape != (t.shape[0], spec.width):
            raise InputError(f"{spec.name} block: values must have shape ({t.shape[0]}, {spec.width}), got {v.shape}")
        return t.astype(np.int64, copy=False), v

    def _screen(self, s: _Stream, t: np.ndarray, increasing: bool) -> np.ndarray:
        """Mask of samples to queue; counts duplicates and late arrivals."""
        c = self.counters
        dup = np.zeros(t.size, dtype=bool)
        if not increasing:
            _, first = np.unique(t, return_index=True)
            dup[:] = True
            dup[first] = False                              # repeats inside the block
        dup |= _member(t, s.t) | _member(t, s.recent)       # pending or recently decided
        late = t <= self._horizon_ns if self._horizon_ns is not None else np.zeros(t.size, bool)
        if self.duplicate_memory_ns is None:
            dup &= ~late                                    # nothing decided is remembered: late first
        else:
            late &= ~dup
        c[f"duplicate_{s.spec.name}"] += int(dup.sum())
        c[f"late_{s.spec.name}"] += int(late.sum())
        return ~(dup | late)

    @staticmethod
    def _insert(s: _Stream, t: np.ndarray, v: np.ndarray) -> None:
        if t.size == 0:
            return
        if s.t.size == 0 and _increasing(t):
            s.t, s.v = t.copy(), v.copy()
            return
        all_t = np.concatenate((s.t, t))
        order = np.argsort(all_t, kind="stable")
        s.t, s.v = all_t[order], np.concatenate((s.v, v))[order]

    # ----------------------------------------------------------------- output
    def pop_ready(self, now_ns: int | None = None) -> AlignedSamples:
        """Decide every sample at or before the horizon (and, with ``release_complete``, the
        complete ones) and return the released ones."""
        newest = [s.max_seen for s in self._streams.values() if s.max_seen is not None]
        candidates = [max(newest) - self.reorder_window_ns] if newest else []
        if now_ns is not None:
            candidates.append(int(now_ns) - (self._clock_offset_ns or 0) - self.reorder_window_ns)
        if not candidates:
            return self._empty()
        return self._decide(max(candidates), final=False)

    def flush(self) -> AlignedSamples:
        """Decide everything pending (end of data) and return it, held-back sample included."""
        streams = (*self._streams.values(), *((self._hold,) if self._hold is not None else ()))
        stamps = [int(s.t[-1]) for s in streams if s.t.size]
        horizon = max(stamps) if stamps else (self._horizon_ns if self._horizon_ns is not None else 0)
        return self._decide(horizon, final=True)

    def _empty(self) -> AlignedSamples:
        hw = self._hold.spec.width if self._hold is not None else 0
        return AlignedSamples(np.empty(0, dtype=np.int64), np.empty((0, int(self._cols[-1]))),
                              np.empty((0, len(self.specs)), dtype=bool), np.empty((0, hw)))

    def _cluster(self) -> tuple[np.ndarray, list[np.ndarray]]:
        """Match the pending samples of all streams: the slot stamps (sorted) and, per
        stream, the index of its sample in each slot (-1 if absent)."""
        streams = list(self._streams.values())
        anchors = streams[0].t
        idx = [np.arange(anchors.size)]
        for k, s in enumerate(streams[1:], start=1):
            j = _match(anchors, s.t, self.match_tolerance_ns)
            lone = np.ones(s.t.size, dtype=bool)
            lone[j[j >= 0]] = False
            idx.append(j)
            if lone.any():                                 # they start slots of their own
                new = np.flatnonzero(lone)
                all_t = np.concatenate((anchors, s.t[new]))
                order = np.argsort(all_t, kind="stable")
                anchors = all_t[order]
                pad = np.full(new.size, -1, dtype=np.int64)
                idx = [np.concatenate((i, pad))[order] for i in idx[:k]] + [np.concatenate((j, new))[order]]
        return anchors, idx

    def _decide(self, horizon: int, final: bool) -> AlignedSamples:
        c = self.counters
        streams = list(self._streams.values())
        anchors, idx = self._cluster()
        if not self.release_complete and self._horizon_ns is not None:
            horizon = max(horizon, self._horizon_ns)
        n = anchors.size if final else int(np.searchsorted(anchors, horizon, side="right"))
        if self.release_complete and not final:
            complete = np.all([i >= 0 for i in idx], axis=0)
            ready = complete | (np.arange(anchors.size) < n)
            n = int(np.argmin(ready)) if not ready.all() else ready.size
        # the first n slots (anchors sorted) are decided; member index of each stream, -1 absent
        members = [i[:n] for i in idx]
        pres = np.stack([m >= 0 for m in members], axis=1)

        # 1. Reject slots without a required stream, or (reject_non_finite) with NaN/inf.
        ok = ~(~pres & self._required).any(axis=1)
        full = bool(pres.all())                              # common case: nothing absent
        vals = [s.v[m] for s, m in zip(streams, members)] if full else None
        fin = np.ones(pres.shape, dtype=bool)
        if self.reject_non_finite:
            for k, (s, m) in enumerate(zip(streams, members)):
                if full:
                    fin[:, k] = np.isfinite(vals[k]).all(axis=1)
                else:
                    fin[pres[:, k], k] = np.isfinite(s.v[m[pres[:, k]]]).all(axis=1)
        all_fin = fin.all(axis=1)
        emit = ok & all_fin
        all_ok = bool(emit.all())
        for k, spec in enumerate(self.specs):
            p, f = pres[:, k], fin[:, k]
            if not all_ok:
                if self.reject_non_finite:
                    c[f"non_finite_{spec.name}"] += int((p & ~f).sum())
                if not ok.all():
                    c[f"unmatched_{spec.name}"] += int((~ok & p & f).sum())
                if not all_fin.all():
                    c[f"partner_rejected_{spec.name}"] += int((ok & ~all_fin & p & f).sum())
            if not spec.required:
                c[f"missing_{spec.name}"] += int((emit & ~p).sum())
        out_t = anchors[:n] if all_ok else anchors[:n][emit]
        out_p = pres if all_ok else pres[emit]
        if full:
            out_v = np.concatenate(vals if all_ok else [v[emit] for v in vals], axis=1)
        else:
            out_v = np.full((out_t.size, int(self._cols[-1])), np.nan)
            for k, (s, m) in enumerate(zip(streams, members)):
                m = m if all_ok else m[emit]
                out_v[out_p[:, k], self._cols[k]:self._cols[k + 1]] = s.v[m[out_p[:, k]]]

        # 2. Remember decided stamps (duplicate detection) and drop them from the queues.
        if self.release_complete:
            if n:
                horizon = int(anchors[n - 1]) + self.match_tolerance_ns
                if self._horizon_ns is not None:
                    horizon = max(horizon, self._horizon_ns)
            else:
                horizon = self._horizon_ns
        self._horizon_ns = horizon
        for s, m in zip(streams, members):
            take = np.zeros(s.t.size, dtype=bool)
            take[m[m >= 0]] = True
            if self.duplicate_memory_ns is not None:
                mem = horizon - self.duplicate_memory_ns
                rec = np.concatenate((s.recent[s.recent > mem], s.t[take]))
                s.recent = rec if rec.size < 2 or np.all(rec[1:] >= rec[:-1]) else np.sort(rec)
            keep = ~take
            s.t, s.v = s.t[keep], s.v[keep]
        if self._hold is None:
            return self._released(out_t, out_v, out_p, np.empty((out_t.size, 0)))
        return self._attach_held(out_t, out_v, out_p, horizon, final)

    def _attach_held(self, out_t, out_v, out_p, horizon: int, final: bool) -> AlignedSamples:
        """Put the held-back sample in front, attach the decided held-stream values to the
        sample at or before them (zero-order hold), hold back the newest unless final."""
        c = self.counters
        h = self._hold
        name = h.spec.name
        if self._held is not None:
            out_t = np.concatenate(([self._held[0]], out_t))
            out_v = np.concatenate((self._held[1][None, :], out_v))
            out_p = np.concatenate((self._held[2][None, :], out_p))
        force_sum = np.zeros((out_t.size, h.spec.width))
        force_cnt = np.zeros(out_t.size, dtype=np.int64)
        if self._held is not None:
            force_sum[0], force_cnt[0] = self._held_sum, self._held_n
        # one older than every candidate belongs to an already released sample (late) or
        # precedes the first sample (orphan)
        ready = h.t <= horizon if not final else np.ones(h.t.size, dtype=bool)
        if ready.any():
            ti, fi = h.t[ready], h.v[ready]
            k = np.searchsorted(out_t, ti, side="right") - 1
            ok = k >= 0
            c[f"late_{name}" if self._last_emitted_ns is not None else f"orphan_{name}"] += int((~ok).sum())
            before = force_cnt.copy()
            np.add.at(force_sum, k[ok], fi[ok])
            np.add.at(force_cnt, k[ok], 1)
            c[f"attached_{name}"] += int(ok.sum())
            c[f"merged_{name}"] += int(ok.sum()) - int(((before == 0) & (force_cnt > 0)).sum())
            h.t, h.v = h.t[~ready], h.v[~ready]
        force = force_sum / np.maximum(force_cnt, 1)[:, None]
        if not final and out_t.size:
            self._held = (int(out_t[-1]), out_v[-1].copy(), out_p[-1].copy())
            self._held_sum, self._held_n = force_sum[-1].copy(), int(force_cnt[-1])
            out_t, out_v, out_p, force = out_t[:-1], out_v[:-1], out_p[:-1], force[:-1]
        else:
            self._held = None
            self._held_sum, self._held_n = np.zeros(h.spec.width), 0
        return self._released(out_t, out_v, out_p, force)

    def _released(self, out_t, out_v, out_p, held) -> AlignedSamples:
        if out_t.size:
            self._last_emitted_ns = int(out_t[-1])
            self.released += out_t.size
            for k, s in enumerate(self.specs):
                self.counters[f"emitted_{s.name}"] += int(out_p[:, k].sum())
        return AlignedSamples(out_t, out_v, out_p, held)


# --------------------------------------------------------------------------- probe planes
PLANE_STREAMS = ("plane1", "plane2")


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

    @staticmethod
    def from_samples(s: AlignedSamples) -> "AlignedBlock":
        return AlignedBlock(s.stamps_ns, s.values, s.held)


def probe_aligner(config: AlignmentConfig | None = None) -> StreamAligner:
    """The estimator's aligner: required streams ``plane1`` [xp1, yp1] and ``plane2`` [xp2, yp2]
    (m; plane 1 is the reference clock), NaN/inf rejecting the whole 4-channel sample, and
    the impact force ``impact`` [fx, fy] (N) held on the samples (zero-order hold).

    >>> al = probe_aligner(AlignmentConfig(reorder_window_ns=0))
    >>> t = np.arange(3, dtype=np.int64) * 50_000
    >>> al.add_block("plane2", t, np.ones((3, 2)))
    >>> al.add_block("plane1", t, np.zeros((3, 2)))
    >>> AlignedBlock.from_samples(al.flush()).probes_m[:, 2].tolist()
    [1.0, 1.0, 1.0]
    """
    config = config if config is not None else AlignmentConfig()
    return StreamAligner([StreamSpec(n) for n in PLANE_STREAMS], config.match_tolerance_ns, config.reorder_window_ns,
                         duplicate_memory_ns=config.duplicate_memory_ns, reject_non_finite=True,
                         release_complete=False, hold=StreamSpec("impact"))
