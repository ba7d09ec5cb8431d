# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Effect-aware data simulator: the rig of Eq. 2 plus any of the hidden effects, for blind tests.

Independent of the diagnosis's numerics on purpose: fixed-step RK4 on a grid
``substeps`` times finer than the sample period, integrated from rest through a
lead-in (the diagnosis re-simulates with exact discretization from the steady state).
The bearing force is nonlinear, ``f_b = K d + C dd/dt + k3 d^3`` on the shaft-to-housing
motion ``d = z - z_p``; housings move only with a pedestal; a bending mode adds a
pinned-pinned modal coordinate (:mod:`.models`). Measurement effects act on the clean
probe signals: timing skew (cubic Hermite interpolation between samples), runout fixed
in the true shaft angle, probe rotation and gain, white noise. A keyphasor offset moves
the pulses to ``angle = offset + 2 pi n``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rotor_estimator.core.forcing import average_impact_force, rigid_state_derivative
from rotor_estimator.core.jit import njit
from rotor_estimator.core.config import RigConfig
from rotor_estimator.core.errors import ConfigError
from rotor_estimator.core.model import point_force_weights, rotor_matrices
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.core.simulator import SIMULATION_EPOCH_NS, Impact
from rotor_estimator.diagnosis import models


@dataclass(frozen=True)
class HiddenEffects:
    """The effects hidden in a blind case (zeros / None = absent). SI units.

    * ``residual_unbalance_kg_m``: ``(u1_cos, u1_sin, u2_cos, u2_sin)`` at the rig's two imbalance planes.
    * ``tach_offset_rad``: keyphasor mark offset.
    * ``runout_m``: (4, H, 2) cos/sin amplitudes per channel and harmonic.
    * ``misalignment_n``: 2X force at bearing 1 ``(fx_cos, fx_sin, fy_cos, fy_sin)``; ``preload_n`` static ``(fx, fy)``.
    * ``cubic_n_per_m3``: ``(k3x, k3y)`` at both bearings.
    * ``pedestal``: ``(mass_kg, stiffness_N_per_m, damping_N_s_per_m)`` under each bearing.
    * ``bending``: ``(frequency_hz, damping_ratio, modal_mass_kg)``.
    * ``gain``: relative gain error per channel; ``orientation_rad``: mounting-angle error per probe
      (4 values, xp1 yp1 xp2 yp2) or a rotation of each probe pair (2 values, one per plane).
    * ``skew_s``: delay of yp1, xp2, yp2 relative to xp1.
    """

    residual_unbalance_kg_m: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    tach_offset_rad: float = 0.0
    runout_m: tuple = ()
    misalignment_n: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    preload_n: tuple[float, float] = (0.0, 0.0)
    cubic_n_per_m3: tuple[float, float] = (0.0, 0.0)
    pedestal: tuple[float, float, float] | None = None
    bending: tuple[float, float, float] | None = None
    gain: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    orientation_rad: tuple[float, ...] = (0.0, 0.0)
    skew_s: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def validate(self) -> "HiddenEffects":
        if self.pedestal is not None and not all(v > 0 for v in self.pedestal[:2]):
            raise ConfigError("effects.pedestal: mass_kg and stiffness_N_per_m must be > 0")
        if self.bending is not None and not (self.bending[0] > 0 and self.bending[2] > 0):
            raise ConfigError("effects.bending: frequency_hz and modal_mass_kg must be > 0")
        if len(self.orientation_rad) not in (2, 4):
            raise ConfigError("effects.orientation_rad: 2 values (per plane) or 4 (per probe)")
        if abs(self.tach_offset_rad) > math.pi:
            raise ConfigError("effects.tach_offset_rad: must be within [-pi, pi]")
        return self


#: Factor by which the start-up transient of the simulation from rest has decayed before the record
#: starts (the lead-in is lengthened to reach it): the record is then steady running, as on a rig.
STARTUP_DECAY = 1e-4


def settling_time_s(rig: RigConfig, coefficients: np.ndarray, speed_rad_s: float, effects: HiddenEffects) -> float:
    """Time for the slowest free mode of the linear part (rigid rotor, pedestals, bending mode) to decay by
    :data:`STARTUP_DECAY`: ``ln(1 / STARTUP_DECAY) / min(-Re lambda)``; ``inf`` for an unstable model."""
    mats = rotor_matrices(rig)
    if effects.pedestal is not None:
        a = models.pedestal_state_matrix(mats, coefficients, speed_rad_s, *effects.pedestal)
    else:
        a = models.rigid_state_matrix(mats, coefficients, speed_rad_s)
    rates = [-float(np.max(np.linalg.eigvals(a).real))]
    if effects.bending is not None:
        rates.append(effects.bending[1] * 2 * math.pi * effects.bending[0])
    rate = min(rates)
    return math.log(1 / STARTUP_DECAY) / rate if rate > 0 else math.inf


