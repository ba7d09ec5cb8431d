# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The library of candidate unmodelled effects: small, physical augmentations of Eq. 2.

Each effect is a frozen dataclass with its physical parameters (SI, unit in the name)
and two functions used by :mod:`.fitting`:

* ``basis(ctx, nl)`` -> ``(offset (N,4) or None, columns (N,4,k))``: the effect's
  contribution to the probe output about the nominal fit, for nonlinear parameters
  ``nl``; the columns' gains are the linear parameters.
* ``physical(nl, lin)`` -> the named physical parameters.

Measurement-side effects act on the probe signals, ``y = g(y_true)``; force-side
effects add a generalized force ``F_e`` to Eq. 5 and enter through the nominal model's
response (linear in their amplitudes); structural effects (pedestal, bending mode)
change the state-space model (:mod:`.models`) and are re-simulated.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.core.model import imbalance_force
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.context import FitContext
from rotor_estimator.diagnosis.linsim import simulate_cubic, simulate_linear

CHANNELS = ("xp1", "yp1", "xp2", "yp2")
UNIT_UNBALANCE_KG_M = 1e-6   # 1 g*mm
UNIT_CUBIC_N_PER_M3 = 1e12
UNIT_RUNOUT_M = 1e-6
UNIT_SKEW_S = 1e-6


