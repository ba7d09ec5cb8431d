# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The nominal fit and the shared fitting context of every candidate effect.

Nominal fit, in two stages:

1. the streaming EKF (Miller & Howard, Eqs. 7-17, ``passes`` passes) gives bearing
   coefficients and the innovation sequence (checked for whiteness and NIS);
2. an output-error least-squares refinement re-simulates Eq. 2 (exact discretization,
   :mod:`.linsim`) with the measured shaft angle and impact force, and minimizes the
   probe output error over the 8 coefficients and a DC offset per probe (gap voltage).

Every candidate effect is then fitted by variable projection on the output error
``e = y - y_nom``: its own columns/offset plus the nominal's linearized coefficient
sensitivity ``J = dy_nom/dr`` and the DC columns, so the bearing coefficients are
re-estimated jointly with the effect (one Gauss-Newton step about the nominal fit).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.optimize import least_squares

from rotor_estimator.core.config import EstimatorConfig, RigConfig
from rotor_estimator.core.errors import InputError
from rotor_estimator.core.linear_filters import single_threaded_blas
from rotor_estimator.core.model import RotorMatrices, imbalance_force, impact_force, rotor_matrices
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.linsim import SpeedSchedule, simulate_linear

#: Scale of the 8 coefficients in the output-error fit (N/m and N*s/m).
COEFFICIENT_SCALE = np.array([1e5] * 4 + [1e3] * 4)
#: Leading time excluded from every fit (start-up transient of the re-simulation), s.
WARMUP_S = 0.010
#: Fraction of the fit span used for fitting in the held-out check (the rest is predicted).
HELD_OUT_SPLIT = 0.6


@dataclass
class ShaftTrack:
    """Shaft angle (rad), speed (rad/s), acceleration (rad/s^2) per sample and their validity."""

    angle_rad: np.ndarray
    speed_rad_s: np.ndarray
    accel_rad_s2: np.ndarray
    valid: np.ndarray


def shaft_track(recording: RigRecording) -> ShaftTrack:
    """Shaft states from the keyphasor pulses (the offline tachometer fit of the core)."""
    from rotor_estimator.core.offline import shaft_inputs_from_recording

    s = shaft_inputs_from_recording(recording)
    return ShaftTrack(s.angle_rad, s.speed_rad_s, s.accel_rad_s2, s.valid)


def noise_std_from_spectrum(residual_m: np.ndarray, sample_rate_hz: float, low_hz: float) -> np.ndarray:
    """Per-channel white-noise std from the mean periodogram above ``low_hz`` (E|X_k|^2/N = sigma^2)."""
    e = residual_m - residual_m.mean(axis=0)
    n = e.shape[0]
    spec = np.abs(np.fft.rfft(e, axis=0)) ** 2 / n
    f = np.fft.rfftfreq(n, 1.0 / sample_rate_hz)
    band = (f >= low_hz) & (f < 0.49 * sample_rate_hz)
    if band.sum() < 16:
        band = f >= 0.25 * sample_rate_hz
    return np.sqrt(np.median(spec[band], axis=0) / np.log(2.0))  # median of chi2_2/2 is ln 2


