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

A record that does not start in the periodic steady state the re-simulation starts in (a run from
rest, a record cut after a speed change) carries the free decay of the rotor's modes from an unknown
initial state. When the record before its first impact shows it (:func:`start_transient_shows` at the
nominal fit, or :func:`start_transient_shows_refitted`, which fits the nominal model with and without it),
every fit (the nominal's included) estimates that state: the free response of the rigid model from
each of its 8 states enters as 8 more linear columns (:func:`.linsim.free_response`; output-error
identification with an estimated initial state), instead of an unmodelled decay that the candidate
effects compete to absorb. Otherwise the record is taken to start steady: an impact right after the
start is a free response too, and an estimated initial state would absorb its scale.

Every fit is a MAP fit under the rig file's coefficient prior (r0, sqrt(diag P0)) of the estimator
configuration, the EKF's own initial belief (Eq. 16 of Miller & Howard), entered as 8 pseudo-observations
(:class:`CoefficientPrior`). A record without an impact at one speed shows the coefficients only through
its 1X response, which they can fit to any 1X misfit by moving 10-30x off (a 20x-stiff fit absorbing an
unbalance was seen): the prior is what keeps them physical there; with an impact it is negligible.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from scipy.optimize import least_squares

from rotor_estimator.core.config import EstimatorConfig, RigConfig
from rotor_estimator.core.errors import InputError
from rotor_estimator.core.linear_filters import single_threaded_blas
from rotor_estimator.core.model import RotorMatrices, imbalance_force, impact_force, rotor_matrices
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.linsim import SpeedSchedule, free_response, simulate_linear, simulate_linear_many

#: Scale of the 8 coefficients in the output-error fit (N/m and N*s/m).
COEFFICIENT_SCALE = np.array([1e5] * 4 + [1e3] * 4)
#: Pseudo-observations the coefficient prior appends to every misfit (:class:`CoefficientPrior`): one per coefficient.
PRIOR_ROWS = 8
#: Leading time excluded from every fit (start-up transient of the re-simulation), s.
WARMUP_S = 0.010
#: Fraction of the fit span used for fitting in the held-out check (the rest is predicted).
HELD_OUT_SPLIT = 0.6
#: States of the rigid model whose initial deviation each fit estimates (the start transient's columns).
START_STATES = 8
#: BIC improvement of the nominal fit before the first impact for the start transient to be estimated.
START_TRANSIENT_DELTA_BIC = 30.0
#: Fewest fit samples before the first impact on which a start transient can be shown.
START_TRANSIENT_MIN_SAMPLES = 200


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


def noise_band_low_hz(rate_hz: float, mean_speed_rad_s: float) -> float:
    """Where the noise floor is read from (up to 0.49 of the rate): 0.3 of the rate or 10x the mean speed, the
    higher, above any rotor response."""
    return max(0.3 * rate_hz, 10 * mean_speed_rad_s / (2 * np.pi))


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


@dataclass(frozen=True)
class CoefficientPrior:
    """Gaussian prior on the 8 bearing coefficients (SI): ``mean`` r0 and ``std`` sqrt(diag P0) of the
    estimator configuration. It enters a least-squares fit of the probe output as 8 pseudo-observations
    ``noise_std_m (r - mean) / std``: the MAP estimate of a Gaussian output error of std ``noise_std_m``."""

    mean: np.ndarray
    std: np.ndarray
    noise_std_m: float

    def residual_m(self, coefficients: np.ndarray) -> np.ndarray:
        """The 8 pseudo-observation residuals (m) at ``coefficients`` (SI)."""
        return self.noise_std_m * (np.asarray(coefficients, float) - self.mean) / self.std

    def penalty_m2(self, coefficients: np.ndarray) -> float:
        """Their sum of squares (m^2): what the prior adds to a fit's residual sum of squares."""
        return float(np.sum(self.residual_m(coefficients) ** 2))

    def design_rows(self) -> np.ndarray:
        """d residual / d (r / COEFFICIENT_SCALE): the diagonal (8, 8) block of the pseudo-observations."""
        return np.diag(self.noise_std_m * COEFFICIENT_SCALE / self.std)


def coefficient_prior(config: EstimatorConfig, noise_std_m: float) -> CoefficientPrior:
    """The prior of the estimator configuration (r0, sqrt(diag P0)) at the record's noise level."""
    return CoefficientPrior(mean=config.initial_coefficients.as_array(),
                            std=config.initial_coefficient_std.as_array(), noise_std_m=float(noise_std_m))


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
    start_columns_m: np.ndarray          # (N, 4, START_STATES or 0) free response from each unit initial state
    noise_std_m: np.ndarray              # (4,) estimated noise per channel
    ekf_innovation_m: np.ndarray         # (N, 4)
    ekf_innovation_std_m: np.ndarray     # (N, 4)
    ekf_nis: np.ndarray                  # (N,)
    known_smooth_n: np.ndarray           # (N, 4) generalized imbalance force (known test masses)
    known_step_n: np.ndarray             # (N, 4) generalized impact force
    prior: CoefficientPrior              # r0 and sqrt(diag P0) of the estimator configuration
    _cache: dict = field(default_factory=dict)
    #: The model forces are sent through by :meth:`response`: ``(build_a(speed) -> A, B, C)`` with the rigid
    #: model's generalized-force input (N, 4) and output rows (probe displacements, then velocities);
    #: ``None`` is the rigid nominal of Eq. 2. A structural effect (pedestal) sets it for its pair partner.
    response_model: tuple | None = None
    #: The start transient is estimated in an effect's own model (:attr:`.Effect.owns_start_transient`: a
    #: foundation's free response from each of its initial states, the rotor's included), so the design's start
    #: columns (:attr:`design_start_columns_m`) are the effect's, not the rigid nominal's :attr:`start_columns_m`
    #: (which still define the nominal residual). Set by :func:`start_in_effect`.
    start_in_effect: bool = False

    @property
    def prior_coefficients(self) -> np.ndarray:
        """(8,) r0 of the estimator configuration."""
        return self.prior.mean

    @cached_property
    def sample_rate_hz(self) -> float:
        return 1.0 / float(np.median(np.diff(self.t_s)))

    @property
    def start_transient(self) -> bool:
        """Whether this record's fits estimate the start transient (:func:`start_transient_shows`)."""
        return self.start_columns_m.shape[2] > 0

    @property
    def design_start_columns_m(self) -> np.ndarray:
        """The start transient's columns in a fit's design ``[J, D, S, X]``: :attr:`start_columns_m`, or none
        (N, 4, 0) when the fitted effect's own columns carry the start transient (:attr:`start_in_effect`)."""
        return self.start_columns_m[:, :, :0] if self.start_in_effect else self.start_columns_m

    @property
    def mean_speed_rad_s(self) -> float:
        return float(np.mean(self.shaft.speed_rad_s[self.mask]))

    @property
    def residual_m(self) -> np.ndarray:
        """Nominal output error with the fitted DC and start transient removed, (N, 4)."""
        return self.y_m - self.y_nom_m - self.nuisance_fit_m

    @cached_property
    def nuisance_fit_m(self) -> np.ndarray:
        """The least-squares DC gap plus start transient of the nominal output error on the fit rows, (N, 4)."""
        return nuisance_fit(self.start_columns_m, self.y_m - self.y_nom_m, self.mask)

    @cached_property
    def motion_m(self) -> np.ndarray:
        """The nominal model's probe displacements (N, 4) with its fitted start transient: the periodic response
        plus the decay from the estimated initial state (:attr:`y_nom_m` alone without one). What a probe's
        calibration map acts on."""
        return self.y_nom_m + start_transient_fit(self.start_columns_m, self.y_m - self.y_nom_m, self.mask)

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

    def responses(self, u_smooth: list[np.ndarray]) -> np.ndarray:
        """:meth:`response` to each of K smooth generalized forces (each (N, 4)), as columns (N, 4, K), in one pass
        (:func:`.linsim.simulate_linear_many`: each column equal to its own :meth:`response`)."""
        r = self.coefficients
        if self.response_model is None:
            mats = self.mats
            build_a, b, c = (lambda w: models.rigid_state_matrix(mats, r, w)), models.rigid_input(mats), \
                models.rigid_output(mats)
        else:
            build_a, b, c = self.response_model
        out = simulate_linear_many(build_a, b, c, self.period_s, self.schedule, self.shaft.angle_rad, u_smooth,
                                   cache=self._cache.setdefault(("response", tuple(np.round(r, 9))), {}))
        return out[:, :4, :]

    @property
    def period_s(self) -> float:
        return 1.0 / self.sample_rate_hz


def only_steady_1x(ctx: FitContext) -> bool:
    """True for a fit span with no impact and no start transient estimated (a record at one steady speed, whose
    coefficients only its synchronous response shows)."""
    return not ctx.start_transient and not bool(np.any(ctx.impact_force_n[ctx.mask] != 0.0))


def nuisance_columns(start_columns_m: np.ndarray) -> np.ndarray:
    """``[D, S]`` (N, 4, 4 + s): one DC column per probe (its gap), then the start transient's (s = 0 or 8)."""
    n = start_columns_m.shape[0]
    dc = np.zeros((n, 4, 4))
    for c in range(4):
        dc[:, c, c] = 1.0
    return np.concatenate([dc, start_columns_m], axis=2)


def nuisance_fit(start_columns_m: np.ndarray, error_m: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Least-squares DC gap plus start transient of ``error_m`` (N, 4) on ``rows``, evaluated on every sample."""
    if start_columns_m.shape[2] == 0:  # the DC gaps alone: each channel's mean (the same solution, no SVD)
        return np.broadcast_to(error_m[rows].mean(axis=0), error_m.shape).copy()
    cols = nuisance_columns(start_columns_m)
    a = cols[rows].reshape(-1, cols.shape[2])
    norm = np.sqrt((a * a).sum(axis=0))
    norm[norm == 0] = 1.0
    coef, *_ = np.linalg.lstsq(a / norm, error_m[rows].ravel(), rcond=1e-10)
    return np.einsum("nck,k->nc", cols, coef / norm)


def start_transient_fit(start_columns_m: np.ndarray, error_m: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The start transient's part ``S s`` (N, 4) of :func:`nuisance_fit`; zeros without start columns.

    The DC gaps are one free constant per channel, so they are projected out by centring each channel of
    ``S`` and of ``error_m`` on ``rows`` (Frisch-Waugh-Lovell), leaving the 8 x 8 normal equations of the
    unit-normed start columns (a pseudo-inverse, as :func:`.fitting.solve_linear`). A probe map's basis needs
    it at every trial point of a joint refit: ``lstsq`` on the stacked 12 columns took 21 ms there, against
    4 ms for the re-simulation itself."""
    if start_columns_m.shape[2] == 0:
        return np.zeros(error_m.shape)
    s_rows = start_columns_m[rows]
    s_rows = s_rows - s_rows.mean(axis=0)
    e_rows = error_m[rows] - error_m[rows].mean(axis=0)
    gram = np.einsum("nck,ncl->kl", s_rows, s_rows)
    norm = np.sqrt(np.diag(gram)).copy()
    norm[norm == 0] = 1.0
    rhs = np.einsum("nck,nc->k", s_rows, e_rows) / norm
    coef = np.linalg.pinv(gram / np.outer(norm, norm), rcond=1e-12, hermitian=True) @ rhs / norm
    return np.einsum("nck,k->nc", start_columns_m, coef)


def start_columns(mats, r, schedule, h_s, *, estimated: bool = True) -> np.ndarray:
    """Probe-displacement free response of the rigid model of Eq. 2 at ``r`` from each unit initial state
    (N, 4, 8); (N, 4, 0) when the start transient is not ``estimated``."""
    if not estimated:
        return np.zeros((schedule.block_of_sample.size, 4, 0))
    return free_response(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats),
                         models.rigid_output(mats)[:4], h_s, schedule)


def simulate_nominal(rig, mats, r, t_s, shaft, schedule, u_smooth, u_step, h_s):
    out, states = simulate_linear(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats),
                                  models.rigid_output(mats), h_s, schedule, shaft.angle_rad, u_smooth, u_step)
    return out[:, :4], out[:, 4:], states[:, 4:8]


