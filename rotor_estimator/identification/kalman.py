# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Recursive estimators on the augmented state ``[v, z (8), theta, b?]``: EKF, UKF, EKF + RTS smoother.

* **EKF** -- Miller & Howard Eqs. 7-17 on the generalized model, with the ``predict`` and
  ``update`` building blocks of :mod:`rotor_estimator.core.filter_kernel` (driven by
  :func:`.passes.ekf_pass`): RK4 state prediction with its exact Jacobian, linear Joseph-form
  update, the coefficients (and, when unknown, the imbalance moments) as constant states. With
  identical bearings, known imbalance and constant coefficients it is the filter of
  :class:`rotor_estimator.core.ekf.StreamingEKF`, whose seed-model prediction equals the
  generalized one to rounding (checked by a test). ``passes`` repeats
  the pass from the previous pass's estimate with the prior covariance (the paper's
  multi-pass use).
* **UKF** -- the same model with the prediction done by propagating filterpy's
  ``MerweScaledSigmaPoints`` (Van der Merwe's scaled unscented transform, Neisi et al.
  2022 Eqs. 13-22 with the errata of the seeds README) through the RK4 step; the
  measurement is linear so the update is the exact linear one.
* **EKF + RTS** -- an EKF pass, then the Rauch-Tung-Striebel backward pass; repeated
  with the forward pass linearized about the previous smoothed trajectory (the
  iterated extended Kalman smoother: each iteration is a Gauss-Newton step on the
  whole-record MAP, so it converges to the batch estimate with the prior). For
  constant coefficients a single smoother pass returns the EKF's final coefficients
  (the smoothed estimate of a constant equals the filtered one at the end); the
  smoother's value is the relinearization and, with random-walk coefficients,
  two-sided (non-lagging) coefficient-versus-time/speed tracks.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from rotor_estimator.core.config import EstimatorConfig
from rotor_estimator.core.errors import ConfigError, FilterDivergedError
from rotor_estimator.identification import passes
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays
from rotor_estimator.identification.result import IdentificationResult


@dataclass(frozen=True)
class KalmanOptions:
    """Prior and tuning of the recursive estimators (SI).

    * ``theta0`` / ``theta_std``: prior mean and std of theta (default: the rig file's r0 and
      sqrt(diag P0) for the order-0 block; higher speed orders get the same std).
    * ``imbalance_std_kg_m``: prior std of each imbalance moment component when estimated
      (prior mean: 0).
    * ``theta_random_walk``: random-walk std rate of theta (SI/sqrt(s)); 0 = constant.
    * ``passes``: forward passes (EKF/UKF), or smoother iterations (EKF + RTS).
    * ``smoother_accel_psd``: white-acceleration PSD ((m/s^2)^2/Hz) used by EKF + RTS when
      ``accel_psd`` is 0. With no process noise on the motion the RTS gain is the inverse
      transition matrix, i.e. the damped dynamics run backwards and round-off grows like
      ``exp(zeta*omega*t)`` (NaN within ~0.05 s on the seed rig); (1e-4 m/s^2)^2/Hz
      stabilizes it and changes the coefficient estimates far below their CRLB.
    * ``ukf_alpha``, ``ukf_beta``, ``ukf_kappa``: scaled sigma point parameters.
    """

    theta0: np.ndarray
    theta_std: np.ndarray
    initial_displacement_std_m: float = 1e-5
    initial_velocity_std_m_s: float = 0.02
    noise_std_m: float = 1e-6
    accel_psd: float = 0.0
    imbalance_std_kg_m: float = 1e-4
    theta_random_walk: np.ndarray | None = None
    passes: int = 2
    smoother_accel_psd: float = 1e-8
    gate_nis: float = 1e6
    ukf_alpha: float = 0.5
    ukf_beta: float = 2.0
    ukf_kappa: float = 0.0

    @classmethod
    def from_config(cls, config: EstimatorConfig, model: CoefficientModel, **kw) -> "KalmanOptions":
        theta0 = model.theta_from_coefficients(config.initial_coefficients.as_array())
        std0 = config.initial_coefficient_std.as_array()
        if not model.identical_bearings:
            std0 = np.concatenate([std0, std0])
        theta_std = np.tile(std0, model.speed_order + 1)
        kw.setdefault("initial_displacement_std_m", config.initial_displacement_std_m)
        kw.setdefault("initial_velocity_std_m_s", config.initial_velocity_std_m_s)
        kw.setdefault("noise_std_m", config.measurement_noise_std_m)
        kw.setdefault("accel_psd", config.motion_process_noise_accel_m_s2 ** 2)
        kw.setdefault("passes", config.passes)
        return cls(theta0=theta0, theta_std=theta_std, **kw)

    def __post_init__(self) -> None:
        if np.any(~(np.asarray(self.theta_std) > 0)):
            raise ConfigError("kalman.theta_std: every prior std must be > 0")
        if not (isinstance(self.passes, int) and 1 <= self.passes <= 20):
            raise ConfigError("kalman.passes: an integer from 1 to 20")


