# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Streaming continuous-discrete EKF for the 8 bearing coefficients (Miller & Howard, Eqs. 7-17).

State ``s = [v (4), z (4), r (8)]``: bearing-center velocities and displacements and the
coefficients ``kxx kxy kyx kyy cxx cxy cyx cyy`` as Gauss-Markov (random-walk) states.

:class:`StreamingEKF` takes samples one at a time (:meth:`StreamingEKF.step`) or in
blocks (:meth:`StreamingEKF.process_block`); both run the same compiled kernel
(:mod:`rotor_estimator.core.filter_kernel`) and give identical results. Numerical safeguards:
Joseph-form update, symmetrized covariance, Cholesky solves, NaN/inf rejection,
Mahalanobis gating of outliers, and recovery to the last healthy state when the
covariance stops being positive definite or the innovations stay inconsistent.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from rotor_estimator.core import filter_kernel as kern
from rotor_estimator.core.config import COEFFICIENT_NAMES, BearingCoefficients, EstimatorConfig, RigConfig
from rotor_estimator.core.model import RotorMatrices, rotor_matrices

N_STATE = 16
COEFF_SLICE = slice(8, 16)


@dataclass(frozen=True)
class FilterModel:
    """Arrays the kernel needs, built once per rig and tuning."""

    mats: RotorMatrices
    minv: np.ndarray
    gyro: np.ndarray
    moments: np.ndarray
    phases: np.ndarray
    wimb: np.ndarray
    wimp: np.ndarray
    hp: np.ndarray
    r_var: np.ndarray
    accel_psd: float
    coeff_rw_var_rate: np.ndarray
    gate: float
    max_step_s: float

    @classmethod
    def build(cls, rig: RigConfig, config: EstimatorConfig, *, imbalance_scale: float = 1.0) -> "FilterModel":
        mats = rotor_matrices(rig)
        return cls(
            mats=mats,
            minv=np.ascontiguousarray(mats.mass_inverse),
            gyro=np.ascontiguousarray(mats.gyro_matrix),
            moments=np.ascontiguousarray(mats.imbalance_moments_kg_m * imbalance_scale),
            phases=np.ascontiguousarray(mats.imbalance_phases_rad),
            wimb=np.ascontiguousarray(mats.imbalance_input.reshape(2, -1)),
            wimp=np.ascontiguousarray(mats.impact_input),
            hp=np.ascontiguousarray(mats.probe_from_bearing),
            r_var=np.full(4, config.measurement_noise_std_m ** 2),
            accel_psd=float(config.motion_process_noise_accel_m_s2 ** 2),
            coeff_rw_var_rate=config.coefficient_random_walk.as_array() ** 2,
            gate=float(config.innovation_gate_nis),
            max_step_s=1.5 * rig.sample_period_s,
        )


@dataclass
class BlockResult:
    """Per-sample outputs of a block: status codes (``filter_kernel.STATUS_*``), NIS,
    innovation ``y - H s_bar`` (m) and predicted innovation std ``sqrt(diag S)`` (m)."""

    status: np.ndarray
    nis: np.ndarray
    innovation_m: np.ndarray
    innovation_std_m: np.ndarray

    def __len__(self) -> int:
        return int(self.status.shape[0])


@dataclass
class FilterHealth:
    """Counters and the consistency monitor of one filter."""

    counts: dict = field(default_factory=lambda: {name: 0 for name in kern.STATUS_NAMES.values()})
    divergence_recoveries: int = 0
    consecutive_rejections: int = 0
    nis_window: deque = field(default_factory=lambda: deque(maxlen=StreamingEKF.NIS_WINDOW))

    def nis_window_mean(self) -> float:
        """Mean NIS of the last updates (chi-square with 4 dof: 4 when consistent)."""
        return float(np.mean(self.nis_window)) if self.nis_window else float("nan")


def initial_covariance(config: EstimatorConfig) -> np.ndarray:
    """P0: motion states from the config, coefficients from ``initial_coefficient_std`` (the paper's P0)."""
    diag = np.concatenate([
        np.full(4, config.initial_velocity_std_m_s ** 2),
        np.full(4, config.initial_displacement_std_m ** 2),
        config.initial_coefficient_std.as_array() ** 2,
    ])
    return np.diag(diag)


