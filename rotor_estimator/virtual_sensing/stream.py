# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Streaming virtual sensing: the same per-sample filter step, fed live (node) or from a bag.

* :class:`SensorAligner`: the virtual-sensing configuration of the core
  :class:`~rotor_estimator.core.alignment.StreamAligner` (S optional sensors), counting late,
  duplicate and missing samples.
* :class:`VirtualSensingPipeline`: keyphasor tracking, prediction across gaps, decimation, NIS
  coverage and a status for ``/diagnostics``; the node and ``virtual-sensing --bag`` both run it.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import NamedTuple, Sequence

import numpy as np
from scipy.stats import chi2

from rotor_estimator.core.alignment import StreamAligner, StreamSpec
from rotor_estimator.core.errors import ConfigError, InputError
from rotor_estimator.core.flexible.state_space import FlexibleStateSpace
from rotor_estimator.core.linear_filters import single_threaded_blas
from rotor_estimator.core.tachometer import ShaftAngleTracker, TachometerConfig
from rotor_estimator.virtual_sensing.estimator import StationFilter, VirtualSensingConfig

__all__ = ["SensorAligner", "AlignedSamples", "PipelineOptions", "StationOutput", "PipelineStatus",
           "VirtualSensingPipeline"]


class AlignedSamples(NamedTuple):
    """Released samples in increasing stamp order: ``stamps_ns`` (M,) int64, ``values``
    (M, S, 2) per sensor [x, y] (NaN where absent), ``present`` (M, S) bool."""

    stamps_ns: np.ndarray
    values: np.ndarray
    present: np.ndarray


class SensorAligner:
    """The virtual-sensing configuration of :class:`~rotor_estimator.core.alignment.StreamAligner`:
    S optional sensor streams [x, y], each sample released as soon as every sensor is in
    (or ``reorder_window_ns`` after the newest stamp seen, or on ``pop_ready(flush=True)``),
    an absent sensor counted ``missing_<sensor>``; NaN/inf values pass to the filter, which
    leaves those channels out. A sample not newer than the last released stamp plus the
    tolerance is ``late_<sensor>``; the same stamp again on a pending sensor is
    ``duplicate_<sensor>`` (the first wins). Every sample received is released, late,
    duplicate or pending. Matching is nearest first and one-to-one, so the sample's stamp is
    that of its first sensor in rotor-file order whatever the arrival order, and a second,
    different stamp of one sensor within the tolerance makes a sample of its own.

    >>> al = SensorAligner(["a", "b"], period_ns=1000)
    >>> al.add_block("a", np.array([0, 1000, 2000]), np.ones((3, 2)))
    >>> al.add_block("b", np.array([2, 1001]), np.zeros((2, 2)))
    >>> al.pop_ready().stamps_ns.tolist()          # 2000 waits for sensor b
    [0, 1000]
    >>> out = al.pop_ready(flush=True)
    >>> out.stamps_ns.tolist(), out.present.tolist(), al.counters["missing_b"]
    ([2000], [[True, False]], 1)
    """

    def __init__(self, sensors: Sequence[str], period_ns: float, match_tolerance_fraction: float = 0.25,
                 reorder_window_ns: int = 200_000_000) -> None:
        if not 0.0 <= match_tolerance_fraction < 0.5:
            raise ConfigError(f"match_tolerance_fraction: in [0, 0.5), got {match_tolerance_fraction!r}")
        self.sensors = tuple(sensors)
        self.tolerance_ns = int(match_tolerance_fraction * period_ns)
        self.queue = StreamAligner([StreamSpec(s, 2, required=False) for s in self.sensors], self.tolerance_ns,
                                   int(reorder_window_ns), duplicate_memory_ns=None, reject_non_finite=False,
                                   release_complete=True)

    @property
    def counters(self) -> dict[str, int]:
        """``released`` and per sensor ``received_``, ``late_``, ``duplicate_``, ``missing_``."""
        c = self.queue.counters
        return {"released": self.queue.released, **{f"{r}_{s}": c[f"{r}_{s}"] for r in
                                                    ("received", "late", "duplicate", "missing") for s in self.sensors}}

    @property
    def pending(self) -> int:
        """Aligned samples waiting."""
        return self.queue.pending_samples

    def add_block(self, sensor: str, stamps_ns: np.ndarray, values: np.ndarray) -> None:
        """Queue a block of one sensor: ``stamps_ns`` (N,) int ns, ``values`` (N, 2) [x, y]."""
        if sensor not in self.sensors:
            raise InputError(f"unknown sensor {sensor!r}; the rotor file has {list(self.sensors)}")
        self.queue.add_block(sensor, stamps_ns, values)

    def pop_ready(self, flush: bool = False) -> AlignedSamples:
        """Release the decided samples (all pending ones with ``flush``)."""
        out = self.queue.flush() if flush else self.queue.pop_ready()
        return AlignedSamples(out.stamps_ns, out.values.reshape(-1, len(self.sensors), 2), out.present)


