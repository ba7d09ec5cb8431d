# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The independent benchmark's own rigid-rotor physics, written apart from :mod:`rotor_estimator.core.model`.

Coordinates are those of the mass center, not of the bearings: ``q = [xc, yc, ax, ay]`` with
``x(s) = xc + s ax`` and ``y(s) = yc + s ay`` the shaft's lateral position at axial station ``s``
(from the mass center, positive toward bearing 2; x horizontal, y vertical, the shaft spinning
from +x toward +y). With a foundation, ``q`` gains ``[xf, yf]``: one mass that carries both
bearing housings on its own spring and damper to ground. Newton-Euler for a symmetric rotor
(tilts ``ax = theta_y``, ``ay = -theta_x``, transverse angular momentum ``It w + Ip Omega n``)::

    m xc''  = sum Fx              It ax'' + Ip Omega ay' = sum s Fx
    m yc''  = sum Fy - m g        It ay'' - Ip Omega ax' = sum s Fy
    mf xf'' = -sum fbx - kf xf - cf xf'   (and y)

Each bearing acts on the shaft with ``f = -(K d + C d') - f_nl(d)``, ``d`` the shaft-to-housing
displacement at the bearing's station and ``K = [[kxx, kxy], [kyx, kyy]]``, ``C`` likewise (the same
8 coefficients at both bearings). Forces are harmonics of the shaft angle ``theta``: ``fx =
Re(Fx e^{i h theta})`` (unbalance: ``h = 1``, ``Fx = u Omega^2 e^{i phi}``, ``Fy = -i Fx``), static
loads (``h = 0``) and hammer pulses (half-sine or rectangular). Integration: ``scipy.integrate.solve_ivp``
(DOP853, rtol 1e-9) with dense output, split at the hammer pulses' edges. A steady record starts from
the periodic solution of the linear part (a complex solve per harmonic); a record from rest starts at
``q = 0``, ``q' = 0``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp

from rotor_estimator.core.config import RigConfig

GRAVITY_M_S2 = 9.80665
#: Stamps of generated records start here (2025-06-15T00:00:00Z), ns.
EPOCH_NS = 1_749_945_600_000_000_000


@dataclass(frozen=True)
class RotorGeometry:
    """Mass, inertias about the mass center and axial stations (m, from the mass center) of a rigid rotor."""

    mass_kg: float
    transverse_inertia_kg_m2: float
    polar_inertia_kg_m2: float
    bearing_positions_m: tuple[float, float]
    probe_positions_m: tuple[float, float]
    impact_position_m: float
    sample_rate_hz: float

    @classmethod
    def from_rig(cls, rig: RigConfig) -> "RotorGeometry":
        return cls(rig.shaft_mass_kg, rig.transverse_inertia_kg_m2, rig.polar_inertia_kg_m2,
                   (rig.bearing1_position_m, rig.bearing2_position_m), (rig.probe1_position_m, rig.probe2_position_m),
                   rig.impact_position_m, rig.sample_rate_hz)


@dataclass(frozen=True)
class HarmonicForce:
    """A lateral force at ``axial_position_m``: ``fx = Re(fx_n e^{i h theta})``, ``fy = Re(fy_n e^{i h theta})``
    (``h = 0``: a static force, the real parts)."""

    axial_position_m: float
    harmonic: int
    fx_n: complex
    fy_n: complex


def unbalance(axial_position_m: float, moment_kg_m: float, phase_rad: float, speed_rad_s: float) -> HarmonicForce:
    """A mass ``m r`` at angle ``phase`` from the keyphasor mark: ``m r Omega^2 (cos, sin)(theta + phase)``."""
    f = moment_kg_m * speed_rad_s ** 2 * complex(math.cos(phase_rad), math.sin(phase_rad))
    return HarmonicForce(axial_position_m, 1, f, -1j * f)


@dataclass(frozen=True)
class Foundation:
    """One mass under both bearing housings, on its own isotropic spring and damper to ground.

    ``probes_relative``: the probes are mounted on the housing (they read shaft minus foundation),
    otherwise on an inertial stand (absolute shaft motion)."""

    mass_kg: float
    stiffness_n_per_m: float
    damping_n_s_per_m: float
    probes_relative: bool


@dataclass(frozen=True)
class BearingNonlinearity:
    """Radial nonlinear bearing force added to the linear one, at both bearings, on the relative displacement d:
    a cubic ``k3 |d|^2 d`` and/or a contact ``kc (|d| - clearance) d/|d|`` beyond a radial clearance."""

    cubic_n_per_m3: float = 0.0
    clearance_m: float = math.inf
    contact_stiffness_n_per_m: float = 0.0