@dataclass(frozen=True)
class Effect:
    """Base of the candidate effects: ``name``, a one-line ``description`` and parameter names."""

    name: ClassVar[str] = "effect"
    description: ClassVar[str] = ""
    nl_names: ClassVar[tuple[str, ...]] = ()

    def lin_names(self, ctx: FitContext) -> tuple[str, ...]:
        raise NotImplementedError

    def n_params(self, ctx: FitContext) -> int:
        return len(self.nl_names) + len(self.lin_names(ctx))

    def nl_grid(self, ctx: FitContext) -> list[np.ndarray]:
        """Starting points of the nonlinear search (empty for a linear effect)."""
        return []

    def nl_bounds(self, ctx: FitContext) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(0), np.zeros(0)

    def refine_starts(self, ctx: FitContext) -> list[np.ndarray]:
        """Extra nonlinear starting points of the joint refit with the coefficients (structural effects)."""
        return []

    def basis(self, ctx: FitContext, nl: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
        raise NotImplementedError

    def physical(self, nl: np.ndarray, lin: np.ndarray) -> dict[str, float]:
        """Physical parameter values (SI) from the fitted nonlinear and linear parameters."""
        return {}

    #: True for an effect that acts on the whole probe signal (a delay): in a pair it also acts
    #: on the other effect's contribution (:meth:`transform`).
    transforms_signal: ClassVar[bool] = False

    def transform(self, ctx: FitContext, nl: np.ndarray, signal_m: np.ndarray) -> np.ndarray:
        """The effect applied to another contribution ``signal_m`` ((N,4) or (N,4,k)); identity by default."""
        return signal_m

    #: True for a force effect: its contribution is the response to a force (``ctx.response``), so in a
    #: pair with a structural effect it is the response through that effect's model (:meth:`carrier`).
    forcing: ClassVar[bool] = False

    def carrier(self, ctx: FitContext, nl: np.ndarray) -> FitContext | None:
        """``ctx`` with its force response sent through this effect's structural model; ``None`` if it has none."""
        return None


def rotating_mass_force(ctx: FitContext, phase_rad: float, moment_kg_m: float,
                        harmonic: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Point force ``(fx, fy)`` (N each) of a rotating mass ``m r`` at phase ``phase_rad`` from the
    keyphasor mark: ``m r (w^2 cos a + w' sin a, w^2 sin a - w' cos a)`` (Eq. 5 before the lever rule)."""
    a = harmonic * ctx.shaft.angle_rad + phase_rad
    w, acc = ctx.shaft.speed_rad_s, ctx.shaft.accel_rad_s2
    return moment_kg_m * (w * w * np.cos(a) + acc * np.sin(a)), moment_kg_m * (w * w * np.sin(a) - acc * np.cos(a))


def _unbalance_force(ctx: FitContext, axial_position_m: float, phase_rad: float, moment_kg_m: float,
                     harmonic: int = 1) -> np.ndarray:
    """Generalized force of a rotating mass ``m r`` at ``axial_position_m`` (Eq. 5, single plane)."""
    fx, fy = rotating_mass_force(ctx, phase_rad, moment_kg_m, harmonic)
    return models.point_generalized_force(ctx.rig, axial_position_m, fx, fy)


def unbalance_planes(ctx: FitContext) -> tuple[float, float]:
    """Correction planes: the rig's two imbalance planes, else the bearing stations."""
    planes = sorted({u.axial_position_m for u in ctx.rig.imbalances})
    if len(planes) >= 2:
        return planes[0], planes[-1]
    return ctx.rig.bearing1_position_m, ctx.rig.bearing2_position_m


@dataclass(frozen=True)
class ResidualUnbalance(Effect):
    """Unknown residual unbalance in two correction planes (1X forcing through Eq. 2)."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "residual_unbalance"
    description: ClassVar[str] = "unknown residual unbalance in two planes (1X forward forcing)"

    def lin_names(self, ctx):
        return ("u1_cos_g_mm", "u1_sin_g_mm", "u2_cos_g_mm", "u2_sin_g_mm")

    def basis(self, ctx, nl):
        cols = [ctx.response(_unbalance_force(ctx, s, ph, UNIT_UNBALANCE_KG_M))
                for s in unbalance_planes(ctx) for ph in (0.0, np.pi / 2)]
        return None, np.stack(cols, axis=2)

    def physical(self, nl, lin):
        u1, u2 = complex(lin[0], lin[1]), complex(lin[2], lin[3])
        return {"plane1_unbalance_g_mm": abs(u1), "plane1_phase_deg": float(np.degrees(np.angle(u1))),
                "plane2_unbalance_g_mm": abs(u2), "plane2_phase_deg": float(np.degrees(np.angle(u2)))}


@dataclass(frozen=True)
class TachometerOffset(Effect):
    """Keyphasor mark off by an angle: the known imbalance is applied at ``angle + offset``."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "tach_offset"
    description: ClassVar[str] = "keyphasor angular offset (imbalance phase reference rotated)"
    nl_names: ClassVar[tuple[str, ...]] = ("offset_rad",)

    def lin_names(self, ctx):
        return ()

    def nl_grid(self, ctx):
        return [np.array([v]) for v in (-0.3, -0.1, 0.1, 0.3)]

    def nl_bounds(self, ctx):
        return np.array([-np.pi / 2]), np.array([np.pi / 2])

    def basis(self, ctx, nl):
        shifted = imbalance_force(ctx.mats, ctx.shaft.angle_rad + nl[0], ctx.shaft.speed_rad_s,
                                  ctx.shaft.accel_rad_s2)
        return ctx.response(shifted - ctx.known_smooth_n), np.zeros((ctx.t_s.size, 4, 0))

    def physical(self, nl, lin):
        return {"offset_deg": float(np.degrees(nl[0]))}


@dataclass(frozen=True)
class ProbeRunout(Effect):
    """Mechanical/electrical runout: a pattern fixed in shaft angle, Fourier series per probe."""

    name: ClassVar[str] = "probe_runout"
    description: ClassVar[str] = "probe runout fixed in shaft angle (harmonics 1..H per channel)"
    harmonics: int = 4

    def lin_names(self, ctx):
        return tuple(f"{ch}_{h}x_{cs}_um" for ch in CHANNELS for h in range(1, self.harmonics + 1)
                     for cs in ("cos", "sin"))

    def basis(self, ctx, nl):
        n = ctx.t_s.size
        cols = np.zeros((n, 4, 8 * self.harmonics))
        i = 0
        for c in range(4):
            for h in range(1, self.harmonics + 1):
                cols[:, c, i] = np.cos(h * ctx.shaft.angle_rad) * UNIT_RUNOUT_M
                cols[:, c, i + 1] = np.sin(h * ctx.shaft.angle_rad) * UNIT_RUNOUT_M
                i += 2
        return None, cols

    def physical(self, nl, lin):
        amp = np.abs(lin[0::2] + 1j * lin[1::2]).reshape(4, self.harmonics) * UNIT_RUNOUT_M
        out = {f"{ch}_runout_peak_m": float(np.sqrt((a ** 2).sum() * 2)) for ch, a in zip(CHANNELS, amp)}
        for h in range(self.harmonics):
            out[f"mean_{h + 1}x_amplitude_m"] = float(amp[:, h].mean())
        return out


@dataclass(frozen=True)
class Misalignment(Effect):
    """Coupling misalignment: a 2X force at the drive-end bearing (its static preload only shifts DC)."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "misalignment"
    description: ClassVar[str] = "coupling misalignment, 2X force at bearing 1 (x and y)"

    def lin_names(self, ctx):
        return ("fx_2x_cos_n", "fx_2x_sin_n", "fy_2x_cos_n", "fy_2x_sin_n")

    def basis(self, ctx, nl):
        two = 2 * ctx.shaft.angle_rad
        s = ctx.rig.bearing1_position_m
        zero = np.zeros_like(two)
        cols = [ctx.response(models.point_generalized_force(ctx.rig, s, np.cos(two), zero)),
                ctx.response(models.point_generalized_force(ctx.rig, s, np.sin(two), zero)),
                ctx.response(models.point_generalized_force(ctx.rig, s, zero, np.cos(two))),
                ctx.response(models.point_generalized_force(ctx.rig, s, zero, np.sin(two)))]
        return None, np.stack(cols, axis=2)

    def physical(self, nl, lin):
        return {"force_2x_x_amplitude_n": float(abs(complex(lin[0], lin[1]))),
                "force_2x_y_amplitude_n": float(abs(complex(lin[2], lin[3])))}


@dataclass(frozen=True)
class BearingCubic(Effect):
    """Bearing stiffness nonlinearity ``f = -k3 x^3`` (x and y, both bearings), simulated exactly.

    ``k3x, k3y`` are nonlinear parameters: the rigid model of Eq. 2 is re-simulated with
    the cubic bearing force (:func:`.linsim.simulate_cubic`, nonlinear periodic start),
    so a hardening that reshapes the impact transient and adds 3X is modelled at any
    strength. The search starts from the first-order estimate (the response to
    ``-k3 z_nom^3`` fitted linearly).
    """

    name: ClassVar[str] = "bearing_cubic"
    description: ClassVar[str] = "cubic bearing stiffness (hardening/softening), k3x and k3y"
    nl_names: ClassVar[tuple[str, ...]] = ("k3x_1e15_N_per_m3", "k3y_1e15_N_per_m3")
    #: Scale of the nonlinear parameters (order one for a realistic hardening), N/m^3.
    nl_unit: ClassVar[float] = 1e15

    def lin_names(self, ctx):
        return ()

    def _first_order_columns(self, ctx):
        z = ctx.z_nom_m
        fx = np.zeros_like(z)
        fy = np.zeros_like(z)
        fx[:, [0, 2]] = -UNIT_CUBIC_N_PER_M3 * z[:, [0, 2]] ** 3
        fy[:, [1, 3]] = -UNIT_CUBIC_N_PER_M3 * z[:, [1, 3]] ** 3
        return np.stack([ctx.response(fx), ctx.response(fy)], axis=2)

    def nl_grid(self, ctx):
        cols = self._first_order_columns(ctx)[ctx.mask]
        e = ctx.residual_m[ctx.mask]
        a = (cols - cols.mean(axis=0)).reshape(-1, 2)
        est, *_ = np.linalg.lstsq(a, (e - e.mean(axis=0)).ravel(), rcond=None)
        est = est * UNIT_CUBIC_N_PER_M3 / self.nl_unit
        lo, hi = self.nl_bounds(ctx)
        est = np.clip(est, 0.9 * lo, 0.9 * hi)
        return [est, 0.5 * est, np.zeros(2)]

    def nl_bounds(self, ctx):
        return np.full(2, -1e4), np.full(2, 1e4)

    #: Tangent-stiffness increases ``3 k3 x_rms^2 / k`` at the measured RMS orbit the joint refit starts from.
    start_tangent_ratios: ClassVar[tuple[float, ...]] = (0.1, 1.0)

    def refine_starts(self, ctx):
        # the nominal fit absorbs a hardening into stiffer coefficients, so the first pass about
        # them sees little of it: the joint refit also starts from hardenings scaled to the data,
        # a given tangent-stiffness increase at the measured orbit over the prior stiffness
        e = ctx.y_m[ctx.mask]
        rms = np.sqrt(np.mean((e - e.mean(axis=0)) ** 2, axis=0))
        x2 = np.array([max(rms[0], rms[2]), max(rms[1], rms[3])]) ** 2
        k = np.abs(np.asarray(ctx.prior_coefficients, float)[[0, 3]])
        lo, hi = self.nl_bounds(ctx)
        return [np.clip(r * k / (3 * np.maximum(x2, 1e-18)) / self.nl_unit, 0.0, 0.9 * hi)
                for r in self.start_tangent_ratios]

    def _simulate(self, ctx, k3_n_per_m3: np.ndarray) -> np.ndarray:
        mats, r = ctx.mats, ctx.coefficients
        k3 = np.array([k3_n_per_m3[0], k3_n_per_m3[1]] * 2)
        out, _ = simulate_cubic(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats),
                                models.rigid_output(mats), ctx.period_s, ctx.schedule, ctx.shaft.angle_rad,
                                ctx.known_smooth_n, ctx.known_step_n, k3, 4,
                                cache=ctx._cache.setdefault("cubic_discretization", {}))
        return out[:, :4]

    def basis(self, ctx, nl):
        ref = ctx._cache.get("cubic_zero")
        if ref is None:
            ref = ctx._cache["cubic_zero"] = self._simulate(ctx, np.zeros(2))
        y = self._simulate(ctx, np.asarray(nl, float) * self.nl_unit)
        if not np.all(np.isfinite(y)):
            y = np.full_like(y, np.nan)
        return y - ref, np.zeros((ctx.t_s.size, 4, 0))

    def physical(self, nl, lin):
        return {"k3x_N_per_m3": float(nl[0] * self.nl_unit), "k3y_N_per_m3": float(nl[1] * self.nl_unit)}


@dataclass(frozen=True)
class PedestalFlexibility(Effect):
    """Bearing housings on a mass-spring-damper foundation (isotropic, both bearings)."""

    name: ClassVar[str] = "pedestal"
    description: ClassVar[str] = "foundation/pedestal flexibility: housing mass, spring and damper under each bearing"
    nl_names: ClassVar[tuple[str, ...]] = ("log10_frequency_hz", "log10_damping_ratio", "log10_mass_kg")

    def lin_names(self, ctx):
        return ()

    def nl_grid(self, ctx):
        return [np.array([np.log10(f), np.log10(0.05), np.log10(m)])
                for f in (50.0, 100.0, 200.0, 400.0, 800.0, 1600.0) for m in (0.5, 2.0, 8.0)]

    def nl_bounds(self, ctx):
        fmax = 0.45 * ctx.sample_rate_hz
        return np.array([np.log10(20.0), -3.0, -1.5]), np.array([np.log10(fmax), 0.0, 2.0])

    def refine_starts(self, ctx):
        return [np.array([np.log10(f), np.log10(0.05), np.log10(2.0)]) for f in (60.0, 120.0, 250.0, 500.0)]

    @staticmethod
    def housing(nl: np.ndarray) -> tuple[float, float, float]:
        f, zeta, m = 10 ** nl[0], 10 ** nl[1], 10 ** nl[2]
        k = m * (2 * np.pi * f) ** 2
        return m, k, 2 * zeta * np.sqrt(k * m)

    def basis(self, ctx, nl):
        y = self.carrier(ctx, nl).response(ctx.known_smooth_n, ctx.known_step_n)
        return y - ctx.y_nom_m, np.zeros((ctx.t_s.size, 4, 0))

    def carrier(self, ctx, nl):
        """The context whose forces (a partner's unbalance, misalignment) act on the shaft on its pedestals."""
        from dataclasses import replace

        m, k, c = self.housing(nl)
        mats, r = ctx.mats, ctx.coefficients
        model = (lambda w: models.pedestal_state_matrix(mats, r, w, m, k, c), models.pedestal_input(mats),
                 models.pedestal_output(mats))
        return replace(ctx, response_model=model, _cache={})

    def physical(self, nl, lin):
        m, k, c = self.housing(nl)
        return {"pedestal_frequency_hz": float(10 ** nl[0]), "pedestal_damping_ratio": float(10 ** nl[1]),
                "pedestal_mass_kg": m, "pedestal_stiffness_N_per_m": k, "pedestal_damping_N_s_per_m": c}


def modal_forces(ctx: FitContext) -> tuple[np.ndarray, np.ndarray]:
    """Modal force ``sum_i phi(s_i) f_i`` (N, 2) of the known imbalances (smooth) and the impact (step)."""
    rig = ctx.rig
    smooth = np.zeros((ctx.t_s.size, 2))
    for u in rig.imbalances:
        phi = float(models.mode_shape(rig, u.axial_position_m))
        fx, fy = rotating_mass_force(ctx, u.phase_rad, u.moment_kg_m)
        smooth[:, 0] += phi * fx
        smooth[:, 1] += phi * fy
    step = float(models.mode_shape(rig, rig.impact_position_m)) * ctx.impact_force_n
    return smooth, step


@dataclass(frozen=True)
class ShaftBending(Effect):
    """First bending mode of the shaft (pinned at the bearings), excited by the imbalance and the impact."""

    name: ClassVar[str] = "shaft_bending"
    description: ClassVar[str] = "shaft flexibility: first bending mode (frequency, damping, modal mass)"
    nl_names: ClassVar[tuple[str, ...]] = ("log10_frequency_hz", "log10_damping_ratio")

    def lin_names(self, ctx):
        return ("inverse_modal_mass_per_kg",)

    def nl_grid(self, ctx):
        fmax = 0.4 * ctx.sample_rate_hz
        return [np.array([lf, np.log10(z)]) for lf in np.linspace(np.log10(60.0), np.log10(fmax), 16)
                for z in (0.01, 0.05)]

    def nl_bounds(self, ctx):
        return np.array([np.log10(20.0), -3.0]), np.array([np.log10(0.45 * ctx.sample_rate_hz), -0.3])

    def refine_starts(self, ctx):
        return [np.array([np.log10(f), np.log10(0.02)]) for f in (80.0, 120.0, 180.0, 270.0, 400.0, 600.0, 900.0)]

    def basis(self, ctx, nl):
        smooth, step = modal_forces(ctx)
        a = models.modal_state_matrix(10 ** nl[0], 10 ** nl[1])
        b = np.vstack([np.eye(2), np.zeros((2, 2))])
        c = np.hstack([np.zeros((2, 2)), np.eye(2)])
        q, _ = simulate_linear(lambda w: a, b, c, ctx.period_s, ctx.schedule, ctx.shaft.angle_rad, smooth, step)
        rig = ctx.rig
        p1, p2 = models.mode_shape(rig, rig.probe1_position_m), models.mode_shape(rig, rig.probe2_position_m)
        col = np.column_stack([p1 * q[:, 0], p1 * q[:, 1], p2 * q[:, 0], p2 * q[:, 1]])
        return None, col[:, :, None]

    def physical(self, nl, lin):
        inv_m = float(lin[0]) if len(lin) else float("nan")
        return {"bending_frequency_hz": float(10 ** nl[0]), "bending_damping_ratio": float(10 ** nl[1]),
                "modal_mass_kg": float(1.0 / inv_m) if inv_m else float("inf")}


@dataclass(frozen=True)
class ProbeGainOrientation(Effect):
    """Sensitivity and mounting-angle error of each probe: a general 2x2 map per probe plane.

    A probe at angle error ``d_i`` with gain error ``g_i`` reads
    ``(1 + g_i) (x cos d_i + y sin d_i)`` (x probe) or ``(1 + g_i) (-x sin d_i + y cos d_i)``
    (y probe): each plane's pair is the exact linear map ``[x', y'] = A_p [x, y]`` with
    4 free entries (per-probe gain and angle, so non-orthogonal probes too), fitted as
    ``A_p - I`` on the nominal output.
    """

    name: ClassVar[str] = "probe_gain_orientation"
    description: ClassVar[str] = "probe gain and mounting-angle error per probe (2x2 map per probe plane)"

    def lin_names(self, ctx):
        return tuple(f"{plane}_{entry}" for plane in ("p1", "p2")
                     for entry in ("axx_minus_1", "axy", "ayx", "ayy_minus_1"))

    def basis(self, ctx, nl):
        y = ctx.y_nom_m
        cols = np.zeros((y.shape[0], 4, 8))
        for p in range(2):
            x_c, y_c = 2 * p, 2 * p + 1
            cols[:, x_c, 4 * p] = y[:, x_c]
            cols[:, x_c, 4 * p + 1] = y[:, y_c]
            cols[:, y_c, 4 * p + 2] = y[:, x_c]
            cols[:, y_c, 4 * p + 3] = y[:, y_c]
        return None, cols

    def physical(self, nl, lin):
        out = {}
        for p in range(2):
            axx, axy, ayx, ayy = 1 + lin[4 * p], lin[4 * p + 1], lin[4 * p + 2], 1 + lin[4 * p + 3]
            x_ch, y_ch = CHANNELS[2 * p], CHANNELS[2 * p + 1]
            out[f"gain_error_{x_ch}"] = float(np.hypot(axx, axy) - 1)
            out[f"gain_error_{y_ch}"] = float(np.hypot(ayx, ayy) - 1)
            out[f"angle_error_{x_ch}_deg"] = float(np.degrees(np.arctan2(axy, axx)))
            out[f"angle_error_{y_ch}_deg"] = float(np.degrees(np.arctan2(-ayx, ayy)))
        return out


def delayed(y_m: np.ndarray, v_m_s: np.ndarray, delay_s: float, period_s: float) -> np.ndarray:
    """``y(t - delay)`` of a sampled signal by cubic Hermite interpolation on samples and derivatives (N,)."""
    n = y_m.size
    shift = delay_s / period_s
    k0 = np.arange(n) - int(np.ceil(shift))
    u = (np.arange(n) - shift) - k0
    k0 = np.clip(k0, 0, n - 2)
    p0, p1, m0, m1 = y_m[k0], y_m[k0 + 1], v_m_s[k0] * period_s, v_m_s[k0 + 1] * period_s
    u2, u3 = u * u, u * u * u
    return ((2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1)


@dataclass(frozen=True)
class TimingSkew(Effect):
    """Sampling skew between channels: ``y_c(t - tau_c)``, tau relative to xp1 (exact delay, not a derivative).

    The delays are nonlinear parameters: the skewed channel is the nominal output delayed
    by cubic Hermite interpolation on the nominal probe displacement and velocity, so a
    delay of a sizeable fraction of a revolution is modelled as well as a small one.
    The search starts from the derivative (first-order) estimate ``tau = -<e, v>/<v, v>``.
    """

    name: ClassVar[str] = "timing_skew"
    description: ClassVar[str] = "timing skew between probe channels (relative to xp1)"
    nl_names: ClassVar[tuple[str, ...]] = ("skew_yp1_us", "skew_xp2_us", "skew_yp2_us")

    def lin_names(self, ctx):
        return ()

    def nl_grid(self, ctx):
        v = ctx.v_nom_m_s[ctx.mask]
        e = ctx.residual_m[ctx.mask]
        tau = np.array([-(e[:, c] @ v[:, c]) / max(float(v[:, c] @ v[:, c]), 1e-300) for c in (1, 2, 3)])
        bound = self.nl_bounds(ctx)[1][0]
        return [np.clip(tau / UNIT_SKEW_S, -0.9 * bound, 0.9 * bound), np.zeros(3)]

    def nl_bounds(self, ctx):
        b = 0.25 * 2 * np.pi / max(ctx.mean_speed_rad_s, 1.0) / UNIT_SKEW_S  # a quarter revolution
        return np.full(3, -b), np.full(3, b)

    def basis(self, ctx, nl):
        y, v = ctx.y_nom_m, ctx.v_nom_m_s
        off = np.zeros_like(y)
        for i, c in enumerate((1, 2, 3)):
            if nl[i] != 0.0:
                off[:, c] = delayed(y[:, c], v[:, c], nl[i] * UNIT_SKEW_S, ctx.period_s) - y[:, c]
        return off, np.zeros((y.shape[0], 4, 0))

    def physical(self, nl, lin):
        return {f"skew_{ch}_s": float(v * UNIT_SKEW_S) for ch, v in zip(CHANNELS[1:], nl)}

    transforms_signal: ClassVar[bool] = True

    def transform(self, ctx, nl, signal_m):
        """Another contribution delayed like the probe it appears on (derivative by central differences)."""
        out = np.array(signal_m, dtype=float, copy=True)
        if out.size == 0:
            return out
        flat = out.reshape(out.shape[0], 4, -1)
        for i, c in enumerate((1, 2, 3)):
            if nl[i] == 0.0:
                continue
            for k in range(flat.shape[2]):
                sig = flat[:, c, k].copy()
                flat[:, c, k] = delayed(sig, np.gradient(sig, ctx.period_s), nl[i] * UNIT_SKEW_S, ctx.period_s)
        return flat.reshape(out.shape)


@dataclass(frozen=True)
class HammerForceScale(Effect):
    """The impact hammer's sensitivity is off: the force acting is ``(1 + s)`` times the recorded one.

    One linear parameter, the response to the recorded impacts (the step input of Eq. 5); nothing to fit
    in a record without an impact. The filter cannot see this error in its innovations (the coefficients
    absorb it): only the shape of the free response after the impact against the 1X response tells it."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "hammer_force_scale"
    description: ClassVar[str] = "impact hammer sensitivity error (recorded force scaled)"

    def lin_names(self, ctx):
        return ("force_scale_error",) if np.any(ctx.known_step_n) else ()

    def basis(self, ctx, nl):
        if not np.any(ctx.known_step_n):
            return None, np.zeros((ctx.t_s.size, 4, 0))
        col = ctx.response(np.zeros_like(ctx.known_smooth_n), ctx.known_step_n)
        return None, col[:, :, None]

    def physical(self, nl, lin):
        if not len(lin):
            return {}
        return {"hammer_force_scale": 1.0 + float(lin[0]), "hammer_sensitivity_error_percent": 100.0 * float(lin[0])}


from rotor_estimator.diagnosis.flexible_shaft import FlexibleShaft  # noqa: E402 - it builds on Effect and the helpers above

#: The candidate library, in report order (``shaft_bending`` is the coupled equivalent beam with the
#: decoupled pinned-pinned mode of :class:`ShaftBending` as its second variant).
LIBRARY: tuple[Effect, ...] = (ResidualUnbalance(), TachometerOffset(), ProbeRunout(), Misalignment(),
                               BearingCubic(), PedestalFlexibility(), FlexibleShaft(), ProbeGainOrientation(),
                               TimingSkew(), HammerForceScale())
EFFECT_NAMES: tuple[str, ...] = tuple(e.name for e in LIBRARY)


def effect_by_name(name: str) -> Effect:
    for e in LIBRARY:
        if e.name == name:
            return e
    raise KeyError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