@dataclass(frozen=True)
class PipelineOptions:
    """Streaming settings of :class:`VirtualSensingPipeline` (the live node's parameters).

    * ``reorder_window_s``: how long (sample time) a sample waits for missing sensors, s.
    * ``match_tolerance_fraction``: stamps of different sensors within this fraction of a
      sample period are one sample.
    * ``publish_rate_hz``: outputs per second of sample time (0: every sample); every
      sample is filtered regardless.
    * ``max_gap_s``: a stretch without samples longer than this restarts the filter from
      the prior, s.
    * ``use_keyphasor``: shaft angle from keyphasor pulses (causal fit); False: the rotor
      file's speed times the time since the first sample.
    """

    reorder_window_s: float = 0.2
    match_tolerance_fraction: float = 0.25
    publish_rate_hz: float = 0.0
    max_gap_s: float = 0.5
    use_keyphasor: bool = True
    tachometer: TachometerConfig = field(default_factory=TachometerConfig)

    def __post_init__(self) -> None:
        for name, low, high in (("reorder_window_s", 0.0, 60.0), ("publish_rate_hz", 0.0, 1e6),
                                ("max_gap_s", 0.0, 3600.0)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and low <= v <= high):
                raise ConfigError(f"virtual_sensing.{name}: a number in [{low:g}, {high:g}], got {v!r}")
        if not 0.0 <= self.match_tolerance_fraction < 0.5:
            raise ConfigError(f"virtual_sensing.match_tolerance_fraction: in [0, 0.5), "
                              f"got {self.match_tolerance_fraction!r}")


class StationOutput(NamedTuple):
    """Station estimates for the sample at ``stamp_ns`` (see :class:`StationSample`)."""

    stamp_ns: int
    mean: np.ndarray
    std: np.ndarray
    disp_cov: np.ndarray
    nis: float
    n_used: int


class PipelineStatus(NamedTuple):
    """Health for ``/diagnostics``: ``level`` 0 OK, 1 WARN, 2 ERROR; ``values`` counters."""

    level: int
    message: str
    values: dict