class _Setup:
    def __init__(self, arrays: RigArrays, model: CoefficientModel, record: Record, opts: KalmanOptions,
                 estimate_b: bool, imbalance_kg_m: np.ndarray | None):
        self.arrays, self.model, self.record, self.opts = arrays, model, record, opts
        self.nth = model.n_theta
        self.nbs = arrays.n_imbalance if estimate_b else 0
        self.m = 8 + self.nth + self.nbs
        self.bfixed = (arrays.imbalance_nominal_kg_m if imbalance_kg_m is None
                       else np.asarray(imbalance_kg_m, dtype=float)).copy()
        rw = np.zeros(self.nth) if opts.theta_random_walk is None else np.asarray(opts.theta_random_walk) ** 2
        self.rw_rate = np.concatenate([rw, np.zeros(self.nbs)])
        self.r_var = np.full(4, opts.noise_std_m ** 2)
        self.common = (record.dt_s, record.angle_rad, record.speed_rad_s, record.accel_rad_s2, record.force_gen_n)
        self.model_args = (model.dmap(), model.powers(), model.speed_ref_rad_s, model.speed_scale_rad_s,
                           arrays.minv, arrays.gyro, arrays.wimb)

    def prior(self, theta: np.ndarray, b: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Prior at sample 0: displacements from the first reading (Eq. 6), velocity 0."""
        x = np.zeros(self.m)
        y0 = self.record.probes_m[0]
        x[4:8] = self.arrays.bearing_from_probe @ np.nan_to_num(y0)
        x[8:8 + self.nth] = theta
        if self.nbs:
            x[8 + self.nth:] = 0.0 if b is None else b
        d = np.concatenate([np.full(4, self.opts.initial_velocity_std_m_s ** 2),
                            np.full(4, self.opts.initial_displacement_std_m ** 2),
                            np.asarray(self.opts.theta_std, dtype=float) ** 2,
                            np.full(self.nbs, self.opts.imbalance_std_kg_m ** 2)])
        return x, np.diag(d)

    def ekf(self, x, P, nominal, store):
        n = len(self.record)
        xf = np.zeros((n if store else 0, self.m))
        pf = np.zeros((n if store else 0, self.m, self.m))
        nis = np.full(n, np.nan)
        stop = passes.ekf_pass(x, P, self.nth, self.nbs, self.bfixed, nominal, store, *self.common,
                                self.record.y(), self.record.use, self.arrays.hp, self.r_var, self.opts.gate_nis,
                                self.opts.accel_psd, self.rw_rate, *self.model_args, xf, pf, nis)
        if stop < n:
            raise FilterDivergedError(f"EKF: state or covariance not finite at sample {stop}")
        return xf, pf, nis

    def rts(self, nominal, xf, pf, keep_every=0):
        n = len(self.record)
        xs = np.zeros_like(xf)
        ps0 = np.zeros((self.m, self.m))
        keep = np.zeros(((n - 1) // keep_every + 1 if keep_every else 0, self.m, self.m))
        passes.rts_pass(nominal, xf, pf, self.nth, self.nbs, self.bfixed, *self.common, self.opts.accel_psd,
                         self.rw_rate, *self.model_args, xs, ps0, keep, keep_every)
        return xs, ps0, keep


def _result(method, setup: _Setup, x, P, t0, **extra) -> IdentificationResult:
    nth, nbs = setup.nth, setup.nbs
    b = x[8 + nth:8 + nth + nbs] if nbs else setup.bfixed
    return IdentificationResult(method=method, model=setup.model, theta=x[8:8 + nth].copy(),
                                covariance=P[8:8 + nth, 8:8 + nth].copy(), imbalance_kg_m=np.array(b, dtype=float),
                                imbalance_estimated=bool(nbs), runtime_s=time.perf_counter() - t0, extra=extra)


def run_ekf(arrays: RigArrays, model: CoefficientModel, record: Record, options: KalmanOptions, *,
            estimate_imbalance: bool = False, imbalance_kg_m: np.ndarray | None = None) -> IdentificationResult:
    """The EKF, ``options.passes`` passes (each from the previous estimate with the prior covariance)."""
    t0 = time.perf_counter()
    s = _Setup(arrays, model, record, options, estimate_imbalance, imbalance_kg_m)
    theta, b = np.asarray(options.theta0, dtype=float), None
    for _ in range(options.passes):
        x, P = s.prior(theta, b)
        _, _, nis = s.ekf(x, P, np.zeros((0, s.m)), False)
        theta, b = x[8:8 + s.nth].copy(), x[8 + s.nth:].copy() if s.nbs else None
    return _result("ekf", s, x, P, t0, nis_mean=float(np.nanmean(nis)))


def run_ekf_rts(arrays: RigArrays, model: CoefficientModel, record: Record, options: KalmanOptions, *,
                estimate_imbalance: bool = False, imbalance_kg_m: np.ndarray | None = None,
                keep_every: int = 0) -> IdentificationResult:
    """EKF pass + RTS smoother, iterated ``options.passes`` times about the smoothed trajectory.

    ``keep_every`` > 0 also returns the smoothed means (every sample) and covariances
    (every ``keep_every``-th sample) in ``extra`` (for random-walk coefficient tracks).
    """
    t0 = time.perf_counter()
    if options.accel_psd == 0.0:
        options = replace(options, accel_psd=options.smoother_accel_psd)
    s = _Setup(arrays, model, record, options, estimate_imbalance, imbalance_kg_m)
    x, P = s.prior(np.asarray(options.theta0, dtype=float), None)
    x_ekf_final = None
    nominal = np.zeros((0, s.m))
    for it in range(options.passes):
        xp, pp = x.copy(), P.copy()
        xf, pf, nis = s.ekf(xp, pp, nominal, True)
        if it == 0:
            x_ekf_final = xp.copy()
            nominal_used = xf
        else:
            nominal_used = nominal
        xs, ps0, keep = s.rts(nominal_used, xf, pf, keep_every if it == options.passes - 1 else 0)
        nominal = xs
        del xf, pf
    extra = {"ekf_theta": x_ekf_final[8:8 + s.nth].copy(), "nis_mean": float(np.nanmean(nis))}
    if keep_every:
        extra.update(smoothed_states=xs, smoothed_cov_every=keep, keep_every=keep_every)
    return _result("ekf+rts", s, xs[0], ps0, t0, **extra)


def ukf_weights(m: int, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Weights of filterpy's ``MerweScaledSigmaPoints`` (the reference implementation)."""
    from filterpy.kalman import MerweScaledSigmaPoints

    pts = MerweScaledSigmaPoints(m, alpha=alpha, beta=beta, kappa=kappa)
    lam = alpha ** 2 * (m + kappa) - m
    return np.ascontiguousarray(pts.Wm), np.ascontiguousarray(pts.Wc), float(lam)


def run_ukf(arrays: RigArrays, model: CoefficientModel, record: Record, options: KalmanOptions, *,
            estimate_imbalance: bool = False, imbalance_kg_m: np.ndarray | None = None) -> IdentificationResult:
    """The UKF, ``options.passes`` passes like :func:`run_ekf`."""
    t0 = time.perf_counter()
    s = _Setup(arrays, model, record, options, estimate_imbalance, imbalance_kg_m)
    wm, wc, lam = ukf_weights(s.m, options.ukf_alpha, options.ukf_beta, options.ukf_kappa)
    theta, b = np.asarray(options.theta0, dtype=float), None
    n = len(record)
    for _ in range(options.passes):
        x, P = s.prior(theta, b)
        nis = np.full(n, np.nan)
        stop = passes.ukf_pass(x, P, s.nth, s.nbs, s.bfixed, wm, wc, lam, *s.common, record.y(), record.use,
                                arrays.hp, s.r_var, options.gate_nis, options.accel_psd, s.rw_rate, *s.model_args, nis)
        if stop < n:
            raise FilterDivergedError(f"UKF: state or covariance not finite at sample {stop}")
        theta, b = x[8:8 + s.nth].copy(), x[8 + s.nth:].copy() if s.nbs else None
    return _result("ukf", s, x, P, t0, nis_mean=float(np.nanmean(nis)))