@dataclass(frozen=True)
class EffectScenario:
    """Operating conditions of one generated record (constant speed, impacts, noise, coefficients).

    ``lead_in_s`` is the least time simulated before the record; :func:`simulate_with_effects`
    lengthens it to :func:`settling_time_s` so that no start-up transient rings through the record
    (after a fixed 0.3 s, a 3 %-damped 60 Hz pedestal still changed the signal by 6.4 um from one
    revolution to the next: an unmodelled signal that no effect of the library, nor the truth, explains).
    """

    speed_rad_s: float
    duration_s: float
    lead_in_s: float
    impacts: tuple[Impact, ...]
    noise_std_m: float
    coefficients: np.ndarray | None = field(repr=False, default=None)
    substeps: int = 4


@njit(cache=True)
def _rhs(t, q, minv, gyro, kmat, cmat, k3, planes, w0, alpha, f2x, preload, fimp, wimp, ped, bend, phi_imp, out):
    theta = w0 * t + 0.5 * alpha * t * t
    w = w0 + alpha * t
    force = np.zeros(4)
    modal = np.zeros(2)
    for i in range(planes.shape[0]):  # moment, phase, w1, w2, phi
        a = theta + planes[i, 1]
        fx = planes[i, 0] * (w * w * math.cos(a) + alpha * math.sin(a))
        fy = planes[i, 0] * (w * w * math.sin(a) - alpha * math.cos(a))
        force[0] += planes[i, 2] * fx
        force[1] += planes[i, 2] * fy
        force[2] += planes[i, 3] * fx
        force[3] += planes[i, 3] * fy
        modal[0] += planes[i, 4] * fx
        modal[1] += planes[i, 4] * fy
    c2 = math.cos(2 * theta)
    s2 = math.sin(2 * theta)
    force[0] += f2x[0] * c2 + f2x[1] * s2 + preload[0]
    force[1] += f2x[2] * c2 + f2x[3] * s2 + preload[1]
    for j in range(2):
        force[2 * 0 + j] += wimp[0] * fimp[j]
        force[2 + j] += wimp[1] * fimp[j]
        modal[j] += phi_imp * fimp[j]
    d = np.zeros(4)
    dv = np.zeros(4)
    for r in range(4):
        d[r] = q[4 + r] - q[12 + r]
        dv[r] = q[r] - q[8 + r]
    fb = np.zeros(4)
    for r in range(4):
        acc = k3[r] * d[r] ** 3
        for c in range(4):
            acc += kmat[r, c] * d[c] + cmat[r, c] * dv[c]
        fb[r] = acc
    res = np.empty(4)
    for r in range(4):
        res[r] = force[r] - fb[r]
    rigid_state_derivative(res, q, w, gyro, minv, out)
    if ped[0] > 0:
        for r in range(4):
            out[8 + r] = (fb[r] - ped[1] * q[12 + r] - ped[2] * q[8 + r]) / ped[0]
            out[12 + r] = q[8 + r]
    else:
        for r in range(4):
            out[8 + r] = 0.0
            out[12 + r] = 0.0
    if bend[0] > 0:
        wb = 2 * math.pi * bend[0]
        for j in range(2):
            out[16 + j] = modal[j] / bend[2] - 2 * bend[1] * wb * q[16 + j] - wb * wb * q[18 + j]
            out[18 + j] = q[16 + j]
    else:
        for j in range(4):
            out[16 + j] = 0.0


