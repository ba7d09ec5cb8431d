# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The estimator node's whole logic on plain arrays (no ROS): ordering, shaft reference, EKF, outputs.

The live node (:mod:`rotor_estimator.ros.estimator_node`) and offline replay
(``rotor-estimator replay``) both decode messages into arrays and call this class,
so after decoding they run the same code.

Steps of one :meth:`EstimatorPipeline.process` call:

1. The :func:`~rotor_estimator.core.alignment.probe_aligner` (time-ordered queue) releases
   complete 4-channel samples in strictly increasing stamp order; late, duplicate,
   non-finite and unmatched probe samples are counted there.
2. The :class:`~rotor_estimator.core.tachometer.ShaftAngleTracker` gives the shaft angle,
   speed and angular acceleration at those stamps (causal fit, extrapolating from the
   newest keyphasor pulse before each sample).
3. A sample whose shaft reference is invalid (before lock-on, stopped shaft, zero speed,
   lost pulses) is **rejected** with reason ``no_shaft_reference`` and not given to the
   EKF. It is not held back: a live sample is decided ``reorder_window_ns`` after its
   stamp, when the pulses before it have long arrived, so waiting would not help. Not
   using the EKF's ``skip`` mask is deliberate: a skipped sample would still propagate
   the model with its (zero) shaft speed; without it the EKF predicts across the
   rejected stretch with the last valid sample's shaft state. A stretch longer than
   ``max_gap_s`` restarts the motion states (coefficients and their covariance kept).
4. :meth:`~rotor_estimator.core.ekf.StreamingEKF.process_block` runs in chunks cut at a grid
   of ``publish_period_s`` in *sample time*; one :class:`Output` is made per grid
   crossing, stamped with the sample that crossed it. Outputs therefore depend on the
   stamps only, not on how the input was split into messages or when it arrived.

Time in the EKF is float seconds relative to the first sample ever processed (integer ns
are converted once, here). Every probe sample ends in exactly one place, see
:meth:`EstimatorPipeline.accounting`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from statistics import NormalDist
from typing import Mapping

import numpy as np

from rotor_estimator.core import filter_kernel as kern
from rotor_estimator.core.alignment import AlignedBlock, AlignmentConfig, probe_aligner
from rotor_estimator.core.config import COEFFICIENT_NAMES, EstimatorConfig, RigConfig
from rotor_estimator.core.ekf import StreamingEKF, initial_covariance
from rotor_estimator.core.identifiability import IdentifiabilityReport, report_from_filter
from rotor_estimator.core.errors import ConfigError, InputError
from rotor_estimator.core.consistency import InnovationConsistency
from rotor_estimator.core.tachometer import ShaftAngleTracker, TachometerConfig, max_speed_for_rig

__all__ = ["PipelineOptions", "PipelineStatus", "Output", "Accounting", "EstimatorPipeline",
           "EKF_REJECTIONS", "ALIGNER_REJECTIONS", "LEVEL_OK", "LEVEL_WARN", "LEVEL_ERROR"]

LEVEL_OK, LEVEL_WARN, LEVEL_ERROR = 0, 1, 2
REPEATED_DIVERGENCE = 3  # recoveries from which the status stays ERROR for the rest of the run
#: Rejections after alignment; each removes one 4-channel sample (one reading of each plane).
EKF_REJECTIONS: tuple[str, ...] = ("no_shaft_reference", "gated_outlier", "numerical_failure", "non_finite")
#: Rejections in the aligner, counted per plane (``late_plane1`` ...).
ALIGNER_REJECTIONS: tuple[str, ...] = ("unmatched", "duplicate", "late", "non_finite", "partner_rejected")
#: Direct coefficients (kxx, kyy, cxx, cyy) judge convergence: cross terms may be near zero.
_DIRECT = np.array([0, 3, 4, 7])
_NIS_DOF = 4
_STATUS_TO_REASON = {kern.STATUS_GATED: "gated_outlier", kern.STATUS_NUMERICAL: "numerical_failure",
                     kern.STATUS_NON_FINITE: "non_finite", kern.STATUS_SKIPPED: "no_shaft_reference"}