#: Forward-difference step along a coefficient, relative to its scaled value (at least this much of its scale).
COEFFICIENT_DIFFERENCE_STEP = 1e-3


def coefficient_difference_steps(coefficients: np.ndarray) -> np.ndarray:
    """Forward-difference steps (8, scaled units) about ``coefficients`` (SI): the sensitivity ``J`` here and the
    effect's coupling to the coefficients (:func:`.ranking.effect_coefficient_sensitivity`) share them."""
    return COEFFICIENT_DIFFERENCE_STEP * np.maximum(np.abs(np.asarray(coefficients, float) / COEFFICIENT_SCALE), 1.0)


def start_transient_sensitivity(ctx: "FitContext", start_state: np.ndarray) -> np.ndarray:
    """(N, 4, 8) derivative of the start transient ``S(r) s`` in the 8 scaled coefficients, at the fitted initial
    deviation ``s`` held (forward differences of :func:`start_columns`, the steps of
    :func:`coefficient_difference_steps`); zeros when the context estimates no start transient.

    A fit's model output is ``y_nom(r) + D d + S(r) s + X theta``: the coefficients' column in the linearized
    design is ``J + dS/dr s``, not ``J`` alone. In a record from rest the transient starts from the whole periodic
    state, so the two terms nearly cancel while both are large: without this one, a runout fit of an independent
    record from rest without an impact reported kxx +- 2.2e3 N/m where the exact misfit's curvature gives
    +- 2.2e5 (the truth 3.8 reported std off, 1.95 noise variances up the misfit)."""
    s = np.asarray(start_state, float)
    out = np.zeros((ctx.t_s.size, 4, 8))
    columns = ctx.design_start_columns_m  # none when an effect's own columns carry the start transient
    if columns.shape[2] == 0 or s.size != columns.shape[2] or not np.any(s):
        return out
    base = np.einsum("nck,k->nc", columns, s)
    for i, step in enumerate(coefficient_difference_steps(ctx.coefficients)):
        shifted = np.asarray(ctx.coefficients, float).copy()
        shifted[i] += step * COEFFICIENT_SCALE[i]
        cols = start_columns(ctx.mats, shifted, ctx.schedule, ctx.period_s)
        out[:, :, i] = (np.einsum("nck,k->nc", cols, s) - base) / step
    return np.where(np.isfinite(out), out, 0.0)


