"""Virtual sensing: vibration at stations without a sensor, with honest 95% intervals.

* :func:`estimate_stations`: displacement, velocity and acceleration at any axial
  station (linear outputs ``C x + D u`` of the filter's state), intervals from
  ``C P C^T`` (``z * sigma`` per axis) and the displacement orbit's confidence ellipse.
* :func:`leave_one_station_out`: Neisi et al.'s Table 6 check made quantitative: hide
  one sensor (all its channels), estimate it from the others, and report the error
  against the hidden measurement, the fraction of samples inside the interval
  (``coverage``; the hidden measurement is compared with the predicted value's
  interval widened by that sensor's own noise variance), the interval width, and, when
  the true state is known (simulation), the coverage of the noise-free value.

An interval that always contains the measurement because it is huge is not a success:
the report gives the mean width and its ratio to the hidden signal's RMS.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import asdict, dataclass, field
from typing import NamedTuple, Sequence

import numpy as np
from scipy.stats import chi2, norm

from .errors import ConfigError, InputError
from .flexible.state_space import FlexibleStateSpace, periodic_steady_state, station_outputs
from .linear_filters import (ExtendedKalmanFilter, KalmanFilter, LinearGaussianModel, UnscentedKalmanFilter,
                             single_threaded_blas)
from .tachometer import ShaftAngleTracker, TachometerConfig, shaft_states_from_pulses

__all__ = ["VirtualSensingConfig", "make_filter", "StationEstimate", "estimate_stations", "confidence_ellipse",
           "ChannelCheck", "HiddenTrace", "LeaveOneOutReport", "leave_one_station_out", "FILTERS",
           "STATION_QUANTITIES", "resolve_stations", "StationSample", "StationFilter", "shaft_angle_from_pulses",
           "SensorAligner", "AlignedSamples", "PipelineOptions", "StationOutput", "PipelineStatus",
           "VirtualSensingPipeline"]

FILTERS = ("kf", "ekf", "ukf")


@dataclass(frozen=True)
class VirtualSensingConfig:
    """``filter``: 'kf' (exact, linear model), 'ekf' or 'ukf' (filterpy's scaled sigma
    points: ``ukf_alpha``, ``ukf_beta``, ``ukf_kappa``); ``confidence`` of the intervals;
    ``burn_in_samples`` left out of the statistics; ``coverage_tolerance``: allowed
    |coverage - confidence| before a channel is flagged; ``gate_probability``: innovation
    gate of the filter's update (None: off, the default; see :mod:`~rotor_estimator.linear_filters`)."""

    filter: str = "kf"
    ukf_alpha: float = 1e-3
    ukf_beta: float = 2.0
    ukf_kappa: float = 0.0
    confidence: float = 0.95
    burn_in_samples: int = 0
    coverage_tolerance: float = 0.03
    gate_probability: float | None = None

    def __post_init__(self) -> None:
        if self.filter not in FILTERS:
            raise ConfigError(f"virtual_sensing.filter: one of {FILTERS}, got {self.filter!r}")
        if not 0 < self.ukf_alpha <= 1:
            raise ConfigError(f"virtual_sensing.ukf_alpha: must be in (0, 1], got {self.ukf_alpha!r}")
        if self.ukf_beta < 0:
            raise ConfigError(f"virtual_sensing.ukf_beta: must be >= 0, got {self.ukf_beta!r}")
        if not 0 < self.confidence < 1:
            raise ConfigError(f"virtual_sensing.confidence: must be in (0, 1), got {self.confidence!r}")
        if not isinstance(self.burn_in_samples, int) or self.burn_in_samples < 0:
            raise ConfigError(f"virtual_sensing.burn_in_samples: integer >= 0, got {self.burn_in_samples!r}")
        if not 0 < self.coverage_tolerance < 1:
            raise ConfigError(f"virtual_sensing.coverage_tolerance: in (0, 1), got {self.coverage_tolerance!r}")
        if self.gate_probability is not None and not 0 < self.gate_probability < 1:
            raise ConfigError(f"virtual_sensing.gate_probability: in (0, 1) or None (off), "
                              f"got {self.gate_probability!r}")

    @property
    def z_value(self) -> float:
        """Two-sided normal quantile (1.96 for 95%)."""
        return float(norm.ppf(0.5 + 0.5 * self.confidence))