@dataclass(frozen=True)
class PipelineOptions:
    """Node-level settings beyond the filter, alignment and tachometer configs.

    * ``convergence_relative_std``: converged when ``std/|estimate|`` of every direct
      coefficient (kxx, kyy, cxx, cyy) is below this (and the NIS is consistent).
    * ``nis_false_alarm_probability``: two-sided probability of the chi-square bounds on
      the windowed NIS mean (4 dof per sample, ``n`` samples in the window).
    * ``falling_behind_s``: samples handled more than this after their stamp (beyond the
      earliest handling ever seen) mean the consumer cannot keep up (s).
    * ``max_gap_s``: a stretch without usable samples longer than this restarts the
      filter's motion states from the next sample (s).
    * ``clock_jump_s``: a probe block this much older than the newest stamp seen means
      the sensor clock jumped back: queues restart on the new timeline (s).
    * ``plane_skew_s``: a probe sample newer than the other plane's newest stamp waits for
      that plane (so a plane delivered in a burst ahead of the other does not make the
      other one late), at most until its own plane is this much further ahead (s).
    * ``shaft_wait_s``: an aligned sample waits for a keyphasor pulse stamped after it (so
      its shaft reference is final whatever order the topics are delivered in). It stops
      waiting when no pulse has arrived while this much probe data (sample time) did
      (pulses stopped), or at the latest when the newest probe stamp is ten times this
      much later (keyphasor topic delivered that far behind) (s).
    """

    convergence_relative_std: float = 0.05
    nis_false_alarm_probability: float = 1e-3
    falling_behind_s: float = 0.5
    max_gap_s: float = 0.02
    clock_jump_s: float = 1.0
    shaft_wait_s: float = 0.5
    plane_skew_s: float = 1.0

    def __post_init__(self) -> None:
        for name, low, high in (("convergence_relative_std", 0.0, 10.0), ("nis_false_alarm_probability", 0.0, 0.5),
                                ("falling_behind_s", 0.0, 3600.0), ("max_gap_s", 0.0, 3600.0),
                                ("clock_jump_s", 0.0, 3600.0), ("shaft_wait_s", 0.0, 3600.0),
                                ("plane_skew_s", 0.0, 3600.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not low < v <= high:
                raise ConfigError(f"pipeline.{name}: must be a number > {low:g} and <= {high:g}, got {v!r}")


@dataclass(frozen=True)
class PipelineStatus:
    """Health of the estimation at one output (becomes one ``DiagnosticStatus``).

    ``level``: 0 OK, 1 WARN, 2 ERROR. ``samples``: the accounting summary (see
    :meth:`Accounting.summary`); ``filter_counts``: EKF status counts since the last reset.
    """

    level: int
    message: str
    converged: bool
    max_relative_std: float
    nis_window_mean: float
    nis_bounds: tuple[float, float]
    falling_behind: bool
    lag_s: float
    divergence_recoveries: int
    samples: Mapping[str, int]
    filter_counts: Mapping[str, int]
    pulse_counts: Mapping[str, int]
    impact_counts: Mapping[str, int]
    extra: Mapping[str, float | int | str] = field(default_factory=dict)

    def key_values(self) -> dict[str, str]:
        """Flat ``key -> value`` strings for ``DiagnosticStatus.values`` (SI in the key names)."""
        kv: dict[str, str] = {
            "converged": str(self.converged).lower(),
            "max_relative_std_direct": f"{self.max_relative_std:.4g}",
            "nis_window_mean": f"{self.nis_window_mean:.4g}",
            "nis_bounds": f"{self.nis_bounds[0]:.4g}..{self.nis_bounds[1]:.4g}",
            "falling_behind": str(self.falling_behind).lower(),
            "lag_s": f"{self.lag_s:.4g}",
            "divergence_recoveries": str(self.divergence_recoveries),
        }
        kv.update({f"samples.{k}": str(v) for k, v in self.samples.items()})
        kv.update({f"filter.{k}": str(v) for k, v in self.filter_counts.items()})
        kv.update({f"pulses.{k}": str(v) for k, v in self.pulse_counts.items()})
        kv.update({f"impact.{k}": str(v) for k, v in self.impact_counts.items()})
        kv.update({k: str(v) for k, v in self.extra.items()})
        return kv


@dataclass(frozen=True)
class Output:
    """One publishable estimate, referring to the sample at ``stamp_ns``.

    ``coefficients``/``std`` (8,) SI in ``kxx kxy kyx kyy cxx cxy cyx cyy`` order,
    ``covariance`` (8, 8); ``innovation_m``/``innovation_std_m`` (4,) of the last updated
    sample (NaN before any); NIS of that sample and the windowed mean; shaft state at
    ``stamp_ns`` (0 when invalid).
    """

    stamp_ns: int
    coefficients: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    innovation_m: np.ndarray
    innovation_std_m: np.ndarray
    nis: float
    nis_window_mean: float
    shaft_speed_rad_s: float
    shaft_angle_rad: float
    diagnostics: PipelineStatus
    identifiability: IdentifiabilityReport | None = None
    nis_dof: int = _NIS_DOF

    def coefficient_dict(self) -> dict[str, dict[str, float]]:
        """``{"kxx": {"mean": ..., "std": ...}, ...}`` (SI)."""
        return {n: {"mean": float(m), "std": float(s)} for n, m, s in zip(COEFFICIENT_NAMES, self.coefficients,
                                                                            self.std)}


@dataclass(frozen=True)
class Accounting:
    """Where every input went.

    Per plane ``p``::

        received_plane{p} == processed + sum(EKF_REJECTIONS) + sum(rejected_*_plane{p}) + pending_plane{p}

    ``processed`` counts 4-channel samples the EKF used (updated or initialized); each
    EKF-stage rejection removes one reading of *each* plane. Impact-force samples and
    keyphasor pulses have their own balances (:data:`alignment.IMPACT_COUNTERS`,
    :data:`tachometer.PULSE_COUNTERS`). ``bad_messages`` counts messages that could not be
    decoded (wrong type or layout) per stream: their samples never entered.
    """

    received: Mapping[int, int]
    processed: int
    ekf_rejected: Mapping[str, int]
    aligner_rejected: Mapping[int, Mapping[str, int]]
    pending: Mapping[int, int]
    reordered: Mapping[int, int]
    missing: Mapping[int, int]
    impact: Mapping[str, int]
    pulses: Mapping[str, int]
    bad_messages: Mapping[str, Mapping[str, int]]

    def balanced(self) -> bool:
        """True when every received probe sample is processed, rejected with a reason or pending."""
        ekf = sum(self.ekf_rejected.values())
        planes_ok = all(self.received[p] == self.processed + ekf + sum(self.aligner_rejected[p].values())
                        + self.pending[p] for p in (1, 2))
        imp = self.impact
        impact_ok = imp["received_impact"] == (imp["attached_impact"] + imp["late_impact"] + imp["orphan_impact"]
                                               + imp["duplicate_impact"] + imp["non_finite_impact"]
                                               + imp["pending_impact"])
        pul = self.pulses
        pulses_ok = pul["pulses_in"] == pul["accepted"] + sum(v for k, v in pul.items() if k.startswith("rejected_"))
        return planes_ok and impact_ok and pulses_ok

    def rejected_by_reason(self) -> dict[str, int]:
        """EKF-stage reasons as is, aligner reasons per plane (``late_plane1``...)."""
        out = {k: int(v) for k, v in self.ekf_rejected.items()}
        for p in (1, 2):
            out.update({f"{k}_plane{p}": int(v) for k, v in self.aligner_rejected[p].items()})
        return out

    def summary(self) -> dict[str, int]:
        """Flat counts for diagnostics and JSON: received/pending per plane, processed,
        rejected (sum of all reasons) and each reason, reordered and missing per plane."""
        reasons = self.rejected_by_reason()
        out = {"received_plane1": int(self.received[1]), "received_plane2": int(self.received[2]),
               "processed": int(self.processed), "rejected": int(sum(reasons.values()))}
        out.update(reasons)
        for p in (1, 2):
            out[f"pending_plane{p}"] = int(self.pending[p])
            out[f"reordered_plane{p}"] = int(self.reordered[p])
            out[f"missing_plane{p}"] = int(self.missing[p])
        for stream, counts in self.bad_messages.items():
            for reason, n in counts.items():
                out[f"bad_messages.{stream}.{reason}"] = int(n)
        return out


@lru_cache(maxsize=4096)
def _nis_bounds(n: int, probability: float) -> tuple[float, float]:
    """Two-sided bounds on the mean of ``n`` NIS values (chi-square, 4 dof each).

    Wilson-Hilferty approximation of the chi-square quantiles (relative error < 1e-3 for
    the >= 4 degrees of freedom used here; no scipy import on the live path).
    """
    if n <= 0:
        return (math.nan, math.nan)
    dof = _NIS_DOF * n
    z = NormalDist().inv_cdf(1 - probability / 2)
    c = 2.0 / (9.0 * dof)
    lo = dof * max(1.0 - c - z * math.sqrt(c), 0.0) ** 3
    hi = dof * (1.0 - c + z * math.sqrt(c)) ** 3
    return (lo / n, hi / n)


class EstimatorPipeline:
    """Inputs in any order, publishable :class:`Output` records out (see the module docstring).

    >>> from rotor_estimator.core.config import load_rig_file
    >>> f = load_rig_file()
    >>> pipe = EstimatorPipeline(f.rig, f.estimator, TachometerConfig(), AlignmentConfig(), publish_period_s=0.05)
    >>> pipe.process()
    []
    >>> pipe.accounting().balanced()
    True
    """

    def __init__(self, rig: RigConfig, estimator_config: EstimatorConfig, tach_config: TachometerConfig | None = None,
                 align_config: AlignmentConfig | None = None, publish_period_s: float = 0.05, *,
                 options: PipelineOptions | None = None, initial_coefficients: np.ndarray | None = None) -> None:
        if (isinstance(publish_period_s, bool) or not isinstance(publish_period_s, (int, float))
                or not math.isfinite(publish_period_s) or not 0 < publish_period_s <= 3600):
            raise ConfigError(f"pipeline.publish_period_s: must be > 0 and <= 3600 s, got {publish_period_s!r}")
        self.rig = rig
        self.estimator_config = estimator_config
        self.tach_config = tach_config if tach_config is not None else TachometerConfig(
            fit_history=1024, max_speed_rad_s=max_speed_for_rig(rig.speed_rad_s))
        self.align_config = align_config if align_config is not None else AlignmentConfig(
            sample_rate_hz=rig.sample_rate_hz)
        self.options = options if options is not None else PipelineOptions()
        self.publish_period_ns = max(1, int(round(publish_period_s * 1e9)))
        self._period_ns = 1e9 / self.align_config.sample_rate_hz
        self.ekf = StreamingEKF(rig, estimator_config, initial_coefficients=initial_coefficients)
        self.tracker = ShaftAngleTracker(self.tach_config)
        self.aligner = probe_aligner(self.align_config)
        self._retired: dict[str, int] = {}            # counters of aligners replaced after a clock jump
        self._ready: list[AlignedBlock | None] = []    # flushed blocks to process first; None = restart motion
        self._waiting: list[AlignedBlock] = []         # aligned samples waiting for the shaft reference
        self._newest_pulse_ns: int | None = None
        self._probe_ns_at_pulse: int | None = None     # newest probe stamp when the last pulse arrived
        self._pulse_arrival_ns: int | None = None      # when the last pulse was received (live clock)
        self._held: dict[int, list[tuple[np.ndarray, np.ndarray, int | None]]] = {1: [], 2: []}
        self._held_count = {1: 0, 2: 0}
        self._ekf_counts = dict.fromkeys(EKF_REJECTIONS, 0)
        self._processed = 0
        self._recoveries_retired = 0
        self._bad_messages: dict[str, dict[str, int]] = {}
        self._missing = {1: 0, 2: 0}
        self._last_stamp_seen = {1: None, 2: None}     # newest stamp per plane (gap detection)
        self._newest_ns: int | None = None
        self._min_offset_ns: int | None = None         # min(arrival - newest stamp of a block)
        self._lag_s = 0.0
        self._events = {"clock_jumps": 0, "motion_restarts": 0, "resets": 0, "falling_behind_events": 0}
        self._falling_behind = False
        self._last_level_counts: dict[str, int] = {}
        self._start_filter()

    # ----------------------------------------------------------------- state
    def _start_filter(self) -> None:
        self._t0_ns: int | None = None
        self._next_publish_ns: int | None = None
        self._last_fed_ns: int | None = None           # stamp of the last sample given to the EKF
        self._last_innov = np.full(4, np.nan)
        self._last_innov_std = np.full(4, np.nan)
        self._last_nis = math.nan
        self._last_shaft = (0.0, 0.0)
        self._last_emitted_ns: int | None = None
        self.consistency = InnovationConsistency()     # NIS and whiteness of this run's innovations

    def reset(self, initial_coefficients: np.ndarray | None = None) -> None:
        """Restart the estimation from the prior (``r0``, ``P0``), or from ``initial_coefficients``.

        Queues, shaft tracking and the input accounting carry on (they describe the data)."""
        self._recoveries_retired += self.ekf.health.divergence_recoveries
        self.ekf.reset(None if initial_coefficients is None else np.asarray(initial_coefficients, dtype=float))
        self._events["resets"] += 1
        self._start_filter()

    def _restart_motion(self) -> None:
        """Re-initialize displacements from the next sample; keep coefficients and their covariance."""
        if self.ekf.restart_motion():
            self._events["motion_restarts"] += 1

    # ----------------------------------------------------------------- inputs
    def on_probe_block(self, plane: int, stamps_ns: np.ndarray, xy_m: np.ndarray,
                       arrival_ns: int | None = None) -> None:
        """Samples ``xy_m`` (N, 2) [x, y] in m of probe ``plane`` (1 or 2) at integer-ns ``stamps_ns``.

        ``arrival_ns``: when the block was received (live: the node's clock), for the
        wall-clock horizon and the falling-behind monitor."""
        t = np.asarray(stamps_ns)
        if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
            raise InputError(f"plane {plane} block: stamps_ns must be a 1-D integer array (ns), got {t.dtype}")
        if t.size == 0:
            return
        newest = int(t.max())
        if self._newest_ns is not None and newest < self._newest_ns - int(self.options.clock_jump_s * 1e9):
            self._clock_jump()
        self._count_gaps(plane, t)
        if arrival_ns is not None:
            offset = int(arrival_ns) - newest
            self._min_offset_ns = offset if self._min_offset_ns is None else min(self._min_offset_ns, offset)
            self._lag_s = (offset - self._min_offset_ns) * 1e-9
            behind = self._lag_s > self.options.falling_behind_s
            if behind and not self._falling_behind:
                self._events["falling_behind_events"] += 1
            self._falling_behind = behind
        self._newest_ns = newest if self._newest_ns is None else max(self._newest_ns, newest)
        self._held[plane].append((t, np.asarray(xy_m, dtype=float), arrival_ns))
        self._held_count[plane] += t.size
        self._release_planes()

    def _release_planes(self, everything: bool = False) -> None:
        """Give the aligner each plane's samples up to the other plane's newest stamp (or up to
        ``plane_skew_s`` behind its own newest), in arrival order."""
        newest = {p: self._last_stamp_seen[p] for p in (1, 2)}
        skew_ns = int(self.options.plane_skew_s * 1e9)
        for p in (1, 2):
            if not self._held[p]:
                continue
            q = 2 if p == 1 else 1
            gate = newest[q] if newest[q] is not None else -(2 ** 62)
            gate = max(gate, newest[p] - skew_ns)
            keep = []
            for t, xy, arrival in self._held[p]:
                go = np.ones(t.size, dtype=bool) if everything else t <= gate
                if go.all():
                    self.aligner.add_block(f"plane{p}", t, xy, arrival)
                elif go.any():
                    self.aligner.add_block(f"plane{p}", t[go], xy[go], arrival)
                    keep.append((t[~go], xy[~go], arrival))
                else:
                    keep.append((t, xy, arrival))
            self._held[p] = keep
            self._held_count[p] = sum(b[0].size for b in keep)

    def on_pulse(self, stamp_ns: int, arrival_ns: int | None = None) -> None:
        """One keyphasor pulse (shaft angle 0) at integer-ns ``stamp_ns``.

        ``arrival_ns`` (live): when it was received. While pulses keep arriving, samples are
        not released by the wall clock without one (see :meth:`process`)."""
        stamp = int(stamp_ns)
        if arrival_ns is not None:
            self._pulse_arrival_ns = int(arrival_ns)
        self._probe_ns_at_pulse = self._newest_ns
        self._newest_pulse_ns = stamp if self._newest_pulse_ns is None else max(self._newest_pulse_ns, stamp)
        self.tracker.add_pulse(stamp)

    def on_impact_block(self, stamps_ns: np.ndarray, f_n: np.ndarray) -> None:
        """Impact force samples ``f_n`` (N, 2) [fx, fy] in N (zero-order hold from each stamp)."""
        self.aligner.add_block("impact", stamps_ns, f_n)

    def reject_message(self, stream: str, reason: str) -> None:
        """Count a message that could not be used (e.g. ``"wrong_type"`` on ``"probe1"``)."""
        counts = self._bad_messages.setdefault(stream, {})
        counts[reason] = counts.get(reason, 0) + 1

    def _count_gaps(self, plane: int, t: np.ndarray) -> None:
        """Estimate samples that never arrived (stamp gaps longer than 1.5 periods)."""
        prev = self._last_stamp_seen[plane]
        ts = np.sort(t) if t.size > 1 and not np.all(t[1:] > t[:-1]) else t
        if prev is not None and ts[0] > prev:
            ts = np.concatenate(([prev], ts))
        elif prev is not None:
            ts = ts[ts > prev]
            if ts.size == 0:
                return
            ts = np.concatenate(([prev], ts))
        if ts.size > 1:
            d = np.diff(ts)
            big = d > 1.5 * self._period_ns
            if big.any():
                self._missing[plane] += int(np.sum(np.rint(d[big] / self._period_ns) - 1))
        self._last_stamp_seen[plane] = int(ts[-1])

    def _clock_jump(self) -> None:
        """The probe clock went back: finish the old timeline, start new queues."""
        self._events["clock_jumps"] += 1
        self._release_planes(everything=True)
        block = AlignedBlock.from_samples(self.aligner.flush())
        if block.stamps_ns.size:
            self._waiting.append(block)
        self._ready.append(self._take_waiting(None))
        self._ready.append(None)
        for k, v in self.aligner.counters.items():
            self._retired[k] = self._retired.get(k, 0) + v
        self.aligner = probe_aligner(self.align_config)
        self._newest_ns = None
        self._newest_pulse_ns = None
        self._probe_ns_at_pulse = None
        self._last_stamp_seen = {1: None, 2: None}
        self._min_offset_ns = None

    # ----------------------------------------------------------------- processing
    def process(self, now_ns: int | None = None) -> list[Output]:
        """Filter every sample that is ready.

        ``now_ns`` (live only, on the clock of ``arrival_ns``): the probe input is known to be
        idle up to now, so samples still waiting for the other plane or the reorder window are
        decided by the clock as well. Samples waiting for a keyphasor pulse are decided by the
        clock only once no pulse has arrived for ``shaft_wait_s`` either: a keyphasor topic
        delivered behind the probes (a loaded consumer takes one message per topic per
        executor round, and pulses can outnumber probe blocks) is waited for, not rejected."""
        outputs = self._drain_ready()
        if now_ns is not None:
            self._release_planes(everything=True)
        block = AlignedBlock.from_samples(self.aligner.pop_ready(now_ns))
        if block.stamps_ns.size:
            self._waiting.append(block)
        if not self._waiting:
            return outputs
        ripe_ns = -1 if self._newest_pulse_ns is None else self._newest_pulse_ns
        wait_ns = int(self.options.shaft_wait_s * 1e9)
        if self._newest_ns is not None:
            since = self._probe_ns_at_pulse
            stopped = since is None or self._newest_ns - since > wait_ns
            ripe_ns = max(ripe_ns, self._newest_ns - (wait_ns if stopped else 10 * wait_ns))
        pulses_quiet = self._pulse_arrival_ns is None or now_ns is None or now_ns - self._pulse_arrival_ns > wait_ns
        if now_ns is not None and self._min_offset_ns is not None and pulses_quiet:
            ripe_ns = max(ripe_ns, int(now_ns) - self._min_offset_ns - wait_ns)
        outputs += self._run(self._take_waiting(ripe_ns))
        return outputs

    def _take_waiting(self, ripe_ns: int | None) -> AlignedBlock:
        """Waiting samples with stamp <= ``ripe_ns`` (all if None), in order."""
        if len(self._waiting) > 1:
            self._waiting = [AlignedBlock(*(np.concatenate(parts) for parts in zip(*self._waiting)))]
        if not self._waiting:
            return AlignedBlock(np.empty(0, dtype=np.int64), np.empty((0, 4)), np.empty((0, 2)))
        w = self._waiting[0]
        k = w.stamps_ns.size if ripe_ns is None else int(np.searchsorted(w.stamps_ns, ripe_ns, side="right"))
        if k == w.stamps_ns.size:
            self._waiting = []
            return w
        self._waiting = [AlignedBlock(w.stamps_ns[k:], w.probes_m[k:], w.impact_force_n[k:])]
        return AlignedBlock(w.stamps_ns[:k], w.probes_m[:k], w.impact_force_n[:k])

    def flush(self) -> list[Output]:
        """End of data: filter everything pending and emit a final output.

        Nothing is then behind: the falling-behind state clears (its events stay counted)."""
        self._falling_behind = False
        self._lag_s = 0.0
        outputs = self._drain_ready()
        self._release_planes(everything=True)
        block = AlignedBlock.from_samples(self.aligner.flush())
        if block.stamps_ns.size:
            self._waiting.append(block)
        outputs += self._run(self._take_waiting(None))
        if self._last_emitted_ns is not None and (not outputs or outputs[-1].stamp_ns != self._last_emitted_ns):
            outputs.append(self._output(self._last_emitted_ns))
        return outputs

    def warm_up(self) -> None:
        """Compile the filter kernel now (a throwaway filter), not on the first live sample."""
        ekf = StreamingEKF(self.rig, self.estimator_config)
        z = np.zeros(3)
        ekf.process_block(np.array([0.0, 1e-5, 2e-5]), np.zeros((3, 4)), z, z + 1.0, z, np.zeros((3, 2)))

    def _drain_ready(self) -> list[Output]:
        outputs: list[Output] = []
        while self._ready:
            block = self._ready.pop(0)
            if block is None:
                if self._last_emitted_ns is not None:
                    outputs.append(self._output(self._last_emitted_ns))
                self._restart_motion()
                self._next_publish_ns = None
                self._last_fed_ns = None
            else:
                outputs += self._run(block)
        return outputs

    def _run(self, block: AlignedBlock) -> list[Output]:
        n = block.stamps_ns.size
        if n == 0:
            return []
        stamps = block.stamps_ns
        shaft = self.tracker.query_many(stamps)
        if self._next_publish_ns is None:
            self._next_publish_ns = int(stamps[0]) + self.publish_period_ns
        outputs = []
        start = 0
        while start < n:
            # cut at the first sample at or past the next publish boundary
            cross = start + int(np.searchsorted(stamps[start:], self._next_publish_ns, side="left"))
            stop = min(cross + 1, n)
            self._filter(stamps[start:stop], block.probes_m[start:stop], block.impact_force_n[start:stop],
                         shaft, slice(start, stop))
            self._last_emitted_ns = int(stamps[stop - 1])
            self._last_shaft = (float(shaft.speed_rad_s[stop - 1]), float(shaft.angle_rad[stop - 1]))
            if cross < n:
                s = int(stamps[cross])
                steps = (s - self._next_publish_ns) // self.publish_period_ns + 1
                self._next_publish_ns += steps * self.publish_period_ns
                outputs.append(self._output(s))
            start = stop
        return outputs

    def _filter(self, stamps: np.ndarray, probes: np.ndarray, impact: np.ndarray, shaft, sl: slice) -> None:
        valid = shaft.valid[sl]
        n_invalid = int((~valid).sum())
        self._ekf_counts["no_shaft_reference"] += n_invalid
        if n_invalid == valid.size:
            return
        idx = np.flatnonzero(valid)
        t_ns = stamps[idx]
        if self._t0_ns is None:
            self._t0_ns = int(t_ns[0])
        # split where the stretch since the previously fed sample is longer than max_gap_s
        max_gap_ns = int(self.options.max_gap_s * 1e9)
        prev = np.concatenate(([self._last_fed_ns if self._last_fed_ns is not None else t_ns[0]], t_ns[:-1]))
        cuts = set(np.flatnonzero(t_ns - prev > max_gap_ns).tolist())
        bounds = sorted({0, *cuts, idx.size})
        angle, speed, accel = shaft.angle_rad[sl], shaft.speed_rad_s[sl], shaft.accel_rad_s2[sl]
        for a, b in zip(bounds[:-1], bounds[1:]):
            if a in cuts:
                self._restart_motion()
            j = idx[a:b]
            t_s = (t_ns[a:b] - self._t0_ns) * 1e-9
            res = self.ekf.process_block(t_s, probes[j], angle[j], speed[j], accel[j], impact[j])
            self._tally(res)
        self._last_fed_ns = int(t_ns[-1])

    def _tally(self, res) -> None:
        status = res.status
        used = (status == kern.STATUS_UPDATED) | (status == kern.STATUS_INITIALIZED)
        self._processed += int(used.sum())
        for code, reason in _STATUS_TO_REASON.items():
            k = int((status == code).sum())
            if k:
                self._ekf_counts[reason] += k
        self.consistency.add(res.nis, res.innovation_m, res.innovation_std_m, status == kern.STATUS_UPDATED)
        upd = np.flatnonzero(status == kern.STATUS_UPDATED)
        if upd.size:
            i = int(upd[-1])
            self._last_innov = res.innovation_m[i].copy()
            self._last_innov_std = res.innovation_std_m[i].copy()
            self._last_nis = float(res.nis[i])

    # ----------------------------------------------------------------- outputs
    def identifiability(self) -> IdentifiabilityReport:
        """Which coefficients the data received so far determine: the filter's information minus
        its prior's, as a Cramer-Rao bound (see :mod:`rotor_estimator.core.identifiability`)."""
        prior = initial_covariance(self.estimator_config)[8:, 8:]
        return report_from_filter(self.ekf.coefficient_covariance, prior, self.ekf.coefficients)

    def _output(self, stamp_ns: int) -> Output:
        ekf = self.ekf
        return Output(stamp_ns=int(stamp_ns), coefficients=ekf.coefficients, std=ekf.coefficient_std,
                      covariance=ekf.coefficient_covariance, identifiability=self.identifiability(),
                      innovation_m=self._last_innov.copy(),
                      innovation_std_m=self._last_innov_std.copy(), nis=self._last_nis,
                      nis_window_mean=ekf.health.nis_window_mean(), shaft_speed_rad_s=self._last_shaft[0],
                      shaft_angle_rad=self._last_shaft[1], diagnostics=self.status())

    @property
    def last_sample_stamp_ns(self) -> int | None:
        """Stamp of the newest sample filtered or rejected after alignment (None before any)."""
        return self._last_emitted_ns

    @property
    def divergence_recoveries(self) -> int:
        """Recoveries of the filter since construction (survives :meth:`reset`)."""
        return self._recoveries_retired + self.ekf.health.divergence_recoveries

    def status(self) -> PipelineStatus:
        """The current health record (levels judged on the change since the previous call)."""
        acc = self.accounting()
        summary = acc.summary()
        ekf = self.ekf
        coef, std = ekf.coefficients, ekf.coefficient_std
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = std[_DIRECT] / np.abs(coef[_DIRECT])
        max_rel = float(np.max(rel)) if np.all(np.isfinite(rel)) else math.inf
        window = len(ekf.health.nis_window)
        bounds = _nis_bounds(window, self.options.nis_false_alarm_probability)
        nis_mean = ekf.health.nis_window_mean()
        nis_ok = window > 0 and bounds[0] <= nis_mean <= bounds[1]
        converged = bool(max_rel < self.options.convergence_relative_std and nis_ok)
        prev = self._last_level_counts
        now = {"recoveries": self.divergence_recoveries, "processed": acc.processed,
               "no_shaft_reference": acc.ekf_rejected["no_shaft_reference"], "rejected": summary["rejected"],
               "missing": acc.missing[1] + acc.missing[2],
               "bad_messages": sum(sum(c.values()) for c in acc.bad_messages.values())}
        now["pulses_in"] = acc.pulses["pulses_in"]
        delta = {k: v - prev.get(k, 0) for k, v in now.items()}
        # keyphasor delivered behind the probes while pulses still arrive: the consumer is behind
        pulse_lag_s = ((self._newest_ns - self._newest_pulse_ns) * 1e-9
                       if self._newest_ns is not None and self._newest_pulse_ns is not None else 0.0)
        pulses_behind = delta["pulses_in"] > 0 and pulse_lag_s > self.options.shaft_wait_s
        if pulses_behind:
            self._lag_s = max(self._lag_s, pulse_lag_s)
        self._last_level_counts = now
        level, problems = LEVEL_OK, []
        recoveries = now["recoveries"]
        if delta["recoveries"] > 0 or recoveries >= REPEATED_DIVERGENCE:
            # ERROR while it happens and for good once it repeats: not judged on the last interval alone
            level = LEVEL_ERROR
            problems.append(f"filter diverged {recoveries} time{'s' if recoveries != 1 else ''} and was restored "
                            f"from its last healthy state; the estimate is not trustworthy"
                            + (": check the rig file against the rig (run `diagnose`)"
                               if recoveries >= REPEATED_DIVERGENCE else ""))
        elif recoveries:
            level = max(level, LEVEL_WARN)
            problems.append(f"filter diverged {recoveries} time{'s' if recoveries != 1 else ''} earlier "
                            f"(restored)")
        falling_behind = self._falling_behind or pulses_behind
        if falling_behind:
            level = max(level, LEVEL_WARN)
            problems.append(f"falling behind: input handled {self._lag_s:.3f} s late; input queues may overflow")
        if delta["no_shaft_reference"] > 0 and delta["processed"] == 0:
            level = max(level, LEVEL_WARN)
            problems.append("no shaft reference (keyphasor pulses missing or shaft stopped)")
        seen = self._last_stamp_seen
        if seen[1] is not None and seen[2] is not None:
            lag = {p: (seen[3 - p] - seen[p]) * 1e-9 for p in (1, 2)}
            stalled = max(lag, key=lag.get)
            if lag[stalled] > self.options.plane_skew_s:
                level = max(level, LEVEL_WARN)
                problems.append(f"probe plane {stalled} stalled: its newest sample is {lag[stalled]:.2f} s behind "
                                f"plane {3 - stalled}'s (topic silent or its publisher stopped)")
        if delta["missing"] > 0:
            level = max(level, LEVEL_WARN)
            problems.append(f"{delta['missing']} probe samples missing (stamp gaps)")
        if now["bad_messages"] > 0:  # a standing fault (e.g. mixed probe types): named while it lasts
            level = max(level, LEVEL_WARN)
            streams = ", ".join(f"{s}: {sum(c.values())} ({', '.join(sorted(c))})"
                                for s, c in sorted(acc.bad_messages.items()) if sum(c.values()))
            problems.append(f"{now['bad_messages']} input messages of the wrong type or layout ({streams})")
        if acc.processed == 0:
            level = max(level, LEVEL_WARN)
            problems.append("no sample filtered yet: " + self.no_data_cause(acc))
        elif not converged:
            level = max(level, LEVEL_WARN)
            why = (f"max relative std {max_rel:.3g} >= {self.options.convergence_relative_std:g}"
                   if max_rel >= self.options.convergence_relative_std else
                   f"NIS window mean {nis_mean:.3g} outside [{bounds[0]:.3g}, {bounds[1]:.3g}]")
            problems.append(f"not converged ({why})")
        message = "; ".join(problems) if problems else "converged"
        return PipelineStatus(
            level=level, message=message, converged=converged, max_relative_std=max_rel, nis_window_mean=nis_mean,
            nis_bounds=bounds, falling_behind=falling_behind, lag_s=self._lag_s,
            divergence_recoveries=now["recoveries"], samples=summary, filter_counts=dict(ekf.health.counts),
            pulse_counts=dict(acc.pulses), impact_counts=dict(acc.impact), extra=dict(self._events))

    def no_data_cause(self, acc: Accounting | None = None) -> str:
        """Why nothing has been filtered, naming the silent or refused input."""
        acc = acc or self.accounting()
        pulses = acc.pulses
        causes = []
        silent = [f"probe plane {p}" for p in (1, 2) if acc.received[p] == 0]
        if silent:
            causes.append(f"no samples received on {' and '.join(silent)}")
        if pulses["pulses_in"] == 0:
            causes.append("no keyphasor pulse received")
        elif pulses["accepted"] < 2:
            refused = {k[len('rejected_'):]: v for k, v in pulses.items() if k.startswith("rejected_") and v}
            causes.append(f"{pulses['pulses_in']} keyphasor pulse(s) received, {pulses['accepted']} accepted"
                          + (f", refused as {refused}" if refused else "")
                          + f" (the tracker needs 2 pulses at {self.tach_config.min_speed_rad_s:g}-"
                          f"{self.tach_config.max_speed_rad_s:g} rad/s on the probes' clock)")
        no_ref = acc.ekf_rejected.get("no_shaft_reference", 0)
        if no_ref and not causes:
            causes.append(f"{no_ref} samples had no shaft reference: the keyphasor pulses do not cover the "
                          f"probe samples' time span (another clock, or stamps in other units?)")
        for stream, counts in sorted(acc.bad_messages.items()):
            if sum(counts.values()):
                causes.append(f"{sum(counts.values())} {stream} message(s) refused ({', '.join(sorted(counts))})")
        if not causes:
            pending = acc.pending[1] + acc.pending[2]
            causes.append(f"{pending} samples still waiting for alignment or a shaft reference")
        return "; ".join(causes)

    def accounting(self) -> Accounting:
        """Counts proving every input sample was processed, rejected with a reason, or is pending."""
        c = dict(self.aligner.counters)
        for k, v in self._retired.items():
            c[k] = c.get(k, 0) + v
        pending = dict(self.aligner.pending_count)
        pending["plane1"] += self._held_count[1]
        pending["plane2"] += self._held_count[2]
        for block in (*self._ready, *self._waiting):
            if block is not None:
                pending = {**pending, "plane1": pending["plane1"] + block.stamps_ns.size,
                           "plane2": pending["plane2"] + block.stamps_ns.size}
        impact = {k: int(v) for k, v in c.items() if k.endswith("_impact")}
        impact["pending_impact"] = pending["impact"]
        return Accounting(  # samples held back for the other plane are received and pending
            received={p: c[f"received_plane{p}"] + self._held_count[p] for p in (1, 2)}, processed=self._processed,
            ekf_rejected=dict(self._ekf_counts),
            aligner_rejected={p: {r: c[f"{r}_plane{p}"] for r in ALIGNER_REJECTIONS} for p in (1, 2)},
            pending={p: pending[f"plane{p}"] for p in (1, 2)},
            reordered={p: c[f"reordered_plane{p}"] for p in (1, 2)}, missing=dict(self._missing),
            impact=impact, pulses=dict(self.tracker.counters),
            bad_messages={k: dict(v) for k, v in self._bad_messages.items()})