def _nominal_products(rig, mats, r_hat, t, shaft, schedule, u_s, u_z, h):
    """Nominal output, probe velocity, bearing displacement and coefficient sensitivity at ``r_hat``."""
    y_nom, v_nom, z_nom = simulate_nominal(rig, mats, r_hat, t, shaft, schedule, u_s, u_z, h)
    jac = np.zeros((len(t), 4, 8))
    steps = coefficient_difference_steps(r_hat)
    for i in range(8):
        step = np.zeros(8)
        step[i] = steps[i]
        yp, _, _ = simulate_nominal(rig, mats, r_hat + step * COEFFICIENT_SCALE, t, shaft, schedule, u_s, u_z, h)
        jac[:, :, i] = (yp - y_nom) / step[i]
    return y_nom, v_nom, z_nom, jac


def recentered(ctx: "FitContext", coefficients: np.ndarray) -> "FitContext":
    """The same context linearized about other coefficients (one outer Gauss-Newton step)."""
    y_nom, v_nom, z_nom, jac = _nominal_products(ctx.rig, ctx.mats, np.asarray(coefficients, float), ctx.t_s,
                                                 ctx.shaft, ctx.schedule, ctx.known_smooth_n, ctx.known_step_n,
                                                 ctx.period_s)
    r = np.asarray(coefficients, float)
    return replace(ctx, coefficients=r, y_nom_m=y_nom, v_nom_m_s=v_nom, z_nom_m=z_nom, jacobian=jac,
                   start_columns_m=_start_columns_of(ctx, r), _cache={})