@dataclass
class FitContext:
    """Everything a candidate effect needs: data, shaft track, nominal fit and its sensitivities."""

    rig: RigConfig
    mats: RotorMatrices
    t_s: np.ndarray
    y_m: np.ndarray                      # (N, 4) measured probes
    shaft: ShaftTrack
    impact_force_n: np.ndarray           # (N, 2)
    mask: np.ndarray                     # (N,) samples used in fits
    fit_rows: np.ndarray                 # (N,) first part (held-out check)
    test_rows: np.ndarray                # (N,) later part (held-out check)
    schedule: SpeedSchedule
    coefficients: np.ndarray             # (8,) nominal output-error estimate
    coefficients_ekf: np.ndarray         # (8,) EKF estimate
    y_nom_m: np.ndarray                  # (N, 4) nominal model output (no DC)
    v_nom_m_s: np.ndarray                # (N, 4) nominal probe velocities
    z_nom_m: np.ndarray                  # (N, 4) nominal bearing displacements
    jacobian: np.ndarray                 # (N, 4, 8) d y_nom / d (r / COEFFICIENT_SCALE)
    noise_std_m: np.ndarray              # (4,) estimated noise per channel
    ekf_innovation_m: np.ndarray         # (N, 4)
    ekf_innovation_std_m: np.ndarray     # (N, 4)
    ekf_nis: np.ndarray                  # (N,)
    known_smooth_n: np.ndarray           # (N, 4) generalized imbalance force (known test masses)
    known_step_n: np.ndarray             # (N, 4) generalized impact force
    prior_coefficients: np.ndarray       # (8,) r0 of the estimator configuration
    _cache: dict = field(default_factory=dict)
    #: The model forces are sent through by :meth:`response`: ``(build_a(speed) -> A, B, C)`` with the rigid
    #: model's generalized-force input (N, 4) and output rows (probe displacements, then velocities);
    #: ``None`` is the rigid nominal of Eq. 2. A structural effect (pedestal) sets it for its pair partner.
    response_model: tuple | None = None

    @cached_property
    def sample_rate_hz(self) -> float:
        return 1.0 / float(np.median(np.diff(self.t_s)))

    @property
    def mean_speed_rad_s(self) -> float:
        return float(np.mean(self.shaft.speed_rad_s[self.mask]))

    @property
    def residual_m(self) -> np.ndarray:
        """Nominal output error with the fitted DC removed, (N, 4)."""
        return self.y_m - self.y_nom_m - self.dc_offset_m

    @property
    def dc_offset_m(self) -> np.ndarray:
        return (self.y_m - self.y_nom_m)[self.mask].mean(axis=0)

    def response(self, u_smooth: np.ndarray, u_step: np.ndarray | None = None) -> np.ndarray:
        """Probe output (N, 4) of the nominal rigid model (or :attr:`response_model`) driven by generalized
        forces (N, 4)."""
        r = self.coefficients
        if self.response_model is None:
            mats = self.mats
            build_a, b, c = (lambda w: models.rigid_state_matrix(mats, r, w)), models.rigid_input(mats), \
                models.rigid_output(mats)
        else:
            build_a, b, c = self.response_model
        out, _ = simulate_linear(build_a, b, c, self.period_s, self.schedule, self.shaft.angle_rad, u_smooth, u_step,
                                 cache=self._cache.setdefault(("response", tuple(np.round(r, 9))), {}))
        return out[:, :4]

    @property
    def period_s(self) -> float:
        return 1.0 / self.sample_rate_hz


def simulate_nominal(rig, mats, r, t_s, shaft, schedule, u_smooth, u_step, h_s):
    out, states = simulate_linear(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats),
                                  models.rigid_output(mats), h_s, schedule, shaft.angle_rad, u_smooth, u_step)
    return out[:, :4], out[:, 4:], states[:, 4:8]


def _nominal_products(rig, mats, r_hat, t, shaft, schedule, u_s, u_z, h):
    """Nominal output, probe velocity, bearing displacement and coefficient sensitivity at ``r_hat``."""
    y_nom, v_nom, z_nom = simulate_nominal(rig, mats, r_hat, t, shaft, schedule, u_s, u_z, h)
    jac = np.zeros((len(t), 4, 8))
    p_hat = r_hat / COEFFICIENT_SCALE
    for i in range(8):
        step = np.zeros(8)
        step[i] = 1e-3 * max(abs(p_hat[i]), 1.0)
        yp, _, _ = simulate_nominal(rig, mats, r_hat + step * COEFFICIENT_SCALE, t, shaft, schedule, u_s, u_z, h)
        jac[:, :, i] = (yp - y_nom) / step[i]
    return y_nom, v_nom, z_nom, jac


def recentered(ctx: "FitContext", coefficients: np.ndarray) -> "FitContext":
    """The same context linearized about other coefficients (one outer Gauss-Newton step)."""
    from dataclasses import replace

    y_nom, v_nom, z_nom, jac = _nominal_products(ctx.rig, ctx.mats, np.asarray(coefficients, float), ctx.t_s,
                                                 ctx.shaft, ctx.schedule, ctx.known_smooth_n, ctx.known_step_n,
                                                 ctx.period_s)
    return replace(ctx, coefficients=np.asarray(coefficients, float), y_nom_m=y_nom, v_nom_m_s=v_nom,
                   z_nom_m=z_nom, jacobian=jac, _cache={})


def with_coefficients(ctx: "FitContext", coefficients: np.ndarray) -> "FitContext":
    """The context's nominal output at other coefficients, without the sensitivities (cheap)."""
    from dataclasses import replace

    r = np.asarray(coefficients, float)
    y_nom, v_nom, z_nom = simulate_nominal(ctx.rig, ctx.mats, r, ctx.t_s, ctx.shaft, ctx.schedule,
                                            ctx.known_smooth_n, ctx.known_step_n, ctx.period_s)
    return replace(ctx, coefficients=r, y_nom_m=y_nom, v_nom_m_s=v_nom, z_nom_m=z_nom, _cache={})


