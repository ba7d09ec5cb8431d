# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
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

import math
from dataclasses import asdict, dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.stats import norm

from rotor_estimator.core.errors import ConfigError, InputError
from rotor_estimator.core.flexible.state_space import FlexibleStateSpace, periodic_steady_state, station_outputs
from rotor_estimator.core.linear_filters import (ExtendedKalmanFilter, KalmanFilter, LinearGaussianModel,
                                                 UnscentedKalmanFilter, single_threaded_blas)
from rotor_estimator.core.tachometer import TachometerConfig, shaft_states_from_pulses

__all__ = ["VirtualSensingConfig", "make_filter", "StationEstimate", "estimate_stations", "confidence_ellipse",
           "ChannelCheck", "HiddenTrace", "LeaveOneOutReport", "leave_one_station_out", "FILTERS",
           "STATION_QUANTITIES", "resolve_stations", "StationSample", "StationFilter", "shaft_angle_from_pulses"]

FILTERS = ("kf", "ekf", "ukf")


@dataclass(frozen=True)
class VirtualSensingConfig:
    """``filter``: 'kf' (exact, linear model), 'ekf' or 'ukf' (filterpy's scaled sigma
    points: ``ukf_alpha``, ``ukf_beta``, ``ukf_kappa``); ``confidence`` of the intervals;
    ``burn_in_samples`` left out of the statistics; ``coverage_tolerance``: allowed
    |coverage - confidence| before a channel is flagged; ``gate_probability``: innovation
    gate of the filter's update (None: off, the default; see :mod:`~rotor_estimator.core.linear_filters`)."""

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


def make_filter(model: LinearGaussianModel, x0: np.ndarray, P0: np.ndarray,
                config: VirtualSensingConfig) -> KalmanFilter | ExtendedKalmanFilter | UnscentedKalmanFilter:
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

    >>> from rotor_estimator.core.flexible import build_state_space, load_rotor_description
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
        self.filter: KalmanFilter | ExtendedKalmanFilter | UnscentedKalmanFilter | None = None
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
    :func:`~rotor_estimator.core.tachometer.shaft_states_from_pulses`) and how many samples had
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