def _start_columns_of(ctx: "FitContext", r: np.ndarray) -> np.ndarray:
    """The rigid start columns at ``r`` for a context re-simulated there; an effect-owned start transient's context
    (:attr:`FitContext.start_in_effect`) keeps its old ones unused in its designs (no re-simulation)."""
    if ctx.start_in_effect:
        return ctx.start_columns_m
    return start_columns(ctx.mats, r, ctx.schedule, ctx.period_s, estimated=ctx.start_transient)


def start_in_effect(ctx: "FitContext", effects) -> "FitContext":
    """``ctx`` for a fit of ``effects`` (None members ignored): when one of them owns the start transient
    (:attr:`.Effect.owns_start_transient`) and the record's is estimated, a copy whose designs leave it to that
    effect's columns (:attr:`FitContext.design_start_columns_m`); otherwise ``ctx`` itself."""
    if ctx.start_in_effect or not ctx.start_transient \
            or not any(e is not None and e.owns_start_transient for e in effects):
        return ctx
    return replace(ctx, start_in_effect=True)


def with_coefficients(ctx: "FitContext", coefficients: np.ndarray) -> "FitContext":
    """The context's nominal output at other coefficients, without the sensitivities (cheap)."""
    r = np.asarray(coefficients, float)
    y_nom, v_nom, z_nom = simulate_nominal(ctx.rig, ctx.mats, r, ctx.t_s, ctx.shaft, ctx.schedule,
                                            ctx.known_smooth_n, ctx.known_step_n, ctx.period_s)
    return replace(ctx, coefficients=r, y_nom_m=y_nom, v_nom_m_s=v_nom, z_nom_m=z_nom,
                   start_columns_m=_start_columns_of(ctx, r), _cache={})