@dataclass(frozen=True)
class HammerPulse:
    """A hammer blow at the impact station: peak ``(force_x_n, force_y_n)`` from ``start_s`` for ``duration_s``,
    half-sine (a real hammer tip) or rectangular (the rig model's idealisation)."""

    start_s: float
    duration_s: float
    force_x_n: float
    force_y_n: float
    shape: str = "half_sine"

    def profile(self, t: np.ndarray) -> np.ndarray:
        """Force shape in [0, 1] at times ``t``."""
        u = (np.asarray(t, dtype=float) - self.start_s) / self.duration_s
        inside = (u >= 0) & (u < 1)
        if self.shape == "rect":
            return inside.astype(float)
        return np.where(inside, np.sin(np.pi * np.clip(u, 0, 1)), 0.0)

    def sample_means(self, t_k: np.ndarray, dt: float) -> np.ndarray:
        """Mean force over each sample period ``[t_k, t_k + dt)`` (N, 2): what a hold-channel records."""
        a = np.clip((t_k - self.start_s) / self.duration_s, 0, 1)
        b = np.clip((t_k + dt - self.start_s) / self.duration_s, 0, 1)
        if self.shape == "rect":
            share = (b - a) * self.duration_s / dt
        else:
            share = (np.cos(np.pi * a) - np.cos(np.pi * b)) / np.pi * self.duration_s / dt
        return share[:, None] * np.array([self.force_x_n, self.force_y_n])


@dataclass(frozen=True)
class TrueModel:
    """Everything the independent simulator integrates: rotor, bearings, foundation, forces, pulses."""

    geometry: RotorGeometry
    coefficients: tuple[float, ...]
    speed_rad_s: float
    forces: tuple[HarmonicForce, ...] = ()
    foundation: Foundation | None = None
    nonlinearity: BearingNonlinearity | None = None
    impacts: tuple[HammerPulse, ...] = ()
    gravity_m_s2: float = GRAVITY_M_S2
    #: shaft angle used by the forcing; None: the true ``Omega t``
    angle_of_time: Callable[[float], float] | None = field(default=None, compare=False)

    def without(self, **changes) -> "TrueModel":
        return replace(self, **changes)


class Matrices:
    """M, C, G (per rad/s), K, the point maps and the harmonic generalized forces of a :class:`TrueModel`."""

    def __init__(self, model: TrueModel) -> None:
        g = model.geometry
        self.n = n = 6 if model.foundation is not None else 4
        self.mass = np.diag([g.mass_kg, g.mass_kg, g.transverse_inertia_kg_m2, g.transverse_inertia_kg_m2]
                            + ([model.foundation.mass_kg] * 2 if model.foundation is not None else []))
        self.gyro = np.zeros((n, n))
        self.gyro[2, 3], self.gyro[3, 2] = g.polar_inertia_kg_m2, -g.polar_inertia_kg_m2
        r = np.asarray(model.coefficients, dtype=float)
        kb, cb = r[:4].reshape(2, 2), r[4:].reshape(2, 2)
        self.relative = [self.point(s) - self.housing() for s in g.bearing_positions_m]
        self.stiffness = sum(t.T @ kb @ t for t in self.relative)
        self.damping = sum(t.T @ cb @ t for t in self.relative)
        if model.foundation is not None:
            f = model.foundation
            self.stiffness[4:, 4:] += f.stiffness_n_per_m * np.eye(2)
            self.damping[4:, 4:] += f.damping_n_s_per_m * np.eye(2)
        relative_probes = model.foundation is not None and model.foundation.probes_relative
        self.probe_map = np.vstack([self.point(s) - (self.housing() if relative_probes else 0.0)
                                    for s in g.probe_positions_m])  # rows xp1 yp1 xp2 yp2
        self.impact_map = self.point(g.impact_position_m).T
        self.harmonics: dict[int, np.ndarray] = {}
        for fo in model.forces:
            vec = self.point(fo.axial_position_m).T @ np.array([fo.fx_n, fo.fy_n], dtype=complex)
            self.harmonics[fo.harmonic] = self.harmonics.get(fo.harmonic, 0) + vec
        static = self.harmonics.get(0, np.zeros(n, dtype=complex)).real.copy()
        static[1] -= g.mass_kg * model.gravity_m_s2
        if model.foundation is not None:
            static[5] -= model.foundation.mass_kg * model.gravity_m_s2
        self.harmonics[0] = static.astype(complex)
        self.mass_inverse = np.linalg.inv(self.mass)
        self.damping_total = self.damping + model.speed_rad_s * self.gyro

    def point(self, s: float) -> np.ndarray:
        """(2, n): ``[x(s), y(s)]`` of the shaft from ``q``."""
        row = np.zeros((2, self.n))
        row[0, 0], row[0, 2], row[1, 1], row[1, 3] = 1.0, s, 1.0, s
        return row

    def housing(self) -> np.ndarray | float:
        if self.n == 4:
            return 0.0
        row = np.zeros((2, self.n))
        row[0, 4], row[1, 5] = 1.0, 1.0
        return row

    def state_matrix(self) -> np.ndarray:
        """First-order ``[q, q']' = A [q, q']`` of the linear part."""
        n = self.n
        a = np.zeros((2 * n, 2 * n))
        a[:n, n:] = np.eye(n)
        a[n:, :n] = -self.mass_inverse @ self.stiffness
        a[n:, n:] = -self.mass_inverse @ self.damping_total
        return a