def make_filter(model: LinearGaussianModel, x0: np.ndarray, P0: np.ndarray, config: VirtualSensingConfig):
    """The configured filter on ``model``; all three share the streaming interface."""
    g = config.gate_probability
    if config.filter == "kf":
        return KalmanFilter(model, x0, P0, gate_probability=g)
    if config.filter == "ekf":
        return ExtendedKalmanFilter.from_linear(model, x0, P0, gate_probability=g)
    return UnscentedKalmanFilter.from_linear(model, x0, P0, config.ukf_alpha, config.ukf_beta, config.ukf_kappa,
                                             gate_probability=g)


def _initial(ss: FlexibleStateSpace, u0: np.ndarray | None) -> np.ndarray:
    if u0 is None or not np.any(u0):
        return np.zeros(ss.n_states)
    return periodic_steady_state(ss, math.atan2(u0[1], u0[0]))


def confidence_ellipse(cov2: np.ndarray, confidence: float = 0.95) -> tuple[float, float, float]:
    """(semi-major, semi-minor, angle of the major axis from +x in rad) of the
    ``confidence`` ellipse of a 2-D Gaussian with covariance ``cov2`` (chi-square, 2 dof)."""
    r = math.sqrt(-2.0 * math.log(1.0 - confidence))
    lam, vec = np.linalg.eigh(0.5 * (cov2 + cov2.T))
    lam = np.clip(lam, 0.0, None)
    return r * math.sqrt(lam[1]), r * math.sqrt(lam[0]), math.atan2(vec[1, 1], vec[0, 1])


def resolve_stations(ss: FlexibleStateSpace, names: list[str] | tuple[str, ...] | None = None
                     ) -> list[tuple[str, float]]:
    """``(name, axial m)`` of the stations to estimate. ``names`` entries: a station of the
    rotor file, a sensor of the rotor file (its station), or ``'name=0.35'`` (any axial
    position in m); None or empty: every station of the rotor file.

    >>> from rotor_estimator.flexible import build_state_space, load_rotor_description
    >>> ss = build_state_space(load_rotor_description("three_probe_rig"))
    >>> resolve_stations(ss, ["disk1", "probe2", "gap=0.2"])
    [('disk1', 0.3), ('probe2', 0.42), ('gap', 0.2)]
    """
    rotor = ss.rotor
    if not names:
        out = [(st.name, st.station_axial_m) for st in rotor.stations]
        if not out:
            raise InputError("no stations given and the rotor file lists none; name some (e.g. 'mid=0.4')")
        return out
    known = {st.name: st.station_axial_m for st in rotor.sensors}
    known.update({st.name: st.station_axial_m for st in rotor.stations})
    out = []
    for item in names:
        name, sep, pos = str(item).partition("=")
        name = name.strip()
        if sep:
            try:
                axial = float(pos)
            except ValueError:
                raise InputError(f"station {item!r}: expected 'name=axial_position_m'") from None
            if not 0.0 <= axial <= rotor.length_m:
                raise InputError(f"station {item!r}: axial position must be in [0, {rotor.length_m:g}] m")
        elif name in known:
            axial = known[name]
        else:
            raise InputError(f"station {name!r}: not a station or sensor of rotor {rotor.name} "
                             f"(known: {sorted(known)}); or give 'name=axial_position_m'")
        out.append((name, float(axial)))
    if len({n for n, _ in out}) != len(out):
        raise InputError(f"station names must be unique, got {[n for n, _ in out]}")
    return out


class StationSample(NamedTuple):
    """Outputs at S stations for one sample: ``mean``, ``std`` (S, 6) in the order of
    :data:`STATION_QUANTITIES` (m, m/s, m/s^2), ``disp_cov`` (S, 2, 2) displacement
    covariance (m^2); ``nis``, ``n_used``, ``gated`` of the sample's update."""

    mean: np.ndarray
    std: np.ndarray
    disp_cov: np.ndarray
    nis: float
    n_used: int
    gated: bool


#: Station output order (``station_outputs``): displacement, velocity, acceleration x/y.
STATION_QUANTITIES = ("displacement_x", "displacement_y", "velocity_x", "velocity_y", "acceleration_x",
                      "acceleration_y")