def rigid_model_is_stable(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float) -> bool:
    """True when the rigid rotor on bearings ``coefficients`` (Eq. 2) is asymptotically stable at ``speed_rad_s``
    (every eigenvalue of its state matrix in the open left half-plane)."""
    try:
        return bool(slowest_decay_rate_1_per_s(mats, coefficients, speed_rad_s) > 0.0)  # NaN: not stable
    except np.linalg.LinAlgError:
        return False


def slowest_decay_rate_1_per_s(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float) -> float:
    """``-max Re(lambda)`` (1/s) of the rigid model's state matrix (Eq. 2): how fast its slowest mode decays
    (negative when one grows; NaN when the matrix is not finite)."""
    a = models.rigid_state_matrix(mats, np.asarray(coefficients, float), speed_rad_s)
    if not np.all(np.isfinite(a)):
        return float("nan")
    return float(-np.max(np.linalg.eigvals(a).real))


#: Steps along the line from an unstable start to a stable reference (:func:`stable_start`).
STABILIZING_STEPS = 20


def stable_start(mats: RotorMatrices, coefficients: np.ndarray, toward: np.ndarray, speed_rad_s: float) -> np.ndarray:
    """``coefficients`` when the rigid model with them is stable, else the first stable point on the line from
    them to ``toward`` in :data:`STABILIZING_STEPS` steps (``toward`` itself when none before it is)."""
    r, target = np.asarray(coefficients, float), np.asarray(toward, float)
    if rigid_model_is_stable(mats, r, speed_rad_s):
        return r
    for t in np.linspace(0.0, 1.0, STABILIZING_STEPS + 1)[1:]:
        r_t = r + t * (target - r)
        if rigid_model_is_stable(mats, r_t, speed_rad_s):
            return r_t
    return target


def without_cross_coupling(coefficients: np.ndarray) -> np.ndarray:
    """``coefficients`` with kxy = kyx = cxy = cyx = 0 and the direct terms' magnitudes: symmetric positive
    stiffness and damping, a rotor stable at every speed (gyroscopic forces do no work: Kelvin-Tait-Chetaev)."""
    r = np.abs(np.asarray(coefficients, float))
    r[[1, 2, 5, 6]] = 0.0
    return r


#: The direct damping terms (cxx, cyy) among the 8 coefficients of Eq. 2: never negative in a passive bearing, so
#: every fit bounds them below by 0.
DIRECT_DAMPING = np.array([False] * 4 + [True, False, False, True])
#: The lower bounds of the 8 scaled coefficients in every bounded fit: 0 for the direct damping, free otherwise.
PASSIVE_LOWER_BOUND = np.where(DIRECT_DAMPING, 0.0, -np.inf)
PASSIVE_LOWER_BOUND.setflags(write=False)  # shared by every fit: no caller may change it in place


