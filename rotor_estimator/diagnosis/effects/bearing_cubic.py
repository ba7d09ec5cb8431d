# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Bearing nonlinearity: a cubic stiffness term at each bearing."""
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
