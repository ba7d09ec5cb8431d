# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Bearing nonlinearity: a cubic stiffness at each bearing, per axis or radial about the static load point, or a
contact spring beyond a radial clearance (a rub)."""
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
        return (BearingCubic(), RadialBearingCubic(), ClearanceContact())

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

    def _prior_stiffness(self, ctx) -> float:
        """The prior's mean direct stiffness, N/m (at least 1)."""
        return max(float(np.abs(np.asarray(ctx.prior_coefficients, float)[[0, 3]]).mean()), 1.0)

    def _sag_um(self, ctx) -> float:
        return float(ctx.rig.shaft_mass_kg * GRAVITY_M_S2 / (2.0 * self._prior_stiffness(ctx)) * 1e6)

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
        k = self._prior_stiffness(ctx)
        lo, hi = self.nl_bounds(ctx)
        out = []
        for p in self._static_points(ctx):
            d2 = x2 + float(np.sum((p * 1e-6) ** 2))  # a tangent-stiffness increase of 30 % at the orbit and point
            k3 = min(0.3 * k / (3 * max(d2, 1e-18)) / self.nl_unit, 0.9 * hi[0])
            out.append(np.array([k3, p[0], p[1]]))
        return out

    def _simulate(self, ctx, k3_n_per_m3: np.ndarray, static_um: np.ndarray | None = None,
                  clearance_um: float | None = None) -> np.ndarray:
        """Probe output (N, 4) with the radial force about ``static_um``: the cubic of ``k3``, or with
        ``clearance_um`` the contact spring of stiffness ``k3`` (N/m) beyond it."""
        mats, r = ctx.mats, ctx.coefficients
        k3 = np.full(4, float(k3_n_per_m3[0]))
        static = np.zeros(4) if static_um is None else np.tile(np.asarray(static_um, float) * 1e-6, 2)
        clearance = None if clearance_um is None else np.full(4, float(clearance_um) * 1e-6)
        out, _ = simulate_cubic(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats),
                                models.rigid_output(mats), ctx.period_s, ctx.schedule, ctx.shaft.angle_rad,
                                ctx.known_smooth_n, ctx.known_step_n, k3, 4, static_m=static, clearance_m=clearance,
                                cache=ctx._cache.setdefault("cubic_discretization", {}))
        return out[:, :4]

    def _simulate_form(self, ctx, nl: np.ndarray) -> np.ndarray:
        """:meth:`_simulate` at this form's nonlinear parameters ``nl``."""
        return self._simulate(ctx, nl[:1] * self.nl_unit, nl[1:])

    def basis(self, ctx, nl):
        ref = ctx._cache.get("cubic_zero")
        if ref is None:
            ref = ctx._cache["cubic_zero"] = BearingCubic._simulate(self, ctx, np.zeros(2))
        y = self._simulate_form(ctx, np.asarray(nl, float))
        if not np.all(np.isfinite(y)):
            y = np.full_like(y, np.nan)
        return y - ref, np.zeros((ctx.t_s.size, 4, 0))

    def physical(self, nl, lin):
        return {"k3_N_per_m3": float(nl[0] * self.nl_unit), "static_x_m": float(nl[1] * 1e-6),
                "static_y_m": float(nl[2] * 1e-6)}