def fit_nominal(rig: RigConfig, mats, t_s: np.ndarray, y_m: np.ndarray, rows: np.ndarray, shaft: ShaftTrack,
                schedule: SpeedSchedule, u_smooth: np.ndarray, u_step: np.ndarray, h_s: float, starts, *,
                max_nfev: int, x_scale: float | None = None, start_transient: bool = False,
                prior: CoefficientPrior | None = None):
    """The nominal output-error fit: Levenberg-Marquardt over the 8 coefficients of Eq. 2, re-simulated by
    :func:`simulate_nominal`, on the output error of ``rows`` with each channel's DC gap (and, with
    ``start_transient``, the start transient of :func:`start_columns`) projected out, in micrometres (so
    that the LM tolerances mean something), with the ``prior``'s 8 pseudo-observations appended (MAP).
    Best of ``starts`` (N/m and N*s/m; non-finite or failing starts
    are skipped); ``None`` when none converges. ``max_nfev`` counts Jacobians (9 evaluations each).
    ``x_scale``: scipy's (``None``, its default, or 1.0).

    The model must be stable at the record's mean speed (a wall where it is not, as in the joint refits):
    the rig ran with a bounded response, and the periodic re-simulation exists for an unstable rotor too, so
    a record without an impact could otherwise be fitted by one (seen: an independent 5-sample skew of one
    probe plane, fitted with cxx = -670 N s/m and a mode growing at 73 1/s). An unstable start is moved
    toward the first stable start, or toward the stable :func:`without_cross_coupling` form of the prior.
    LM is unbounded: a start that ends with negative direct damping is fitted again inside the passive bounds
    (:func:`_passive_refit`), as the joint refits are bounded."""
    speed_rad_s = float(np.mean(shaft.speed_rad_s[rows]))
    wall = 1e3 * (float(np.sqrt(np.mean(y_m[rows] ** 2))) + 1e-12) * 1e6

    def residual(p):
        r = p * COEFFICIENT_SCALE
        extra = np.zeros(0) if prior is None else prior.residual_m(r)
        if not rigid_model_is_stable(mats, r, speed_rad_s):
            return np.full(int(rows.sum()) * 4 + extra.size, wall)
        yn, _, _ = simulate_nominal(rig, mats, r, t_s, shaft, schedule, u_smooth, u_step, h_s)
        e = y_m - yn
        if not np.all(np.isfinite(e[rows])):
            return np.full(int(rows.sum()) * 4 + extra.size, wall)
        s = start_columns(mats, r, schedule, h_s, estimated=start_transient)
        return np.concatenate([(e - nuisance_fit(s, e, rows))[rows].ravel(), extra]) * 1e6

    finite = [np.asarray(r0, dtype=float) for r0 in starts if np.all(np.isfinite(r0))]
    if not finite:
        return None
    stable = [r0 for r0 in finite if rigid_model_is_stable(mats, r0, speed_rad_s)]
    toward = stable[0] if stable else without_cross_coupling(prior.mean if prior is not None else finite[0])
    best = None
    for r0 in finite:
        p0 = stable_start(mats, r0, toward, speed_rad_s) / COEFFICIENT_SCALE
        try:
            res = least_squares(residual, p0, method="lm", x_scale=x_scale, diff_step=1e-4, max_nfev=max_nfev * 9)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if np.any(res.x[DIRECT_DAMPING] < 0.0):  # LM is unbounded: fit again inside the passive bounds
            passive = _passive_refit(residual, [res.x, p0], mats, toward, speed_rad_s, x_scale, max_nfev)
            res = res if passive is None else passive
        if best is None or res.cost < best.cost:
            best = res
    return best


def _passive_refit(residual, starts: list[np.ndarray], mats, toward: np.ndarray, speed_rad_s: float,
                   x_scale: float | None, max_nfev: int):
    """:func:`fit_nominal`'s fit again with the direct damping bounded below by 0 (a passive bearing), as the joint
    refits are, from each of ``starts`` (scaled coefficients) with its negative direct damping set to 0 and moved
    toward the stable ``toward`` (its direct damping also set to at least 0). Best result; ``None`` when none runs.
    Seen: a record with unmodelled 2X forces of 280 N fitted by LM with cyy = -2 993 N s/m and kxx = 10 MN/m,
    where every exact re-simulation of the effects is out of bounds."""
    passive = np.maximum(np.asarray(toward, float), PASSIVE_LOWER_BOUND)
    best = None
    for p in starts:
        r = np.maximum(np.asarray(p, float) * COEFFICIENT_SCALE, PASSIVE_LOWER_BOUND)
        p0 = stable_start(mats, r, passive, speed_rad_s) / COEFFICIENT_SCALE  # on the line between two passive points
        try:
            res = least_squares(residual, p0, method="trf", bounds=(PASSIVE_LOWER_BOUND, np.inf),
                                x_scale=x_scale or 1.0, diff_step=1e-4, max_nfev=max_nfev)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if best is None or res.cost < best.cost:
            best = res
    return best