@njit(cache=True)
def _integrate(n, dt, substeps, minv, gyro, kmat, cmat, k3, planes, w0, alpha, f2x, preload, wimp, ped, bend,
               phi_imp, imp_start, imp_end, imp_fx, imp_fy):
    h = dt / substeps
    q = np.zeros(20)
    states = np.zeros((n, 20))
    derivs = np.zeros((n, 20))
    k1 = np.zeros(20)
    k2 = np.zeros(20)
    k3v = np.zeros(20)
    k4 = np.zeros(20)
    tmp = np.zeros(20)
    fimp = np.zeros(2)
    for k in range(n):
        t0 = k * dt
        fimp[0] = 0.0
        fimp[1] = 0.0
        _rhs(t0, q, minv, gyro, kmat, cmat, k3, planes, w0, alpha, f2x, preload, fimp, wimp, ped, bend, phi_imp, k1)
        states[k, :] = q
        derivs[k, :] = k1
        for s in range(substeps):
            t = t0 + s * h
            average_impact_force(t, h, imp_start, imp_end, imp_fx, imp_fy, fimp)
            _rhs(t, q, minv, gyro, kmat, cmat, k3, planes, w0, alpha, f2x, preload, fimp, wimp, ped, bend, phi_imp, k1)
            for i in range(20):
                tmp[i] = q[i] + 0.5 * h * k1[i]
            _rhs(t + 0.5 * h, tmp, minv, gyro, kmat, cmat, k3, planes, w0, alpha, f2x, preload, fimp, wimp, ped, bend,
                 phi_imp, k2)
            for i in range(20):
                tmp[i] = q[i] + 0.5 * h * k2[i]
            _rhs(t + 0.5 * h, tmp, minv, gyro, kmat, cmat, k3, planes, w0, alpha, f2x, preload, fimp, wimp, ped, bend,
                 phi_imp, k3v)
            for i in range(20):
                tmp[i] = q[i] + h * k3v[i]
            _rhs(t + h, tmp, minv, gyro, kmat, cmat, k3, planes, w0, alpha, f2x, preload, fimp, wimp, ped, bend,
                 phi_imp, k4)
            for i in range(20):
                q[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3v[i] + k4[i])
    return states, derivs


@dataclass
class EffectSimulation:
    """A generated record, its noise-free probe signal and the realized noise."""

    recording: RigRecording
    clean_m: np.ndarray
    noise_m: np.ndarray