def nonlinear_bearing_force(nl: BearingNonlinearity, d: np.ndarray) -> np.ndarray:
    """Extra force on the shaft (2,) at relative displacement ``d`` (2,)."""
    r = math.hypot(d[0], d[1])
    f = -nl.cubic_n_per_m3 * r * r * d
    if r > nl.clearance_m:
        f = f - nl.contact_stiffness_n_per_m * (r - nl.clearance_m) * d / r
    return f


def static_equilibrium(model: TrueModel, mats: Matrices | None = None) -> np.ndarray:
    """``q0`` (n,) where the static loads (gravity, ``h = 0`` forces) meet the bearings' linear and nonlinear
    restoring forces: ``K q0 - sum_b T_b' f_nl(T_b q0) = F0``, by Newton's method from the linear solution."""
    mats = mats or Matrices(model)
    f0 = mats.harmonics[0].real
    q = np.linalg.solve(mats.stiffness, f0)
    nl = model.nonlinearity
    if nl is None:
        return q
    for _ in range(100):
        resid = mats.stiffness @ q - sum(tb.T @ nonlinear_bearing_force(nl, tb @ q) for tb in mats.relative) - f0
        jac = mats.stiffness + sum(tb.T @ bearing_tangent_stiffness(nl, tb @ q) @ tb for tb in mats.relative)
        step = np.linalg.solve(jac, resid)
        q = q - step
        if np.max(np.abs(step)) < 1e-15 + 1e-12 * np.max(np.abs(q)):
            return q
    raise RuntimeError("static_equilibrium: Newton's method did not converge")