class StationFilter:
    """The per-sample step shared by offline estimation and the live node.

    ``step(z, u, mask)``: 1. update on the present, finite channels of ``z`` (p,) (input
    ``u`` (2,) for the direct term); 2. station outputs ``C x + D u`` with covariance
    ``C P C^T`` (per station); 3. predict to the next sample with ``u`` held (ZOH).
    ``skip(u)``: a sample without any measurement (predict only). The filter starts at
    the periodic steady state of the first sample's shaft angle with the stationary
    covariance ``P0``.
    """

    def __init__(self, ss: FlexibleStateSpace, config: VirtualSensingConfig = VirtualSensingConfig(),
                 stations: list[tuple[str, float]] | None = None) -> None:
        self.ss, self.config = ss, config
        self.stations = resolve_stations(ss) if stations is None else list(stations)
        if not self.stations:
            raise InputError("StationFilter: no stations to estimate")
        blocks = [station_outputs(ss, pos) for _, pos in self.stations]
        self.C = np.vstack([b[0] for b in blocks])
        self.D = np.vstack([b[1] for b in blocks])
        self.filter = None
        self.n_samples = 0

    @property
    def started(self) -> bool:
        return self.filter is not None

    def start(self, u0: np.ndarray | None) -> None:
        """(Re)start from the steady state at ``u0``'s shaft angle and the prior P0."""
        self.filter = make_filter(self.ss.model, _initial(self.ss, u0), self.ss.P0, self.config)

    def step(self, z: np.ndarray, u: np.ndarray, mask: np.ndarray | None = None) -> StationSample:
        if self.filter is None:
            self.start(u)
        f = self.filter
        f.update(z, u=u, mask=mask)
        S = len(self.stations)
        mean = (self.C @ f.x + self.D @ u).reshape(S, 6)
        CP = self.C @ f.P
        cov = np.empty((S, 6, 6))
        for i in range(S):
            sl = slice(6 * i, 6 * i + 6)
            cov[i] = CP[sl] @ self.C[sl].T
        std = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
        out = StationSample(mean, std, cov[:, :2, :2], f.last_nis, f.last_n_used, f.last_gated)
        f.predict(u)
        self.n_samples += 1
        return out

    def skip(self, u: np.ndarray) -> None:
        """No measurement at this sample: predict only."""
        if self.filter is None:
            self.start(u)
        self.filter.predict(u)


@dataclass(frozen=True)
class StationEstimate:
    """``mean``, ``std`` (N, 6) for ``names`` = displacement/velocity/acceleration x, y
    (m, m/s, m/s^2); ``half_width = z * std``; ``disp_cov`` (N, 2, 2) for the orbit ellipse."""

    name: str
    station_axial_m: float
    t_s: np.ndarray
    names: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    half_width: np.ndarray
    disp_cov: np.ndarray

    def ellipse(self, k: int, confidence: float = 0.95) -> tuple[float, float, float]:
        return confidence_ellipse(self.disp_cov[k], confidence)


def estimate_stations(ss: FlexibleStateSpace, t_s: np.ndarray, z: np.ndarray, u: np.ndarray,
                      config: VirtualSensingConfig = VirtualSensingConfig(),
                      stations: list[tuple[str, float]] | None = None,
                      mask: np.ndarray | None = None) -> list[StationEstimate]:
    """Run the filter once over ``z`` (N, p) and return estimates at ``stations``
    (name, axial m); default: the stations of the rotor file. Each sample goes through
    :meth:`StationFilter.step`, the code the live node runs."""
    sf = StationFilter(ss, config, resolve_stations(ss) if stations is None else stations)
    N, S = len(z), len(sf.stations)
    mean, std, dcov = np.empty((N, S, 6)), np.empty((N, S, 6)), np.empty((N, S, 2, 2))
    masks = None if mask is None else np.asarray(mask, bool)
    with single_threaded_blas():
        for k in range(N):
            mk = None if masks is None else (masks if masks.ndim == 1 else masks[k])
            r = sf.step(z[k], u[k], mk)
            mean[k], std[k], dcov[k] = r.mean, r.std, r.disp_cov
    return [StationEstimate(name, pos, np.asarray(t_s), STATION_QUANTITIES, mean[:, i], std[:, i],
                            config.z_value * std[:, i], dcov[:, i])
            for i, (name, pos) in enumerate(sf.stations)]