def fit_nominal(rig: RigConfig, mats, t_s: np.ndarray, y_m: np.ndarray, rows: np.ndarray, shaft: ShaftTrack,
                schedule: SpeedSchedule, u_smooth: np.ndarray, u_step: np.ndarray, h_s: float, starts, *,
                max_nfev: int, x_scale: float | None = None):
    """The nominal output-error fit: Levenberg-Marquardt over the 8 coefficients of Eq. 2, re-simulated by
    :func:`simulate_nominal`, on the output error of ``rows`` with each channel's mean (the probe's DC gap)
    projected out, in micrometres (so that the LM tolerances mean something). Best of ``starts`` (N/m and
    N*s/m; non-finite or failing starts are skipped); ``None`` when none converges. ``max_nfev`` counts
    Jacobians (9 evaluations each). ``x_scale``: scipy's (``None``, its default, or 1.0)."""
    def residual(p):
        yn, _, _ = simulate_nominal(rig, mats, p * COEFFICIENT_SCALE, t_s, shaft, schedule, u_smooth, u_step, h_s)
        e = (y_m - yn)[rows]
        return (e - e.mean(axis=0)).ravel() * 1e6

    best = None
    for r0 in starts:
        p0 = np.asarray(r0, dtype=float) / COEFFICIENT_SCALE
        if not np.all(np.isfinite(p0)):
            continue
        try:
            res = least_squares(residual, p0, method="lm", x_scale=x_scale, diff_step=1e-4, max_nfev=max_nfev * 9)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if best is None or res.cost < best.cost:
            best = res
    return best


@single_threaded_blas()  # small matrices: threaded BLAS only oversubscribes (2.3x slower measured)
def build_context(recording: RigRecording, rig: RigConfig, config: EstimatorConfig, *, passes: int = 2,
                  shaft: ShaftTrack | None = None, max_nfev: int = 30) -> FitContext:
    """EKF, then output-error refinement of the 8 coefficients; returns the fitting context."""
    from rotor_estimator.core.offline import ShaftInputs, estimate

    if len(recording) < 400:
        raise InputError(f"diagnosis needs at least 400 probe samples, got {len(recording)}")
    bad_force = int(np.sum(~np.all(np.isfinite(recording.impact_force_n), axis=1)))
    if bad_force:
        raise InputError(f"impact_force_n has {bad_force} non-finite sample(s): the hammer force must be finite "
                         "(zeros where there is no impact)")
    shaft = shaft or shaft_track(recording)
    mats = rotor_matrices(rig)
    t = recording.time_s()
    h = float(np.median(np.diff(t)))
    y = recording.probes_m
    finite = np.all(np.isfinite(y), axis=1)
    mask = shaft.valid & finite & (t >= t[0] + WARMUP_S)
    if mask.sum() < 200:
        raise InputError("fewer than 200 usable samples after the warm-up and the tachometer's valid span")
    y_clean = np.where(finite[:, None], y, 0.0)
    t_fit = t[mask]
    t_cut = t_fit[0] + HELD_OUT_SPLIT * (t_fit[-1] - t_fit[0])
    schedule = SpeedSchedule.from_speed(shaft.speed_rad_s)
    u_s = imbalance_force(mats, shaft.angle_rad, shaft.speed_rad_s, shaft.accel_rad_s2)
    u_z = impact_force(mats, recording.impact_force_n)

    # 1. EKF (Eqs. 7-17)
    est = estimate(recording, rig, config, passes=passes,
                   shaft=ShaftInputs(shaft.angle_rad, shaft.speed_rad_s, shaft.accel_rad_s2, shaft.valid))
    r_ekf = est.coefficients.copy()
    lp = est.last_pass

    # 2. output-error refinement (DC projected out)
    best = fit_nominal(rig, mats, t, y_clean, mask, shaft, schedule, u_s, u_z, h,
                       [r_ekf, config.initial_coefficients.as_array()], max_nfev=max_nfev, x_scale=1.0)
    if best is None:
        raise InputError("the nominal output-error fit failed from both the EKF estimate and r0")
    r_hat = best.x * COEFFICIENT_SCALE
    y_nom, v_nom, z_nom, jac = _nominal_products(rig, mats, r_hat, t, shaft, schedule, u_s, u_z, h)
    e0 = y_clean - y_nom
    low = max(0.3 * (1 / h), 10 * float(np.mean(shaft.speed_rad_s)) / (2 * np.pi))
    sigma = noise_std_from_spectrum(e0[mask], 1 / h, low)
    return FitContext(
        rig=rig, mats=mats, t_s=t, y_m=y_clean, shaft=shaft, impact_force_n=recording.impact_force_n, mask=mask,
        fit_rows=mask & (t < t_cut), test_rows=mask & (t >= t_cut), schedule=schedule, coefficients=r_hat,
        coefficients_ekf=r_ekf, y_nom_m=y_nom, v_nom_m_s=v_nom, z_nom_m=z_nom, jacobian=jac, noise_std_m=sigma,
        ekf_innovation_m=lp.innovation_m, ekf_innovation_std_m=lp.innovation_std_m, ekf_nis=lp.nis,
        known_smooth_n=u_s, known_step_n=u_z, prior_coefficients=config.initial_coefficients.as_array())