def simulate_with_effects(rig: RigConfig, scenario: EffectScenario, effects: HiddenEffects, *,
                          seed: int | None = 0, noise: bool = True) -> EffectSimulation:
    """Simulate ``rig`` with ``effects`` from rest; record ``duration_s`` after the lead-in (``lead_in_s``, or
    longer until the start-up transient has decayed: :func:`settling_time_s`)."""
    effects.validate()
    from rotor_estimator.core.model import damping_matrix, stiffness_matrix

    mats = rotor_matrices(rig)
    r = np.asarray(scenario.coefficients if scenario.coefficients is not None else rig.true_coefficients.as_array(),
                   dtype=float)
    dt = rig.sample_period_s
    settle_s = settling_time_s(rig, r, scenario.speed_rad_s, effects)
    if not math.isfinite(settle_s):
        raise ConfigError("effects: the linear model (coefficients, pedestal, bending mode) is unstable at "
                          f"{scenario.speed_rad_s:.1f} rad/s; it has no steady running to record")
    n_lead = int(round(max(scenario.lead_in_s, settle_s) / dt))
    n_rec = int(round(scenario.duration_s / dt))
    n = n_lead + n_rec
    planes = []
    for u in rig.imbalances:
        w1, w2 = point_force_weights(rig, u.axial_position_m)
        planes.append([u.moment_kg_m, u.phase_rad, w1, w2, float(models.mode_shape(rig, u.axial_position_m))])
    ru = effects.residual_unbalance_kg_m
    positions = sorted({u.axial_position_m for u in rig.imbalances})
    s1, s2 = ((positions[0], positions[-1]) if len(positions) >= 2
              else (rig.bearing1_position_m, rig.bearing2_position_m))
    for s, c, si in ((s1, ru[0], ru[1]), (s2, ru[2], ru[3])):
        if c or si:
            w1, w2 = point_force_weights(rig, s)
            planes.append([abs(complex(c, si)), math.atan2(si, c), w1, w2, float(models.mode_shape(rig, s))])
    planes_arr = np.array(planes, dtype=float).reshape(-1, 5)
    wb1 = point_force_weights(rig, rig.bearing1_position_m)  # (1, 0): misalignment acts at bearing 1 only
    assert abs(wb1[0] - 1.0) < 1e-12
    ped = np.zeros(3) if effects.pedestal is None else np.array(effects.pedestal, dtype=float)
    bend = np.zeros(3) if effects.bending is None else np.array(effects.bending, dtype=float)
    imp = scenario.impacts
    lead = n_lead * dt
    states, derivs = _integrate(
        n, dt, scenario.substeps, mats.mass_inverse, mats.gyro_matrix, stiffness_matrix(r), damping_matrix(r),
        np.array([effects.cubic_n_per_m3[0], effects.cubic_n_per_m3[1]] * 2, dtype=float), planes_arr,
        float(scenario.speed_rad_s), 0.0, np.array(effects.misalignment_n, dtype=float),
        np.array(effects.preload_n, dtype=float), mats.impact_input, ped, bend,
        float(models.mode_shape(rig, rig.impact_position_m)),
        np.array([lead + i.start_s for i in imp]), np.array([lead + i.start_s + i.duration_s for i in imp]),
        np.array([i.force_x_n for i in imp]), np.array([i.force_y_n for i in imp]))
    hp = mats.probe_from_bearing
    phi_p = np.array([models.mode_shape(rig, rig.probe1_position_m)] * 2
                     + [models.mode_shape(rig, rig.probe2_position_m)] * 2)
    pos = states[:, 4:8] @ hp.T + phi_p * np.tile(states[:, 18:20], 2)
    vel = states[:, 0:4] @ hp.T + phi_p * np.tile(states[:, 16:18], 2)
    t_all = np.arange(n) * dt
    y = pos.copy()
    for i, tau in enumerate(effects.skew_s):  # y_c(t - tau): cubic Hermite between samples
        c = i + 1
        if tau == 0.0:
            continue
        shift = tau / dt
        k0 = np.arange(n) - int(math.ceil(shift))
        u = (np.arange(n) - shift) - k0  # fraction in [0,1] from k0 toward k0+1
        k0 = np.clip(k0, 0, n - 2)
        p0, p1, m0, m1 = pos[k0, c], pos[k0 + 1, c], vel[k0, c] * dt, vel[k0 + 1, c] * dt
        h00, h10, h01, h11 = (2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u,
                              -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2)
        y[:, c] = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
    theta = scenario.speed_rad_s * t_all
    if len(effects.runout_m):
        ro = np.asarray(effects.runout_m, dtype=float)
        for c in range(4):
            for h in range(ro.shape[1]):
                y[:, c] += ro[c, h, 0] * np.cos((h + 1) * theta) + ro[c, h, 1] * np.sin((h + 1) * theta)
    angles = np.repeat(effects.orientation_rad, 2) if len(effects.orientation_rad) == 2 else effects.orientation_rad
    for p in range(2):
        dx, dy = float(angles[2 * p]), float(angles[2 * p + 1])
        x, yy = y[:, 2 * p].copy(), y[:, 2 * p + 1].copy()
        y[:, 2 * p] = (1 + effects.gain[2 * p]) * (x * math.cos(dx) + yy * math.sin(dx))
        y[:, 2 * p + 1] = (1 + effects.gain[2 * p + 1]) * (-x * math.sin(dy) + yy * math.cos(dy))
    clean = y[n_lead:]
    rng = np.random.default_rng(seed)
    noise_m = rng.standard_normal(clean.shape) * scenario.noise_std_m if noise else np.zeros_like(clean)
    t_rec = t_all[n_lead:] - lead
    # keyphasor: true angle = offset + 2 pi k
    first_k = math.ceil((scenario.speed_rad_s * lead - effects.tach_offset_rad) / (2 * math.pi)) - 1
    last_k = math.floor((scenario.speed_rad_s * (lead + scenario.duration_s) - effects.tach_offset_rad)
                        / (2 * math.pi)) + 1
    kk = np.arange(first_k, last_k + 1)
    pulses = (effects.tach_offset_rad + 2 * math.pi * kk) / scenario.speed_rad_s - lead
    force = np.zeros((n_rec, 2))
    for i in imp:
        ov = np.clip(np.minimum(t_rec + dt, i.start_s + i.duration_s) - np.maximum(t_rec, i.start_s), 0, None)
        frac = np.round(ov / dt, 9)
        force[:, 0] += i.force_x_n * frac
        force[:, 1] += i.force_y_n * frac
    epoch = SIMULATION_EPOCH_NS
    rec = RigRecording(stamps_ns=epoch + np.round(t_rec * 1e9).astype(np.int64), probes_m=clean + noise_m,
                       pulse_stamps_ns=epoch + np.round(pulses * 1e9).astype(np.int64), impact_force_n=force,
                       meta={"generator": "rotor_estimator.bench.effect_sim"})
    return EffectSimulation(recording=rec, clean_m=clean, noise_m=noise_m)