def shaft_angle_from_pulses(ss: FlexibleStateSpace, stamps_ns: np.ndarray, pulse_stamps_ns: np.ndarray,
                            tachometer: TachometerConfig | None = None) -> tuple[np.ndarray, int]:
    """Offline shaft angle (rad) at ``stamps_ns`` from keyphasor pulses (centered fit of
    :func:`~rotor_estimator.tachometer.shaft_states_from_pulses`) and how many samples had
    no valid fit: those continue from the nearest valid sample at the rotor file's speed
    (without any pulse: ``speed * (t - t[0])``, as an NPZ without ``shaft_angle_rad``)."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    w = ss.rotor.speed_rad_s
    pulses = np.asarray(pulse_stamps_ns, dtype=np.int64)
    if len(pulses) == 0 or len(stamps) == 0:
        return w * (stamps - (stamps[0] if len(stamps) else 0)).astype(float) * 1e-9, len(stamps)
    states, _ = shaft_states_from_pulses(pulses, stamps, tachometer)
    angle = np.array(states.angle_rad, dtype=float)
    valid = np.asarray(states.valid, bool)
    bad = np.flatnonzero(~valid)
    if len(bad) and valid.any():
        good = np.flatnonzero(valid)
        pos = np.clip(np.searchsorted(good, bad), 0, len(good) - 1)
        left = good[np.clip(pos - 1, 0, len(good) - 1)]
        right = good[pos]
        ref = np.where(np.abs(stamps[bad] - stamps[left]) < np.abs(stamps[right] - stamps[bad]), left, right)
        angle[bad] = angle[ref] + w * (stamps[bad] - stamps[ref]).astype(float) * 1e-9
    elif len(bad):
        angle = w * (stamps - stamps[0]).astype(float) * 1e-9
    return angle, int(len(bad))


@dataclass(frozen=True)
class ChannelCheck:
    """One hidden channel. ``coverage_measured``: fraction of samples whose hidden
    measurement lies in the prediction interval (with its own sensor noise);
    ``coverage_true``: the same for the noise-free value (NaN without truth);
    ``mean_interval_width``: upper minus lower bound for the hidden measurement, in
    ``unit``; ``mean_state_interval_width``: the same without the hidden sensor's noise
    (the interval of the noise-free value), which shows how much the estimate knows."""

    sensor: str
    channel: str
    unit: str
    n_samples: int
    rms_error: float
    coverage_measured: float
    coverage_true: float
    mean_interval_width: float
    mean_state_interval_width: float
    signal_rms: float
    width_to_signal_rms: float
    calibrated: bool


@dataclass(frozen=True)
class HiddenTrace:
    """Per-sample record of one hidden sensor (``keep_traces=True``), (N, c) arrays for
    its channels: the hidden ``measured`` values, the ``predicted`` ones, the interval
    half-widths of the measurement (``half_width``, with the sensor's noise) and of the
    noise-free value (``half_width_state``); ``clean`` noise-free truth or None."""

    sensor: str
    channels: tuple[str, ...]
    units: tuple[str, ...]
    measured: np.ndarray
    predicted: np.ndarray
    half_width: np.ndarray
    half_width_state: np.ndarray
    clean: np.ndarray | None = None


@dataclass(frozen=True)
class LeaveOneOutReport:
    filter: str
    confidence: float
    rows: tuple[ChannelCheck, ...]
    n_rejected: int
    traces: tuple[HiddenTrace, ...] = field(default=(), compare=False, repr=False)

    def summary(self, unit: str = "m") -> dict[str, float]:
        """Mean coverage and interval width over hidden channels in ``unit``."""
        sel = [r for r in self.rows if r.unit == unit]
        if not sel:
            return {"coverage": float("nan"), "interval_width": float("nan")}
        return {"coverage": float(np.mean([r.coverage_measured for r in sel])),
                "interval_width": float(np.mean([r.mean_interval_width for r in sel]))}

    def to_dict(self) -> dict:
        return {"filter": self.filter, "confidence": self.confidence, "n_rejected": self.n_rejected,
                "channels": [asdict(r) for r in self.rows]}

    def format_table(self) -> str:
        head = (f"{'hidden':<10} {'channel':<12} {'unit':<6} {'rms error':>10} {'coverage':>9} {'cov.true':>9} "
                f"{'width':>10} {'w.state':>10} {'width/rms':>9}  ok")
        lines = [f"leave-one-station-out, filter={self.filter}, {100 * self.confidence:.0f}% intervals", head,
                 "-" * len(head)]
        for r in self.rows:
            lines.append(f"{r.sensor:<10} {r.channel:<12} {r.unit:<6} {r.rms_error:>10.3e} "
                         f"{r.coverage_measured:>9.3f} {r.coverage_true:>9.3f} {r.mean_interval_width:>10.3e} "
                         f"{r.mean_state_interval_width:>10.3e} "
                         f"{r.width_to_signal_rms:>9.2f}  {'yes' if r.calibrated else 'NO'}")
        lines.append(f"non-finite samples rejected: {self.n_rejected}; width: 95% interval of the hidden "
                     f"measurement (incl. its sensor noise); w.state: of the noise-free value; "
                     f"width/rms: width over the hidden signal's std")
        return "\n".join(lines)


def leave_one_station_out(ss: FlexibleStateSpace, z: np.ndarray, u: np.ndarray,
                          config: VirtualSensingConfig = VirtualSensingConfig(),
                          hidden: list[str] | None = None, x_true: np.ndarray | None = None,
                          keep_traces: bool = False) -> LeaveOneOutReport:
    """Table 6 of Neisi et al.: for each sensor in ``hidden`` (default: all), run the
    filter without its channels and check the prediction of those channels
    (``keep_traces``: also return the per-sample :class:`HiddenTrace` for plots)."""
    z = np.asarray(z, dtype=float)
    sensors = list(dict.fromkeys(ss.channel_sensor)) if hidden is None else list(hidden)
    owner = np.array(ss.channel_sensor)
    if len(sensors) < 1 or len(set(owner)) < 2:
        raise InputError("leave-one-station-out needs at least two sensors (one to hide, one to keep)")
    m, zval, b = ss.model, config.z_value, config.burn_in_samples
    x0 = _initial(ss, u[0] if len(u) else None)
    rows, rejected, traces = [], 0, []
    for s in sensors:
        idx = np.flatnonzero(owner == s)
        if len(idx) == 0:
            raise InputError(f"hidden sensor {s!r}: not in the rotor file (sensors: {sorted(set(owner))})")
        f = make_filter(m, x0, ss.P0, config)
        run = f.run(z, u, masks=owner != s, outputs=(m.H[idx], m.D[idx]))
        rejected = max(rejected, run.n_rejected)
        var_state = np.clip(np.diagonal(run.y_cov, axis1=1, axis2=2), 0.0, None)
        var_meas = var_state + np.diag(m.R)[idx]
        clean = None if x_true is None else x_true @ m.H[idx].T + u @ m.D[idx].T
        if keep_traces:
            traces.append(HiddenTrace(s, tuple(ss.channel_names[c] for c in idx),
                                      tuple(ss.channel_units[c] for c in idx), z[:, idx], run.y,
                                      zval * np.sqrt(var_meas), zval * np.sqrt(var_state), clean))
        for j, ch in enumerate(idx):
            zh, pred = z[b:, ch], run.y[b:, j]
            ok = np.isfinite(zh)
            err = zh[ok] - pred[ok]
            half = zval * np.sqrt(var_meas[b:, j][ok])
            cov_m = float(np.mean(np.abs(err) <= half)) if ok.any() else float("nan")
            cov_t = float("nan")
            if clean is not None:
                cov_t = float(np.mean(np.abs(clean[b:, j] - pred) <= zval * np.sqrt(var_state[b:, j])))
            width = float(np.mean(2.0 * half)) if ok.any() else float("nan")
            width_state = float(np.mean(2.0 * zval * np.sqrt(var_state[b:, j])))
            sig = float(np.std(zh[ok])) if ok.any() else float("nan")
            rows.append(ChannelCheck(s, ss.channel_names[ch], ss.channel_units[ch], int(ok.sum()),
                                     float(np.sqrt(np.mean(err ** 2))) if ok.any() else float("nan"), cov_m, cov_t,
                                     width, width_state, sig, width / sig if sig > 0 else float("inf"),
                                     bool(abs(cov_m - config.confidence) <= config.coverage_tolerance)))
    return LeaveOneOutReport(config.filter, config.confidence, tuple(rows), rejected, tuple(traces))


# --------------------------------------------------------------------------- streaming
class AlignedSamples(NamedTuple):
    """Released samples in increasing stamp order: ``stamps_ns`` (M,) int64, ``values``
    (M, S, 2) per sensor [x, y] (NaN where absent), ``present`` (M, S) bool."""

    stamps_ns: np.ndarray
    values: np.ndarray
    present: np.ndarray


class SensorAligner:
    """Time ordering of S sensors' sample blocks by stamp (a queue keyed by stamp).

    * **Matching**: a sample joins the pending sample whose stamp is nearest, if within
      ``match_tolerance_fraction`` of the sample period (that first stamp is kept);
      otherwise it opens a new pending sample.
    * **Release**, oldest first: a pending sample is released when every sensor is
      present, or when it is ``reorder_window_ns`` older than the newest stamp seen, or
      on ``pop_ready(flush=True)``; each sensor absent then counts ``missing_<sensor>``.
    * **Late**: a sample not newer than the last released stamp (plus the tolerance) is
      dropped (``late_<sensor>``): the filter cannot go back in time.
    * **Duplicate**: a second sample of one sensor in one pending sample is dropped
      (``duplicate_<sensor>``); the first wins.

    Every sample received ends in exactly one of: released, ``late``, ``duplicate``, or
    still pending.

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
        self.sensors = tuple(sensors)
        if not self.sensors or len(set(self.sensors)) != len(self.sensors):
            raise InputError(f"SensorAligner: sensor names must be unique and non-empty, got {self.sensors}")
        if not 0.0 <= match_tolerance_fraction < 0.5:
            raise ConfigError(f"match_tolerance_fraction: in [0, 0.5), got {match_tolerance_fraction!r}")
        self._index = {s: i for i, s in enumerate(self.sensors)}
        self.tolerance_ns = int(match_tolerance_fraction * period_ns)
        self.reorder_window_ns = int(reorder_window_ns)
        self._keys: list[int] = []
        self._values: dict[int, np.ndarray] = {}
        self._present: dict[int, np.ndarray] = {}
        self._newest: int | None = None
        self.last_released_ns: int | None = None
        self.counters: dict[str, int] = {"released": 0}
        for c in ("received", "late", "duplicate", "missing"):
            for s in self.sensors:
                self.counters[f"{c}_{s}"] = 0

    @property
    def pending(self) -> int:
        return len(self._keys)

    def add_block(self, sensor: str, stamps_ns: np.ndarray, values: np.ndarray) -> None:
        """Queue a block of one sensor: ``stamps_ns`` (N,) int ns, ``values`` (N, 2) [x, y]."""
        i = self._index.get(sensor)
        if i is None:
            raise InputError(f"unknown sensor {sensor!r}; the rotor file has {list(self.sensors)}")
        stamps = np.asarray(stamps_ns)
        vals = np.asarray(values, dtype=float)
        if stamps.ndim != 1 or not np.issubdtype(stamps.dtype, np.integer) or vals.shape != (len(stamps), 2):
            raise InputError(f"sensor {sensor}: expected integer stamps (N,) and values (N, 2), got "
                             f"{stamps.dtype} {stamps.shape} and {vals.shape}")
        c, tol, keys = self.counters, self.tolerance_ns, self._keys
        c[f"received_{sensor}"] += len(stamps)
        for t, v in zip(stamps.tolist(), vals):
            if self.last_released_ns is not None and t <= self.last_released_ns + tol:
                c[f"late_{sensor}"] += 1
                continue
            j = bisect.bisect_left(keys, t)
            key = None
            for cand in (j - 1, j):
                if 0 <= cand < len(keys) and abs(keys[cand] - t) <= tol and (
                        key is None or abs(keys[cand] - t) < abs(key - t)):
                    key = keys[cand]
            if key is None:
                key = t
                keys.insert(j, t)
                self._values[t] = np.full((len(self.sensors), 2), np.nan)
                self._present[t] = np.zeros(len(self.sensors), bool)
            if self._present[key][i]:
                c[f"duplicate_{sensor}"] += 1
                continue
            self._present[key][i] = True
            self._values[key][i] = v
            if self._newest is None or t > self._newest:
                self._newest = t

    def pop_ready(self, flush: bool = False) -> AlignedSamples:
        """Release the decided samples (all pending ones with ``flush``)."""
        horizon = None if self._newest is None else self._newest - self.reorder_window_ns
        stamps, values, present = [], [], []
        while self._keys:
            k = self._keys[0]
            pres = self._present[k]
            if not (flush or pres.all() or (horizon is not None and k <= horizon)):
                break
            self._keys.pop(0)
            stamps.append(k)
            values.append(self._values.pop(k))
            present.append(self._present.pop(k))
            for s in np.flatnonzero(~pres):
                self.counters[f"missing_{self.sensors[s]}"] += 1
            self.last_released_ns = k
        self.counters["released"] += len(stamps)
        S = len(self.sensors)
        return AlignedSamples(np.asarray(stamps, dtype=np.int64),
                              np.asarray(values, dtype=float).reshape(-1, S, 2),
                              np.asarray(present, dtype=bool).reshape(-1, S))


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
        if sensor not in self.aligner._index:
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