def start_transient_shows(mats, r, y_m: np.ndarray, rows: np.ndarray, impact_force_n: np.ndarray,
                          y_nom_m: np.ndarray, schedule: SpeedSchedule, h_s: float) -> bool:
    """True when the nominal output error before the first impact (the whole record without one) is better
    explained with the start transient than without: BIC down by :data:`START_TRANSIENT_DELTA_BIC` on at
    least :data:`START_TRANSIENT_MIN_SAMPLES` fit samples (a record starting right before an impact cannot
    tell its initial state from the impact's scale, so it is taken to start steady)."""
    pre = pre_impact_rows(rows, impact_force_n)
    n = int(pre.sum())
    if n < START_TRANSIENT_MIN_SAMPLES:
        return False
    e = y_m - y_nom_m
    steady = start_columns(mats, r, schedule, h_s, estimated=False)
    rss_steady = float(np.sum((e - nuisance_fit(steady, e, pre))[pre] ** 2))
    cols = start_columns(mats, r, schedule, h_s)
    rss_start = float(np.sum((e - nuisance_fit(cols, e, pre))[pre] ** 2))
    m = 4 * n
    gain = m * np.log(max(rss_steady, 1e-300) / max(rss_start, 1e-300)) - cols.shape[2] * np.log(m)
    return bool(gain >= START_TRANSIENT_DELTA_BIC)


def pre_impact_rows(rows: np.ndarray, impact_force_n: np.ndarray) -> np.ndarray:
    """The fit rows before the first impact (all of them in a record without one)."""
    hit = np.flatnonzero(np.any(impact_force_n != 0.0, axis=1))
    pre = rows.copy()
    if hit.size:
        pre[hit[0]:] = False
    return pre


def start_transient_shows_refitted(rig: RigConfig, mats, t_s: np.ndarray, y_m: np.ndarray, rows: np.ndarray,
                                   shaft: "ShaftTrack", schedule: SpeedSchedule, u_smooth: np.ndarray,
                                   u_step: np.ndarray, h_s: float, starts, *, max_nfev: int,
                                   prior: "CoefficientPrior | None", impact_force_n: np.ndarray) -> np.ndarray | None:
    """The coefficients of the nominal fit with the start transient estimated, when that fit beats the one
    without it by :data:`START_TRANSIENT_DELTA_BIC` on the record before its first impact, each fitted there
    at its own optimum; ``None`` otherwise.

    :func:`start_transient_shows` judges the start columns at the coefficients fitted without them, which a
    run from rest drags to absorb its start (seen: a record from rest without an impact, fitted at the
    stability limit, whose free-response columns then ring for the whole record and explain nothing). Here
    both models are fitted, so the comparison is between the two at their optima (nested models, BIC).

    Only for a record without an impact: with one, the impact's free response holds the coefficients and the
    test at the nominal fit stands; and on the short span before an impact, 8 free columns fitted with the
    coefficients absorb part of any steady misfit (3 of 17 steady independent records with an impact and an
    effect were flagged so on seed 7420; none of its steady records without one)."""
    if np.any(impact_force_n != 0.0):
        return None
    pre = pre_impact_rows(rows, impact_force_n)
    n = int(pre.sum())
    if n < START_TRANSIENT_MIN_SAMPLES:
        return None
    kw = dict(max_nfev=max_nfev, x_scale=1.0, prior=prior)
    steady = fit_nominal(rig, mats, t_s, y_m, pre, shaft, schedule, u_smooth, u_step, h_s, starts[:1], **kw)
    if steady is None:
        return None
    r_steady = steady.x * COEFFICIENT_SCALE
    with_start = fit_nominal(rig, mats, t_s, y_m, pre, shaft, schedule, u_smooth, u_step, h_s,
                             [r_steady, *starts], start_transient=True, **kw)
    if with_start is None:
        return None
    m = 4 * n
    rss_steady = float(np.sum(steady.fun[:m] ** 2))
    rss_start = float(np.sum(with_start.fun[:m] ** 2))
    gain = m * np.log(max(rss_steady, 1e-300) / max(rss_start, 1e-300)) - START_STATES * np.log(m)
    return with_start.x * COEFFICIENT_SCALE if gain >= START_TRANSIENT_DELTA_BIC else None


