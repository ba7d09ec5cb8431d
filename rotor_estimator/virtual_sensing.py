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
from dataclasses import asdict, dataclass

import numpy as np
from scipy.stats import norm

from .errors import ConfigError, InputError
from .flexible.state_space import FlexibleStateSpace, periodic_steady_state, station_outputs
from .linear_filters import ExtendedKalmanFilter, KalmanFilter, LinearGaussianModel, UnscentedKalmanFilter

__all__ = ["VirtualSensingConfig", "make_filter", "StationEstimate", "estimate_stations", "confidence_ellipse",
           "ChannelCheck", "LeaveOneOutReport", "leave_one_station_out", "FILTERS"]

FILTERS = ("kf", "ekf", "ukf")


@dataclass(frozen=True)
class VirtualSensingConfig:
    """``filter``: 'kf' (exact, linear model), 'ekf' or 'ukf' (filterpy's scaled sigma
    points: ``ukf_alpha``, ``ukf_beta``, ``ukf_kappa``); ``confidence`` of the intervals;
    ``burn_in_samples`` left out of the statistics; ``coverage_tolerance``: allowed
    |coverage - confidence| before a channel is flagged."""

    filter: str = "kf"
    ukf_alpha: float = 1e-3
    ukf_beta: float = 2.0
    ukf_kappa: float = 0.0
    confidence: float = 0.95
    burn_in_samples: int = 0
    coverage_tolerance: float = 0.03

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

    @property
    def z_value(self) -> float:
        """Two-sided normal quantile (1.96 for 95%)."""
        return float(norm.ppf(0.5 + 0.5 * self.confidence))


def make_filter(model: LinearGaussianModel, x0: np.ndarray, P0: np.ndarray, config: VirtualSensingConfig):
    """The configured filter on ``model``; all three share the streaming interface."""
    if config.filter == "kf":
        return KalmanFilter(model, x0, P0)
    if config.filter == "ekf":
        return ExtendedKalmanFilter.from_linear(model, x0, P0)
    return UnscentedKalmanFilter.from_linear(model, x0, P0, config.ukf_alpha, config.ukf_beta, config.ukf_kappa)


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
    (name, axial m); default: the stations of the rotor file."""
    if stations is None:
        stations = [(s.name, s.station_axial_m) for s in ss.rotor.stations]
    if not stations:
        raise InputError("estimate_stations: no stations given and the rotor file lists none")
    blocks = [station_outputs(ss, pos) for _, pos in stations]
    C = np.vstack([b[0] for b in blocks])
    D = np.vstack([b[1] for b in blocks])
    f = make_filter(ss.model, _initial(ss, u[0] if len(u) else None), ss.P0, config)
    run = f.run(z, u, masks=mask, outputs=(C, D))
    out = []
    for i, ((name, pos), (_, _, names)) in enumerate(zip(stations, blocks)):
        sl = slice(6 * i, 6 * i + 6)
        cov = run.y_cov[:, sl, sl]
        std = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
        out.append(StationEstimate(name, pos, np.asarray(t_s), names, run.y[:, sl], std, config.z_value * std,
                                   cov[:, :2, :2]))
    return out


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
class LeaveOneOutReport:
    filter: str
    confidence: float
    rows: tuple[ChannelCheck, ...]
    n_rejected: int

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
                          ) -> LeaveOneOutReport:
    """Table 6 of Neisi et al.: for each sensor in ``hidden`` (default: all), run the
    filter without its channels and check the prediction of those channels."""
    z = np.asarray(z, dtype=float)
    sensors = list(dict.fromkeys(ss.channel_sensor)) if hidden is None else list(hidden)
    owner = np.array(ss.channel_sensor)
    if len(sensors) < 1 or len(set(owner)) < 2:
        raise InputError("leave-one-station-out needs at least two sensors (one to hide, one to keep)")
    m, zval, b = ss.model, config.z_value, config.burn_in_samples
    x0 = _initial(ss, u[0] if len(u) else None)
    rows, rejected = [], 0
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
    return LeaveOneOutReport(config.filter, config.confidence, tuple(rows), rejected)
