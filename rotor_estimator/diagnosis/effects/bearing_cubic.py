# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Bearing nonlinearity: a cubic stiffness at each bearing, per axis or radial about the static load point."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.effects.base import UNIT_CUBIC_N_PER_M3, Effect
from rotor_estimator.diagnosis.linsim import simulate_cubic


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
    kind: ClassVar[str] = "structural"
    starts_from_prior: ClassVar[bool] = True
    pair_always_refitted: ClassVar[bool] = True
    responses: ClassVar[dict[str, str]] = {
        "impact_amplitude": "the free-response frequency and decay change with amplitude",
        "speed_change": "1X amplitude no longer linear in speed^2",
    }
    description: ClassVar[str] = "cubic bearing stiffness (hardening/softening), k3x and k3y"

    def variants(self):
        return (BearingCubic(), RadialBearingCubic())

    @property
    def form(self) -> str:
        return "per axis about the bearing centre"
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
        return ctx.responses([fx, fy])

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


#: Standard gravity, m/s^2 (the static load that sets a bearing's operating point).
GRAVITY_M_S2 = 9.80665


@dataclass(frozen=True)
class RadialBearingCubic(BearingCubic):
    """Radial cubic ``f = -k3 |d|^2 d`` on each bearing's displacement ``d = s + z`` from its centre.

    A bearing runs about a static load point ``s`` (gravity, a preload), and its coefficients are the
    tangent there; what the linear model lacks is the rest of the force, ``f(s + z) - f(s) - K_t(s) z``
    (:func:`.linsim._bearing_force`): quadratic terms (2X, a DC shift, an orbit that depends on its
    direction) as well as cubic ones. ``s`` (the same at both bearings, micrometres) is fitted with
    ``k3``; the search starts from the gravity sag of the rotor on the prior stiffness in each of the four
    directions (the rig file does not say which way is down).
    """

    nl_names: ClassVar[tuple[str, ...]] = ("k3_1e15_N_per_m3", "static_x_um", "static_y_um")
    description: ClassVar[str] = "radial cubic bearing stiffness about the static load point: k3 and the point"

    def variants(self):
        return (self,)

    @property
    def form(self) -> str:
        return "radial about the static load point"

    def _sag_um(self, ctx) -> float:
        k = np.abs(np.asarray(ctx.prior_coefficients, float)[[0, 3]]).mean()
        return float(ctx.rig.shaft_mass_kg * GRAVITY_M_S2 / (2.0 * max(k, 1.0)) * 1e6)

    def _static_points(self, ctx) -> list[np.ndarray]:
        g = self._sag_um(ctx)
        return [np.array(p) for p in ((0.0, -g), (0.0, g), (-g, 0.0), (g, 0.0), (0.0, 0.0))]

    def _force(self, z_m: np.ndarray, static_um: np.ndarray) -> np.ndarray:
        """The higher-order radial force (N, 4) of unit ``k3`` (N/m^3) on bearing displacements ``z_m`` (N, 4)."""
        s = np.tile(np.asarray(static_um, float) * 1e-6, 2)
        out = np.zeros_like(z_m)
        for j in (0, 2):
            zx, zy, sx, sy = z_m[:, j], z_m[:, j + 1], s[j], s[j + 1]
            dx, dy = sx + zx, sy + zy
            r2, s2, sd = dx * dx + dy * dy, sx * sx + sy * sy, sx * zx + sy * zy
            out[:, j] = -(r2 * dx - s2 * sx - s2 * zx - 2 * sx * sd)
            out[:, j + 1] = -(r2 * dy - s2 * sy - s2 * zy - 2 * sy * sd)
        return out

    def nl_grid(self, ctx):
        e = ctx.residual_m[ctx.mask]
        e = (e - e.mean(axis=0)).ravel()
        lo, hi = self.nl_bounds(ctx)
        grid = []
        for p in self._static_points(ctx):
            col = ctx.response(UNIT_CUBIC_N_PER_M3 * self._force(ctx.z_nom_m, p))[ctx.mask]
            col = (col - col.mean(axis=0)).ravel()
            k3 = float(col @ e / max(float(col @ col), 1e-300)) * UNIT_CUBIC_N_PER_M3 / self.nl_unit
            grid.append(np.clip(np.array([k3, p[0], p[1]]), 0.9 * lo, 0.9 * hi))
        return grid

    def nl_bounds(self, ctx):
        smax = max(50.0, 10.0 * self._sag_um(ctx))
        return np.array([-1e4, -smax, -smax]), np.array([1e4, smax, smax])

    def refine_starts(self, ctx):
        e = ctx.y_m[ctx.mask]
        x2 = float(np.max(np.mean((e - e.mean(axis=0)) ** 2, axis=0)))
        k = float(np.abs(np.asarray(ctx.prior_coefficients, float)[[0, 3]]).mean())
        lo, hi = self.nl_bounds(ctx)
        out = []
        for p in self._static_points(ctx):
            d2 = x2 + float(np.sum((p * 1e-6) ** 2))  # a tangent-stiffness increase of 30 % at the orbit and point
            k3 = min(0.3 * k / (3 * max(d2, 1e-18)) / self.nl_unit, 0.9 * hi[0])
            out.append(np.array([k3, p[0], p[1]]))
        return out

    def _simulate(self, ctx, k3_n_per_m3: np.ndarray, static_um: np.ndarray | None = None) -> np.ndarray:
        mats, r = ctx.mats, ctx.coefficients
        k3 = np.full(4, float(k3_n_per_m3[0]))
        static = np.zeros(4) if static_um is None else np.tile(np.asarray(static_um, float) * 1e-6, 2)
        out, _ = simulate_cubic(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats),
                                models.rigid_output(mats), ctx.period_s, ctx.schedule, ctx.shaft.angle_rad,
                                ctx.known_smooth_n, ctx.known_step_n, k3, 4, static_m=static,
                                cache=ctx._cache.setdefault("cubic_discretization", {}))
        return out[:, :4]

    def basis(self, ctx, nl):
        ref = ctx._cache.get("cubic_zero")
        if ref is None:
            ref = ctx._cache["cubic_zero"] = BearingCubic._simulate(self, ctx, np.zeros(2))
        nl = np.asarray(nl, float)
        y = self._simulate(ctx, nl[:1] * self.nl_unit, nl[1:])
        if not np.all(np.isfinite(y)):
            y = np.full_like(y, np.nan)
        return y - ref, np.zeros((ctx.t_s.size, 4, 0))

    def physical(self, nl, lin):
        return {"k3_N_per_m3": float(nl[0] * self.nl_unit), "static_x_m": float(nl[1] * 1e-6),
                "static_y_m": float(nl[2] * 1e-6)}