@single_threaded_blas()  # small matrices: threaded BLAS only oversubscribes (2.3x slower measured)
def build_context(recording: RigRecording, rig: RigConfig, config: EstimatorConfig, *, passes: int = 2,
                  shaft: ShaftTrack | None = None, max_nfev: int = 30,
                  noise_std_m: np.ndarray | None = None) -> FitContext:
    """EKF, then output-error refinement of the 8 coefficients; returns the fitting context. ``noise_std_m``: the
    record's white-noise std per channel (m) when read elsewhere (a decimated record's, at its own rate:
    :func:`.decimation.fit_rate_noise_std_m`); ``None`` reads it here, above 10x the speed."""
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

    # 2. output-error refinement (DC projected out), MAP under the coefficient prior at the noise level of
    # the record's band above any rotor response (the fits' own noise estimate needs a fit first)
    low = noise_band_low_hz(1 / h, float(np.mean(shaft.speed_rad_s)))
    y_centred = y_clean[mask] - y_clean[mask].mean(axis=0)
    given_noise = None if noise_std_m is None else np.asarray(noise_std_m, float)
    if given_noise is not None and (given_noise.shape != (4,) or not np.all(np.isfinite(given_noise))
                                    or np.any(given_noise <= 0)):
        raise InputError(f"noise_std_m: four finite positive stds (m), got {noise_std_m!r}")
    noise_data = noise_std_from_spectrum(y_centred, 1 / h, low) if given_noise is None else given_noise
    prior = coefficient_prior(config, float(np.sqrt(np.mean(noise_data ** 2))))
    best = fit_nominal(rig, mats, t, y_clean, mask, shaft, schedule, u_s, u_z, h,
                       [r_ekf, config.initial_coefficients.as_array()], max_nfev=max_nfev, x_scale=1.0,
                       prior=prior)
    if best is None:
        raise InputError("the nominal output-error fit failed from both the EKF estimate and r0")
    r_hat = best.x * COEFFICIENT_SCALE
    y_nom, _, _ = simulate_nominal(rig, mats, r_hat, t, shaft, schedule, u_s, u_z, h)
    transient = start_transient_shows(mats, r_hat, y_clean, mask, recording.impact_force_n, y_nom, schedule, h)
    r_start = None if transient else start_transient_shows_refitted(
        rig, mats, t, y_clean, mask, shaft, schedule, u_s, u_z, h,
        [r_hat, r_ekf, config.initial_coefficients.as_array()], max_nfev=max_nfev, prior=prior,
        impact_force_n=recording.impact_force_n)
    if transient or r_start is not None:  # refitted with the start transient estimated (its decay had dragged
        transient = True                  # the coefficients)
        starts = [r_hat, r_ekf] if r_start is None else [r_start, r_hat, r_ekf]
        again = fit_nominal(rig, mats, t, y_clean, mask, shaft, schedule, u_s, u_z, h, starts,
                            max_nfev=max_nfev, x_scale=1.0, start_transient=True, prior=prior)
        r_hat = r_hat if again is None else again.x * COEFFICIENT_SCALE
    y_nom, v_nom, z_nom, jac = _nominal_products(rig, mats, r_hat, t, shaft, schedule, u_s, u_z, h)
    s0 = start_columns(mats, r_hat, schedule, h, estimated=transient)
    e0 = y_clean - y_nom - nuisance_fit(s0, y_clean - y_nom, mask)
    sigma = noise_std_from_spectrum(e0[mask], 1 / h, low) if given_noise is None else given_noise
    return FitContext(
        rig=rig, mats=mats, t_s=t, y_m=y_clean, shaft=shaft, impact_force_n=recording.impact_force_n, mask=mask,
        start_columns_m=s0,
        fit_rows=mask & (t < t_cut), test_rows=mask & (t >= t_cut), schedule=schedule, coefficients=r_hat,
        coefficients_ekf=r_ekf, y_nom_m=y_nom, v_nom_m_s=v_nom, z_nom_m=z_nom, jacobian=jac, noise_std_m=sigma,
        ekf_innovation_m=lp.innovation_m, ekf_innovation_std_m=lp.innovation_std_m, ekf_nis=lp.nis,
        known_smooth_n=u_s, known_step_n=u_z, prior=prior)