@dataclass(frozen=True)
class ClearanceContact(RadialBearingCubic):
    """A contact spring beyond a radial clearance at each bearing, ``f = -kc (|d| - c) d / |d|`` for ``|d| > c``
    on the displacement ``d = s + z`` from the bearing centre: a rub, or a bearing whose clearance the orbit
    closes for part of each revolution (piecewise linear, so its harmonics are not a cubic's).

    As the radial cubic, it runs about the static load point ``s`` and the coefficients are the tangent there
    (the contact's stiffness is in them when the shaft rests on it); what the linear model lacks is the rest
    (:func:`.linsim._bearing_force`, ``radial == 2``). Fitted: ``log10 kc``, ``c`` and ``s`` (the same at both
    bearings). The contact shows only when the orbit crosses the clearance, so the starts put ``c`` at the
    static point's radius and half the orbit's radius either side (:meth:`_starts`), at the gravity sags of
    :meth:`_contact_points`; the first pass's grid with ``kc`` a third and three times the prior stiffness, the
    joint refit's with ``kc`` at it and 30 times it.
    """

    nl_names: ClassVar[tuple[str, ...]] = ("log10_contact_N_per_m", "clearance_um", "static_x_um", "static_y_um")
    description: ClassVar[str] = ("contact spring beyond a radial bearing clearance (a rub) about the static load "
                                  "point: its stiffness, the clearance and the point")
    #: Contact stiffness of the starts, relative to the prior's mean direct stiffness.
    start_stiffness_ratios: ClassVar[tuple[float, ...]] = (1.0 / 3.0, 3.0)
    #: Clearances of the starts: the static point's radius plus these fractions of the orbit's radius.
    start_clearance_offsets: ClassVar[tuple[float, ...]] = (-0.5, 0.0, 0.5)
    #: Static points of the starts: the centre, and these fractions of the gravity sag on the prior's stiffness
    #: matrix in each of the four directions (the rig file does not say which way is down): ``s = K^-1 w``, ``w``
    #: half the rotor's weight, so a cross-coupled bearing sags askew (one record rested at -45 deg, where the
    #: axis-aligned starts of the radial form never reached). The nominal fit's matrix is not used: a contact
    #: drags it far (kxx -0.3 MN/m on that record, sags of 350-700 um).
    start_sag_fractions: ClassVar[tuple[float, ...]] = (0.5, 1.0)
    #: Contact stiffness of the joint refit's starts, relative to the prior's mean direct stiffness: a contact
    #: may be much stiffer than the bearing (a stop), which the first pass about the dragged fit rarely sees.
    refine_stiffness_ratios: ClassVar[tuple[float, ...]] = (1.0, 30.0)

    @property
    def form(self) -> str:
        return "contact beyond a radial clearance"

    def _orbit_radius_um(self, ctx) -> float:
        """The largest radius of the nominal fit's bearing orbits about their mean, micrometres."""
        z = ctx.z_nom_m[ctx.mask]
        z = z - z.mean(axis=0)
        return float(max(np.max(np.hypot(z[:, 0], z[:, 1])), np.max(np.hypot(z[:, 2], z[:, 3]))) * 1e6)

    def _contact_points(self, ctx, fractions: tuple[float, ...]) -> list[np.ndarray]:
        load_n = ctx.rig.shaft_mass_kg * GRAVITY_M_S2 / 2.0
        points = [np.zeros(2)]
        k = np.asarray(ctx.prior_coefficients, float)[:4].reshape(2, 2)
        if abs(np.linalg.det(k)) < 1e-12 * max(float(np.abs(k).max()), 1.0) ** 2:
            return points + self._static_points(ctx)[:4]  # a singular prior: the radial form's axis-aligned sags
        for w in ((0.0, -1.0), (0.0, 1.0), (-1.0, 0.0), (1.0, 0.0)):
            sag_um = np.linalg.solve(k, load_n * np.array(w)) * 1e6
            points += [f * sag_um for f in fractions]
        return points

    def _starts(self, ctx, fractions, ratios, offsets) -> list[np.ndarray]:
        """Starts at each static point, clearance and stiffness ratio. The clearance is the static point's radius
        plus ``offsets`` times the orbit's radius (where the orbit crosses it); about the centre, the orbit's
        radius times ``0.5 + offsets / 2``."""
        k = self._prior_stiffness(ctx)
        orbit = self._orbit_radius_um(ctx)
        lo, hi = self.nl_bounds(ctx)
        out = []
        for p in self._contact_points(ctx, fractions):
            radius = float(np.hypot(*p))
            for off in offsets:
                c = radius + off * orbit if radius > 0 else (0.5 + 0.5 * off) * orbit
                for ratio in ratios:
                    out.append(np.clip(np.array([np.log10(ratio * k), max(c, 0.0), p[0], p[1]]), lo + 1e-9,
                                       hi - 1e-9))
        return out

    def nl_grid(self, ctx):
        return self._starts(ctx, self.start_sag_fractions, self.start_stiffness_ratios, self.start_clearance_offsets)

    def refine_starts(self, ctx):
        return self._starts(ctx, (1.0,), self.refine_stiffness_ratios, (0.0,))

    def nl_bounds(self, ctx):
        k = np.log10(self._prior_stiffness(ctx))
        smax = max(50.0, 10.0 * self._sag_um(ctx))
        return np.array([k - 2.0, 0.0, -smax, -smax]), np.array([k + 2.0, 2.0 * smax, smax, smax])

    def _simulate_form(self, ctx, nl: np.ndarray) -> np.ndarray:
        return self._simulate(ctx, np.array([10.0 ** nl[0]]), nl[2:4], float(nl[1]))

    def physical(self, nl, lin):
        return {"contact_stiffness_N_per_m": float(10.0 ** nl[0]), "clearance_m": float(nl[1] * 1e-6),
                "static_x_m": float(nl[2] * 1e-6), "static_y_m": float(nl[3] * 1e-6)}