class StreamingEKF:
    """The EKF as a streaming object; one :meth:`step` per probe sample.

    Times are float seconds on any fixed origin (the caller converts integer-ns
    stamps once). Inputs per sample: probe readings ``[xp1, yp1, xp2, yp2]`` (m), the
    shaft angle (rad, 0 at the keyphasor mark), speed (rad/s) and angular
    acceleration (rad/s^2) at the sample time, and the impact force ``[fx, fy]`` (N)
    that acts from this sample until the next (zero-order hold).

    >>> from rotor_estimator.core.config import load_rig_file
    >>> f = load_rig_file()
    >>> ekf = StreamingEKF(f.rig, f.estimator)
    >>> ekf.coefficients.round(1)[:2]
    array([300000., 300000.])
    """

    NIS_WINDOW = 2000
    #: Consecutive rejected samples after which the filter is declared diverged.
    MAX_CONSECUTIVE_REJECTIONS = 400

    def __init__(self, rig: RigConfig, config: EstimatorConfig, *,
                 initial_coefficients: BearingCoefficients | np.ndarray | None = None,
                 imbalance_scale: float = 1.0) -> None:
        self.rig = rig
        self.config = config
        self.model = FilterModel.build(rig, config, imbalance_scale=imbalance_scale)
        self._initial_coefficients = (config.initial_coefficients.as_array() if initial_coefficients is None
                                      else np.asarray(getattr(initial_coefficients, "as_array",
                                                              lambda: initial_coefficients)(), dtype=float))
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self, initial_coefficients: np.ndarray | None = None) -> None:
        """Restart from the prior (r0, P0); the next sample initializes the motion states."""
        if initial_coefficients is not None:
            self._initial_coefficients = np.asarray(initial_coefficients, dtype=float).copy()
        self.x = np.zeros(N_STATE)
        self.x[COEFF_SLICE] = self._initial_coefficients
        self.P = initial_covariance(self.config)
        self.t_s: float | None = None
        self._prev_shaft = np.zeros(3)
        self._prev_impact = np.zeros(2)
        self._healthy = (self.x.copy(), self.P.copy(), None)
        self.health = FilterHealth()
        self._step_buffers = {
            "dt": np.zeros(1), "angle": np.zeros(1), "speed": np.zeros(1), "accel": np.zeros(1),
            "impact": np.zeros((1, 2)), "y": np.zeros((1, 4)), "skip": np.zeros(1, dtype=np.bool_),
            "status": np.zeros(1, dtype=np.int64), "nis": np.zeros(1), "innov": np.zeros((1, 4)),
            "sstd": np.zeros((1, 4)),
        }

    def restart_motion(self) -> bool:
        """After a gap too long to predict across: forget the motion states (their P0 again, no
        correlation with the coefficients) and re-initialize them from the next sample.

        The coefficients and their covariance are kept. Returns False when not yet initialized.
        """
        if not self.initialized:
            return False
        p0 = initial_covariance(self.config)
        self.P[:8, :] = 0.0
        self.P[:, :8] = 0.0
        self.P[:8, :8] = p0[:8, :8]
        self.t_s = None
        return True

    @property
    def initialized(self) -> bool:
        return self.t_s is not None

    @property
    def coefficients(self) -> np.ndarray:
        """Current estimate ``[kxx kxy kyx kyy cxx cxy cyx cyy]`` (SI)."""
        return self.x[COEFF_SLICE].copy()

    @property
    def coefficient_covariance(self) -> np.ndarray:
        """8x8 covariance of the coefficient estimate (SI units squared)."""
        return self.P[COEFF_SLICE, COEFF_SLICE].copy()

    @property
    def coefficient_std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.P)[COEFF_SLICE])

    def coefficient_dict(self) -> dict[str, dict[str, float]]:
        return {n: {"mean": float(m), "std": float(s)}
                for n, m, s in zip(COEFFICIENT_NAMES, self.coefficients, self.coefficient_std)}

    # ------------------------------------------------------------------ steps
    def _initialize_from(self, t_s: float, probes_m: np.ndarray, shaft: np.ndarray, impact_n: np.ndarray) -> None:
        self.x[4:8] = self.model.mats.bearing_from_probe @ probes_m
        self.x[:4] = 0.0
        self.t_s = float(t_s)
        self._prev_shaft = np.asarray(shaft, dtype=float).copy()
        self._prev_impact = np.asarray(impact_n, dtype=float).copy()
        self._healthy = (self.x.copy(), self.P.copy(), self.t_s)

    def process_block(self, t_s: np.ndarray, probes_m: np.ndarray, angle_rad: np.ndarray, speed_rad_s: np.ndarray,
                      accel_rad_s2: np.ndarray, impact_n: np.ndarray, skip: np.ndarray | None = None) -> BlockResult:
        """Run Eqs. 12-17 over a block of samples in time order (strictly increasing ``t_s``)."""
        t_s = np.ascontiguousarray(t_s, dtype=float)
        n = t_s.shape[0]
        probes_m = np.ascontiguousarray(probes_m, dtype=float).reshape(n, 4)
        shaft = np.column_stack([np.asarray(angle_rad, float), np.asarray(speed_rad_s, float),
                                 np.asarray(accel_rad_s2, float)]).reshape(n, 3)
        impact_n = np.ascontiguousarray(impact_n, dtype=float).reshape(n, 2)
        skip = np.zeros(n, dtype=np.bool_) if skip is None else np.ascontiguousarray(skip, dtype=np.bool_)
        status = np.full(n, kern.STATUS_SKIPPED, dtype=np.int64)
        nis = np.full(n, np.nan)
        innov = np.full((n, 4), np.nan)
        sstd = np.full((n, 4), np.nan)
        start = 0
        if n and not self.initialized:
            first = 0
            while first < n and (skip[first] or not np.all(np.isfinite(probes_m[first]))):
                status[first] = kern.STATUS_SKIPPED if skip[first] else kern.STATUS_NON_FINITE
                first += 1
            if first == n:
                self._count(status)
                return BlockResult(status, nis, innov, sstd)
            self._initialize_from(t_s[first], probes_m[first], shaft[first], impact_n[first])
            status[first] = kern.STATUS_INITIALIZED
            start = first + 1
        while start < n:
            seg = slice(start, n)
            prev_t = np.concatenate([[self.t_s], t_s[start:n - 1]])
            prev_shaft = np.vstack([self._prev_shaft[None, :], shaft[start:n - 1]])
            prev_imp = np.vstack([self._prev_impact[None, :], impact_n[start:n - 1]])
            dt = t_s[seg] - prev_t
            if np.any(dt <= 0):
                bad = start + int(np.argmax(dt <= 0))
                raise ValueError(f"process_block: times must increase strictly (sample {bad}: "
                                 f"{t_s[bad]!r} after {prev_t[bad - start]!r})")
            stop = kern.run_block(
                self.x, self.P, np.ascontiguousarray(dt), np.ascontiguousarray(prev_shaft[:, 0]),
                np.ascontiguousarray(prev_shaft[:, 1]), np.ascontiguousarray(prev_shaft[:, 2]),
                np.ascontiguousarray(prev_imp), probes_m[seg], skip[seg], self.model.minv, self.model.gyro,
                self.model.moments, self.model.phases, self.model.wimb, self.model.wimp, self.model.hp,
                self.model.r_var, self.model.accel_psd, self.model.coeff_rw_var_rate, self.model.gate,
                self.model.max_step_s, status[seg], nis[seg], innov[seg], sstd[seg])
            done = stop - 0  # samples of seg processed (stop == len when healthy)
            seg_len = n - start
            if done >= seg_len:
                self.t_s = float(t_s[n - 1])
                self._prev_shaft = shaft[n - 1].copy()
                self._prev_impact = impact_n[n - 1].copy()
                break
            # the state went non-finite at sample start + done: recover and continue after it
            bad = start + done
            status[bad] = kern.STATUS_NUMERICAL
            self._recover(t_s[bad], probes_m[bad], shaft[bad], impact_n[bad])
            start = bad + 1
        self._count(status)
        self._monitor(status, nis, t_s, probes_m, shaft, impact_n)
        return BlockResult(status, nis, innov, sstd)

    def step(self, t_s: float, probes_m: np.ndarray, angle_rad: float, speed_rad_s: float,
             accel_rad_s2: float = 0.0, impact_n: np.ndarray | None = None) -> BlockResult:
        """One sample: predict to ``t_s`` (Eqs. 12-13), update with ``probes_m`` (Eqs. 15-17).

        Same kernel and arithmetic as :meth:`process_block` with a block of one, through
        preallocated buffers (the per-message path of a live node).
        """
        imp = np.zeros(2) if impact_n is None else np.asarray(impact_n, dtype=float).reshape(2)
        y = np.asarray(probes_m, dtype=float).reshape(4)
        if not self.initialized or not t_s > self.t_s:
            return self.process_block(np.array([t_s], dtype=float), y.reshape(1, 4), np.array([angle_rad]),
                                      np.array([speed_rad_s]), np.array([accel_rad_s2]), imp.reshape(1, 2))
        b = self._step_buffers
        b["dt"][0] = t_s - self.t_s
        b["angle"][0], b["speed"][0], b["accel"][0] = self._prev_shaft
        b["impact"][0] = self._prev_impact
        b["y"][0] = y
        m = self.model
        stop = kern.run_block(self.x, self.P, b["dt"], b["angle"], b["speed"], b["accel"], b["impact"], b["y"],
                              b["skip"], m.minv, m.gyro, m.moments, m.phases, m.wimb, m.wimp, m.hp, m.r_var,
                              m.accel_psd, m.coeff_rw_var_rate, m.gate, m.max_step_s, b["status"], b["nis"],
                              b["innov"], b["sstd"])
        shaft = np.array([angle_rad, speed_rad_s, accel_rad_s2], dtype=float)
        result = BlockResult(b["status"].copy(), b["nis"].copy(), b["innov"].copy(), b["sstd"].copy())
        if stop < 1:
            result.status[0] = kern.STATUS_NUMERICAL
            self._count(result.status)
            self._recover(t_s, y, shaft, imp)
            return result
        self.t_s = float(t_s)
        self._prev_shaft = shaft
        self._prev_impact = imp
        self._count(result.status)
        self._monitor(result.status, result.nis, np.array([t_s]), y.reshape(1, 4), shaft.reshape(1, 3),
                      imp.reshape(1, 2))
        return result

    # ------------------------------------------------------------------ health
    def _count(self, status: np.ndarray) -> None:
        if status.shape[0] == 1:
            self.health.counts[kern.STATUS_NAMES[int(status[0])]] += 1
            return
        codes, counts = np.unique(status, return_counts=True)
        for c, k in zip(codes, counts):
            self.health.counts[kern.STATUS_NAMES[int(c)]] += int(k)

    def _recover(self, t_s: float, probes_m: np.ndarray, shaft: np.ndarray, impact_n: np.ndarray) -> None:
        """Back to the last healthy coefficients and covariance; motion states from the next good sample."""
        x_ok, p_ok, _ = self._healthy
        self.health.divergence_recoveries += 1
        self.x = x_ok.copy()
        self.P = p_ok.copy()
        self.t_s = None
        self.health.consecutive_rejections = 0
        if np.all(np.isfinite(probes_m)):
            self._initialize_from(t_s, probes_m, shaft, impact_n)

    def _monitor(self, status: np.ndarray, nis: np.ndarray, t_s, probes_m, shaft, impact_n) -> None:
        """Track consecutive rejections and a windowed NIS; snapshot the state while healthy.

        The kernel has already checked that ``x`` and ``diag(P)`` are finite and positive.
        """
        if status.shape[0] == 1:  # the per-sample path, without array temporaries
            code = int(status[0])
            if code == kern.STATUS_UPDATED:
                self.health.consecutive_rejections = 0
                self.health.nis_window.append(float(nis[0]))
                self._healthy = (self.x.copy(), self.P.copy(), self.t_s)
            elif code in (kern.STATUS_GATED, kern.STATUS_NUMERICAL):
                self.health.consecutive_rejections += 1
                if self.health.consecutive_rejections > self.MAX_CONSECUTIVE_REJECTIONS:
                    self._recover(t_s[0], probes_m[0], shaft[0], impact_n[0])
            return
        updated = status == kern.STATUS_UPDATED
        rejected = (status == kern.STATUS_GATED) | (status == kern.STATUS_NUMERICAL)
        if updated.any():
            last_update = int(np.flatnonzero(updated)[-1])
            self.health.consecutive_rejections = int(rejected[last_update + 1:].sum())
        else:
            self.health.consecutive_rejections += int(rejected.sum())
        good_nis = nis[updated]
        if good_nis.size:
            self.health.nis_window.extend(good_nis[-self.NIS_WINDOW:].tolist())
        if self.health.consecutive_rejections > self.MAX_CONSECUTIVE_REJECTIONS:
            # sustained rejection means the filter, not the data, is wrong: recover
            last = len(status) - 1
            self._recover(t_s[last], probes_m[last], shaft[last], impact_n[last])
            return
        if updated.any() and np.all(np.isfinite(self.x)) and np.all(np.diag(self.P) > 0):
            self._healthy = (self.x.copy(), self.P.copy(), self.t_s)