def bearing_tangent_stiffness(nl: BearingNonlinearity, d: np.ndarray, step_m: float = 1e-9) -> np.ndarray:
    """(2, 2) restoring stiffness ``-d f_nl / d d`` of the nonlinear bearing force at displacement ``d``
    (central differences)."""
    out = np.zeros((2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = step_m
        out[:, j] = -(nonlinear_bearing_force(nl, d + e) - nonlinear_bearing_force(nl, d - e)) / (2 * step_m)
    return out


def tangent_coefficients(model: TrueModel) -> np.ndarray:
    """(2, 8) the bearing coefficients linearized about the static equilibrium, per bearing: ``K`` plus the
    nonlinear force's tangent stiffness there (damping unchanged). This is what a linear model fitted to the
    motion about the operating point can see (the probes' DC is unknown); without a nonlinearity both rows
    are the model's coefficients."""
    mats = Matrices(model)
    r = np.asarray(model.coefficients, dtype=float)
    rows = np.tile(r, (len(mats.relative), 1))
    if model.nonlinearity is None:
        return rows
    q0 = static_equilibrium(model, mats)
    for b, tb in enumerate(mats.relative):
        rows[b, :4] += bearing_tangent_stiffness(model.nonlinearity, tb @ q0).ravel()
    return rows


def periodic_start(model: TrueModel, mats: Matrices, angle_rad: float) -> np.ndarray:
    """State ``[q, q']`` of the periodic solution of the linear part at shaft angle ``angle_rad``."""
    w = model.speed_rad_s
    q = np.linalg.solve(mats.stiffness, mats.harmonics[0].real)
    v = np.zeros(mats.n)
    for h, p in mats.harmonics.items():
        if h == 0:
            continue
        dyn = -(h * w) ** 2 * mats.mass + 1j * h * w * mats.damping_total + mats.stiffness
        x = np.linalg.solve(dyn, p) * np.exp(1j * h * angle_rad)
        q, v = q + x.real, v + (1j * h * w * x).real
    return np.concatenate([q, v])


class Trajectory:
    """The integrated motion: ``states(t)`` from the dense output of each segment (held before the start)."""

    def __init__(self, t0: float, segments: list, initial: np.ndarray) -> None:
        self.t0, self.segments, self.initial = t0, segments, initial

    def states(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = np.empty((t.size, self.initial.size))
        out[:] = self.initial
        for a, b, sol in self.segments:
            sel = (t >= a) & (t <= b)
            if np.any(sel):
                out[sel] = sol(t[sel]).T
        return out


def integrate(model: TrueModel, t0: float, t_end: float, *, steady: bool, rtol: float = 1e-9,
              initial: np.ndarray | None = None) -> tuple[Trajectory, Matrices]:
    """Integrate ``model`` from ``t0`` to ``t_end`` (s); ``steady`` starts on the linear periodic solution."""
    mats = Matrices(model)
    n = mats.n
    angle = model.angle_of_time or (lambda t: model.speed_rad_s * t)
    harmonics = [(h, p) for h, p in mats.harmonics.items() if h != 0]
    static = mats.harmonics[0].real
    nl = model.nonlinearity
    rel = mats.relative
    minv, kk, cc = mats.mass_inverse, mats.stiffness, mats.damping_total
    imp_map = mats.impact_map

    def rhs(t, y, pulses):
        q, v = y[:n], y[n:]
        th = angle(t)
        force = static.copy()
        for h, p in harmonics:
            force += (p * complex(math.cos(h * th), math.sin(h * th))).real
        for p in pulses:
            shape = float(p.profile(np.array([t]))[0])
            if shape:
                force += imp_map @ np.array([p.force_x_n * shape, p.force_y_n * shape])
        if nl is not None:
            for tb in rel:
                force += tb.T @ nonlinear_bearing_force(nl, tb @ q)
        return np.concatenate([v, minv @ (force - cc @ v - kk @ q)])

    if initial is not None:
        y0 = np.asarray(initial, dtype=float)
    elif steady:
        y0 = periodic_start(model, mats, angle(t0))
    else:
        y0 = np.zeros(2 * n)
    edges = sorted({t0, t_end, *[e for p in model.impacts for e in (p.start_s, p.start_s + p.duration_s)
                                 if t0 < e < t_end]})
    scale = max(float(np.max(np.abs(y0[:n]))) if np.any(y0[:n]) else 0.0, 1e-5)
    atol = np.concatenate([np.full(n, scale * 1e-9), np.full(n, scale * model.speed_rad_s * 1e-9 + 1e-12)])
    segments, y = [], y0
    for a, b in zip(edges[:-1], edges[1:]):
        active = [p for p in model.impacts if p.start_s < b and p.start_s + p.duration_s > a]
        h_max = min((p.duration_s / 8 for p in active), default=np.inf)
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=rtol, atol=atol, dense_output=True,
                        args=(active,), max_step=h_max)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed on [{a:.6f}, {b:.6f}] s: {sol.message}")
        segments.append((a, b, sol.sol))
        y = sol.y[:, -1]
    return Trajectory(t0, segments, y0), mats


def mechanical_energy(mats: Matrices, states: np.ndarray) -> np.ndarray:
    """Kinetic plus elastic energy ``v'Mv/2 + q'Kq/2`` (J) of the linear part, per row of ``states``."""
    n = mats.n
    q, v = states[:, :n], states[:, n:]
    k_sym = 0.5 * (mats.stiffness + mats.stiffness.T)
    return 0.5 * np.einsum("ij,jk,ik->i", v, mats.mass, v) + 0.5 * np.einsum("ij,jk,ik->i", q, k_sym, q)


def linear_eigenvalues(model: TrueModel) -> np.ndarray:
    """Eigenvalues of the linear part (rad/s); the model is stable when all real parts are negative."""
    return np.linalg.eigvals(Matrices(model).state_matrix())


def settle_time_s(model: TrueModel, decay: float = 1e-4, cap_s: float = 0.6) -> float:
    """Time for the slowest linear mode to decay by ``decay`` (capped)."""
    lam = linear_eigenvalues(model)
    slowest = float(np.min(-lam.real))
    return cap_s if slowest <= 0 else min(cap_s, math.log(1 / decay) / slowest)