class VirtualSensingPipeline:
    """Live virtual sensing without ROS: sensor blocks and keyphasor pulses in, station
    estimates out, through :class:`SensorAligner` and :meth:`StationFilter.step` (the
    code :func:`estimate_stations` runs offline).

    ``on_block(sensor, stamps_ns, values)`` / ``on_pulse(stamp_ns)`` in any order, then
    ``process()`` (``flush=True`` when the input stopped) returns the new
    :class:`StationOutput` s (every sample, or decimated to ``publish_rate_hz``).
    Missing sensors leave their channels out of the update; missing samples are predicted
    over; a gap over ``max_gap_s`` restarts the filter; samples before the shaft angle is
    known are dropped (``no_shaft_angle``). ``status()``: counts and the coverage so far of
    the innovation's ``confidence`` region (fraction of updates with NIS below
    ``chi2.ppf(confidence, channels used)``; expected: ``confidence``).
    """

    def __init__(self, ss: FlexibleStateSpace, config: VirtualSensingConfig = VirtualSensingConfig(),
                 stations: list[tuple[str, float]] | None = None,
                 options: PipelineOptions = PipelineOptions()) -> None:
        self.ss, self.config, self.options = ss, config, options
        self.station_filter = StationFilter(ss, config, stations)
        self.stations = self.station_filter.stations
        sensors = [s.name for s in ss.rotor.sensors]
        self.period_ns = ss.dt_s * 1e9
        self.aligner = SensorAligner(sensors, self.period_ns, options.match_tolerance_fraction,
                                     int(round(options.reorder_window_s * 1e9)))
        self.tracker = ShaftAngleTracker(options.tachometer)
        idx = {s: i for i, s in enumerate(sensors)}
        self._slot = np.array([idx[s] for s in ss.channel_sensor])
        self._col = np.array([0 if name.endswith("_x") else 1 for name in ss.channel_names])
        self._publish_ns = 0 if options.publish_rate_hz == 0 else 1e9 / options.publish_rate_hz
        self._last_ns: int | None = None          # newest filtered sample
        self._last_angle: tuple[int, float] | None = None
        self._first_ns: int | None = None
        self._last_out_ns: float | None = None
        self.counters: dict[str, int] = dict.fromkeys(
            ("samples_filtered", "samples_predicted_over", "no_shaft_angle", "filter_restarts", "outputs",
             "nis_updates", "nis_inside", "pulses", "pulses_rejected", "unknown_sensor_blocks"), 0)
        self._nis_sum = 0.0
        self._dof_sum = 0
        self._nis_limits: dict[int, float] = {}
        self._pulses: list[int] = []

    # ----------------------------------------------------------------- input
    def on_block(self, sensor: str, stamps_ns: np.ndarray, values: np.ndarray) -> None:
        if sensor not in self.aligner.sensors:
            self.counters["unknown_sensor_blocks"] += 1
            raise InputError(f"unknown sensor {sensor!r}; the rotor file has {list(self.aligner.sensors)}")
        self.aligner.add_block(sensor, stamps_ns, values)

    def on_pulse(self, stamp_ns: int) -> bool:
        ok = self.tracker.add_pulse(int(stamp_ns))
        self.counters["pulses" if ok else "pulses_rejected"] += 1
        if ok:
            bisect.insort(self._pulses, int(stamp_ns))
            del self._pulses[:-64]
        return ok

    # ----------------------------------------------------------------- processing
    def _angle(self, stamp_ns: int) -> float | None:
        w = self.ss.rotor.speed_rad_s
        if not self.options.use_keyphasor:
            if self._first_ns is None:
                self._first_ns = stamp_ns
            return w * (stamp_ns - self._first_ns) * 1e-9
        st = self.tracker.query(stamp_ns)
        if st.valid:
            self._last_angle = (stamp_ns, st.angle_rad)
            return st.angle_rad
        if self._last_angle is not None and abs(stamp_ns - self._last_angle[0]) * 1e-9 <= self.options.max_gap_s:
            return self._last_angle[1] + w * (stamp_ns - self._last_angle[0]) * 1e-9
        j = bisect.bisect_right(self._pulses, stamp_ns)  # one pulse known: angle 0 there, rotor file's speed
        if j and stamp_ns - self._pulses[j - 1] <= 1.5e9 * 2 * math.pi / w:
            return w * (stamp_ns - self._pulses[j - 1]) * 1e-9
        return None

    def _u(self, angle: float) -> np.ndarray:
        w = self.ss.rotor.speed_rad_s
        return w * w * np.array([math.cos(angle), math.sin(angle)])

    def _advance_to(self, stamp_ns: int) -> bool:
        """Predict over missing samples up to ``stamp_ns``; False if the filter restarted."""
        sf = self.station_filter
        if not sf.started or self._last_ns is None:
            return False
        steps = int(round((stamp_ns - self._last_ns) / self.period_ns))
        if (stamp_ns - self._last_ns) * 1e-9 > self.options.max_gap_s:
            sf.filter = None
            self.counters["filter_restarts"] += 1
            return False
        for j in range(1, steps):
            angle = self._angle(int(self._last_ns + j * self.period_ns))
            if angle is None:
                sf.filter = None
                self.counters["filter_restarts"] += 1
                return False
            sf.skip(self._u(angle))
            self.counters["samples_predicted_over"] += 1
        return True

    def process(self, flush: bool = False) -> list[StationOutput]:
        """Filter every released sample; return the outputs due for publication."""
        ready = self.aligner.pop_ready(flush)
        if not len(ready.stamps_ns):
            return []
        with single_threaded_blas():
            outputs = self._filter(ready)
        self.counters["outputs"] += len(outputs)
        return outputs

    def _filter(self, ready: AlignedSamples) -> list[StationOutput]:
        outputs: list[StationOutput] = []
        sf = self.station_filter
        for stamp, values, present in zip(ready.stamps_ns.tolist(), ready.values, ready.present):
            angle = self._angle(stamp)
            if angle is None:
                self.counters["no_shaft_angle"] += 1
                continue
            self._advance_to(stamp)
            u = self._u(angle)
            z = values[self._slot, self._col]
            mask = present[self._slot]
            r = sf.step(z, u, mask)
            self._last_ns = stamp
            self.counters["samples_filtered"] += 1
            dof = int(np.count_nonzero(mask & np.isfinite(z)))
            if dof:
                self.counters["nis_updates"] += 1
                self.counters["nis_inside"] += int(r.nis <= self._nis_limit(dof))
                self._nis_sum += r.nis
                self._dof_sum += dof
            if self._last_out_ns is None or stamp - self._last_out_ns >= self._publish_ns - 0.5 * self.period_ns:
                self._last_out_ns = stamp
                outputs.append(StationOutput(stamp, r.mean, r.std, r.disp_cov, r.nis, r.n_used))
        return outputs

    def _nis_limit(self, dof: int) -> float:
        lim = self._nis_limits.get(dof)
        if lim is None:
            lim = self._nis_limits[dof] = float(chi2.ppf(self.config.confidence, dof))
        return lim

    # ----------------------------------------------------------------- health
    @property
    def last_sample_stamp_ns(self) -> int | None:
        """Stamp of the newest filtered sample (ns), or None."""
        return self._last_ns

    @property
    def nis_coverage(self) -> float:
        n = self.counters["nis_updates"]
        return self.counters["nis_inside"] / n if n else float("nan")

    def status(self) -> PipelineStatus:
        """Counts, NIS coverage so far and a level: WARN when the coverage is off by more
        than ``coverage_tolerance`` (after 200 updates) or samples are late/missing/dropped."""
        c = dict(self.counters)
        c.update(self.aligner.counters)
        f = self.station_filter.filter
        c["gated_updates"] = 0 if f is None else f.n_gated
        c["non_finite_channels"] = 0 if f is None else f.n_rejected
        cov = self.nis_coverage
        values = {k: str(v) for k, v in c.items()}
        values["nis_coverage"] = f"{cov:.4f}"
        values["nis_coverage_expected"] = f"{self.config.confidence:.4f}"
        values["mean_nis_per_dof"] = f"{self._nis_sum / self._dof_sum:.4f}" if self._dof_sum else "nan"
        values["filter"] = self.config.filter
        values["pending_samples"] = str(self.aligner.pending)
        problems = []
        if c["nis_updates"] >= 200 and abs(cov - self.config.confidence) > self.config.coverage_tolerance:
            problems.append(f"innovation coverage {cov:.3f} vs {self.config.confidence:.2f}: intervals not "
                            f"calibrated (model, Q or R do not match the data)")
        dropped = sum(v for k, v in c.items() if k.startswith(("late_", "duplicate_"))) + c["no_shaft_angle"]
        missing = sum(v for k, v in c.items() if k.startswith("missing_"))
        if dropped or missing:
            problems.append(f"{dropped} samples dropped (late, duplicate, no shaft angle), {missing} sensor "
                            f"samples missing")
        if c["samples_filtered"] == 0:
            return PipelineStatus(1, "waiting for sensor samples and keyphasor pulses", values)
        if problems:
            return PipelineStatus(1, "; ".join(problems), values)
        return PipelineStatus(0, f"{c['samples_filtered']} samples, innovation coverage {cov:.3f}", values)
