# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Coupled flexible-shaft effect: an equivalent Euler-Bernoulli beam on the fitted bearings.

The rig file gives only the rotor's mass ``m``, transverse and polar inertias about the
mass center ``I_t, I_p`` and the axial stations. The *equivalent rotor* built from them
(:func:`equivalent_beam`) is

* a uniform beam over ``[-L/2, L/2]`` about the mass center, ``L = 2 max|station|``,
  mass per length ``mu``, bending stiffness ``EI`` (the fitted parameter), no section
  rotary inertia;
* a rigid disk at the mass center: mass ``m_d``, polar inertia ``I_p`` (all of it) and
  transverse inertia ``I_d = I_p / 2`` (thin disk, capped at ``I_t / 2``);
* ``mu = 12 (I_t - I_d) / L^3`` and ``m_d = m - mu L``, so the mass, the mass center and
  the transverse inertia equal the rig's. When ``m_d`` would be negative (the mass lies
  further out than a uniform beam over the stations) the beam is lengthened to
  ``L = sqrt(12 (I_t - I_d) / m)`` and ``m_d = 0``.

Finite elements (Friswell et al., *Dynamics of Rotating Machines*, Sec. 5.4; Neisi et al.
2022, Eqs. 1-5): cubic Hermite elements with slope coordinates, identical in the x-z and
y-z planes, ``M q'' + (C + Omega G) q' + K q = F``; the disk's gyroscopic term couples
the planes' slopes at the center, ``G[phi_x, phi_y] = -G[phi_y, phi_x] = I_p``.

Reduction (Neisi et al., Appendix A, with residual flexibility; Craig & Bampton style):
the generalized coordinates are ``g = [z, e]`` with ``z = [x1, y1, x2, y2]`` the rigid
motion in the bearing coordinates of Miller & Howard's Eq. 2 (exact rigid shapes of the
beam) and ``e`` elastic Ritz coordinates per plane: the lowest ``N_FREE_MODES``
free-free bending modes plus the inertia-relief residual-flexibility shapes of a unit
force at each bearing, ``sum_{k > N} phi_k phi_k(s_b) / lambda_k``, mass-normalized and
orthogonalized. Their beam stiffness is ``EI diag(lambda)`` and they carry modal damping
``2 zeta sqrt(EI lambda)``. The bearings act on the *flexible* shaft at the bearing
stations, ``d_b = z + W e``, with the same 8 coefficients as Eq. 2::

    M_g g'' + (C_b + C_e + Omega G_g) g' + (K_b + K_e) g = B_f f,
    M_g = diag(M, I),  K_b = [I W]^T S [I W],  C_b = [I W]^T C [I W],  K_e = diag(0, EI Lambda),

``M, G, S, C`` those of Miller & Howard Eqs. 2-4. Forces ``f``: the known imbalances
(point forces at their stations, as in Eq. 5) and the measured impact at its station.
Output: the absolute shaft displacement and velocity at the probes, ``y = P z + E_p e``.
As ``EI -> inf`` the elastic coordinates vanish and the model is Eq. 2 itself
(:func:`flexible_response` with ``stiffness_scale=inf`` is exactly the rigid model).

Parameters: ``log10`` of the first pinned-pinned bending frequency of the equivalent
beam (pins at the bearings; ``EI`` follows as ``(2 pi f)^2 / lambda_pp(EI=1)``) and
``log10`` of the modal damping ratio. The effect's basis is ``y_flex(r, nl) - y_nom(r)``,
an offset re-simulated at the coefficients being fitted.

A second, *decoupled* variant shares the effect (:class:`FlexibleShaft`): one pinned-pinned
mode between the bearings, ``q'' + 2 zeta w q' + w^2 q = sum_i phi(s_i) f_i / m_b``,
``y += phi(s_p) q`` (the form of the own blind generator, :mod:`rotor_estimator.bench.effect_sim`),
selected by the range of ``nl[0]``, so the multi-start fit picks whichever has the lower cost.
It has one linear parameter ``1 / m_b`` (zero column in the coupled variant), so the effect
counts 3 parameters in either variant.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar

import numpy as np
import scipy.linalg

from rotor_estimator.core.config import RigConfig
from rotor_estimator.core.flexible.fe_rotor import hermite_shape, subdivide
from rotor_estimator.core.model import (RotorMatrices, damping_matrix, point_force_weights, rotor_matrices,
                                        stiffness_matrix)
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.context import FitContext
from rotor_estimator.diagnosis.effects.base import Effect, rotating_mass_force
from rotor_estimator.diagnosis.linsim import simulate_linear

#: Free-free bending modes kept per plane (plus one residual-flexibility shape per bearing).
N_FREE_MODES = 3
#: Minimum number of beam elements over the equivalent beam.
MIN_ELEMENTS = 16
#: ``nl[0]`` of the decoupled variant is this plus ``log10`` of its frequency (the coupled one has none).
DECOUPLED_OFFSET = 10.0
#: ``nl[0]`` below this is the coupled variant (between the ranges each variant is held at its bound).
VARIANT_SWITCH = 8.0
#: Frequency ranges: coupled pinned-pinned frequency up to this times the sample rate (stiff shafts still
#: shift the rigid modes), the decoupled mode up to this times the sample rate (below Nyquist).
COUPLED_MAX_FACTOR = 10.0
DECOUPLED_MAX_FACTOR = 0.45
MIN_FREQUENCY_HZ = 20.0


@dataclass(frozen=True)
class EquivalentBeam:
    """Uniform beam over ``[-L/2, L/2]`` plus a rigid disk at the mass center (module docstring)."""

    length_m: float
    mass_per_length_kg_m: float
    disk_mass_kg: float
    disk_transverse_inertia_kg_m2: float
    polar_inertia_kg_m2: float
    nodes_m: np.ndarray

    @property
    def mass_kg(self) -> float:
        return self.mass_per_length_kg_m * self.length_m + self.disk_mass_kg

    @property
    def transverse_inertia_kg_m2(self) -> float:
        return self.mass_per_length_kg_m * self.length_m ** 3 / 12.0 + self.disk_transverse_inertia_kg_m2


def rig_stations(rig: RigConfig) -> np.ndarray:
    """Axial stations of the rig file: bearings, probes, impact and imbalance planes (m)."""
    s = [rig.bearing1_position_m, rig.bearing2_position_m, rig.probe1_position_m, rig.probe2_position_m,
         rig.impact_position_m] + [u.axial_position_m for u in rig.imbalances]
    return np.array(s, dtype=float)


def equivalent_beam(rig: RigConfig, min_elements: int = MIN_ELEMENTS) -> EquivalentBeam:
    """The uniform beam plus central disk matching ``m``, ``I_t`` and ``I_p`` of the rig (module docstring)."""
    m, it, ip = rig.shaft_mass_kg, rig.transverse_inertia_kg_m2, rig.polar_inertia_kg_m2
    stations = rig_stations(rig)
    i_disk = min(0.5 * ip, 0.5 * it)
    it_beam = it - i_disk
    length = 2.0 * float(np.max(np.abs(stations)))
    mu = 12.0 * it_beam / length ** 3
    m_disk = m - mu * length
    if m_disk < 0.0:
        length = float(np.sqrt(12.0 * it_beam / m))
        mu, m_disk = m / length, 0.0
    nodes = subdivide(np.concatenate([[-length / 2, 0.0, length / 2], stations]), length / min_elements)
    return EquivalentBeam(length, mu, m_disk, i_disk, ip, nodes)


def plane_matrices(beam: EquivalentBeam) -> tuple[np.ndarray, np.ndarray]:
    """Mass and unit-``EI`` stiffness of one bending plane, DOFs ``[w_0, w'_0, w_1, w'_1, ...]``.

    Euler-Bernoulli cubic Hermite element (Friswell et al., Eqs. 5.68 and 5.71 with no shear
    and no rotary inertia) plus the disk's mass and transverse inertia at the center node.
    """
    nodes = beam.nodes_m
    n = 2 * nodes.size
    m_mat, k_mat = np.zeros((n, n)), np.zeros((n, n))
    mu = beam.mass_per_length_kg_m
    for e in range(nodes.size - 1):
        ll = nodes[e + 1] - nodes[e]
        ke = np.array([[12, 6 * ll, -12, 6 * ll], [6 * ll, 4 * ll ** 2, -6 * ll, 2 * ll ** 2],
                       [-12, -6 * ll, 12, -6 * ll], [6 * ll, 2 * ll ** 2, -6 * ll, 4 * ll ** 2]]) / ll ** 3
        me = mu * ll / 420.0 * np.array([[156, 22 * ll, 54, -13 * ll], [22 * ll, 4 * ll ** 2, 13 * ll, -3 * ll ** 2],
                                         [54, 13 * ll, 156, -22 * ll], [-13 * ll, -3 * ll ** 2, -22 * ll, 4 * ll ** 2]])
        sl = slice(2 * e, 2 * e + 4)
        k_mat[sl, sl] += ke
        m_mat[sl, sl] += me
    c = 2 * int(np.argmin(np.abs(nodes)))
    m_mat[c, c] += beam.disk_mass_kg
    m_mat[c + 1, c + 1] += beam.disk_transverse_inertia_kg_m2
    return m_mat, k_mat


def plane_row(nodes_m: np.ndarray, station_m: float, slope: bool = False) -> np.ndarray:
    """Row giving the displacement (or slope) at a station by cubic Hermite interpolation."""
    e, shape = hermite_shape(nodes_m, station_m, slope)
    row = np.zeros(2 * nodes_m.size)
    row[2 * e:2 * e + 4] = shape
    return row


@dataclass(frozen=True)
class ReducedShaft:
    """Per-rig constants of the reduced model (independent of ``EI``, damping and the coefficients).

    ``basis`` (n_plane, 2 + n_e): rigid shapes of bearing coordinates 1, 2 then the elastic
    Ritz shapes; ``elastic_eigenvalues`` (n_e,) at ``EI = 1``; ``row(s)`` maps a station to
    its generalized row (2 + n_e) in one plane; ``mass_rigid`` the beam's mass matrix on the
    rigid shapes (equal to Eq. 3's); ``pinned_eigenvalue`` / ``free_eigenvalue``: first
    pinned-pinned (pins at the bearings) / free-free bending eigenvalue ``omega^2`` at ``EI = 1``.
    """

    beam: EquivalentBeam
    mats: RotorMatrices
    basis: np.ndarray
    elastic_eigenvalues: np.ndarray
    mass_rigid: np.ndarray
    center_slope: np.ndarray
    pinned_eigenvalue: float
    free_eigenvalue: float

    @property
    def n_elastic(self) -> int:
        return self.elastic_eigenvalues.size

    def row(self, station_m: float) -> np.ndarray:
        return plane_row(self.beam.nodes_m, station_m) @ self.basis


def reduce_shaft(rig: RigConfig, n_free_modes: int = N_FREE_MODES) -> ReducedShaft:
    """Rigid shapes, free-free modes and bearing residual flexibility of the equivalent beam."""
    beam = equivalent_beam(rig)
    nodes = beam.nodes_m
    m_mat, k_mat = plane_matrices(beam)
    n = m_mat.shape[0]
    b1, b2 = rig.bearing1_position_m, rig.bearing2_position_m
    rigid = np.zeros((n, 2))
    for i, s in enumerate(nodes):
        w1, w2 = point_force_weights(rig, s)
        rigid[2 * i] = (w1, w2)
        rigid[2 * i + 1] = (-1.0 / (b2 - b1), 1.0 / (b2 - b1))
    lam, phi = scipy.linalg.eigh(k_mat, m_mat)
    # the two (numerically) zero eigenvalues are the rigid modes; the elastic modes are M-orthogonal to them
    lam, phi = lam[2:], phi[:, 2:]
    keep = min(n_free_modes, lam.size)
    lam_r, elastic = lam[:keep], phi[:, :keep]
    if lam.size - keep >= 2:
        bearing_rows = np.array([plane_row(nodes, b1), plane_row(nodes, b2)])
        residual = phi[:, keep:] @ ((phi[:, keep:].T @ bearing_rows.T) / lam[keep:, None])
        lam_x, psi = scipy.linalg.eigh(residual.T @ k_mat @ residual, residual.T @ m_mat @ residual)
        lam_r, elastic = np.concatenate([lam_r, lam_x]), np.hstack([elastic, residual @ psi])
    basis = np.hstack([rigid, elastic])
    # first pinned-pinned bending eigenvalue: x = 0 at both bearing nodes
    free = np.ones(n, dtype=bool)
    free[[2 * int(np.argmin(np.abs(nodes - b))) for b in (b1, b2)]] = False
    lam_pp = scipy.linalg.eigh(k_mat[np.ix_(free, free)], m_mat[np.ix_(free, free)], eigvals_only=True,
                               subset_by_index=[0, 0])[0]
    c = 2 * int(np.argmin(np.abs(nodes)))
    return ReducedShaft(beam=beam, mats=rotor_matrices(rig), basis=basis, elastic_eigenvalues=lam_r,
                        mass_rigid=rigid.T @ m_mat @ rigid, center_slope=basis[c + 1],
                        pinned_eigenvalue=float(lam_pp), free_eigenvalue=float(lam[0]))


def _plane_index(n_e: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions of the x-plane and y-plane coordinates in ``g = [x1, y1, x2, y2, e_x, e_y]``."""
    ix = np.concatenate([[0, 2], 4 + np.arange(n_e)])
    iy = np.concatenate([[1, 3], 4 + n_e + np.arange(n_e)])
    return ix, iy


@dataclass(frozen=True)
class ShaftModel:
    """Speed-independent generalized matrices ``(M_g^-1, C, K, G)`` and the input/output maps."""

    minv: np.ndarray
    c_mat: np.ndarray
    k_mat: np.ndarray
    g_mat: np.ndarray
    force_input: np.ndarray   # (n_g, m) generalized force per point-force column
    probe_rows: np.ndarray    # (4, n_g)

    def state_matrix(self, speed_rad_s: float) -> np.ndarray:
        """``A`` for the state ``[g', g]`` (the ordering of Eq. 2's ``[v, z]``)."""
        n = self.minv.shape[0]
        a = np.zeros((2 * n, 2 * n))
        a[:n, :n] = -self.minv @ (self.c_mat + speed_rad_s * self.g_mat)
        a[:n, n:] = -self.minv @ self.k_mat
        a[n:, :n] = np.eye(n)
        return a

    def input_matrix(self) -> np.ndarray:
        return np.vstack([self.minv @ self.force_input, np.zeros_like(self.force_input)])

    def output_matrix(self) -> np.ndarray:
        """Rows 0-3 probe displacements, rows 4-7 probe velocities (like ``models.rigid_output``)."""
        n = self.minv.shape[0]
        c = np.zeros((8, 2 * n))
        c[:4, n:] = self.probe_rows
        c[4:, :n] = self.probe_rows
        return c


def force_stations(rig: RigConfig) -> list[float]:
    """Stations of the point-force columns: each imbalance plane, then the impact."""
    return [u.axial_position_m for u in rig.imbalances] + [rig.impact_position_m]


def shaft_model(rig: RigConfig, red: ReducedShaft, coefficients: np.ndarray, stiffness_scale: float,
                damping_ratio: float) -> ShaftModel:
    """Generalized matrices of the module docstring for ``EI = stiffness_scale`` (``inf``: rigid, Eq. 2)."""
    mats = red.mats
    n_e = red.n_elastic if np.isfinite(stiffness_scale) else 0
    ix, iy = _plane_index(n_e)
    ng = 4 + 2 * n_e
    cols = slice(0, 2 + n_e)
    g_mat = np.zeros((ng, ng))
    t = red.center_slope[cols]
    g_mat[np.ix_(ix, iy)] = red.beam.polar_inertia_kg_m2 * np.outer(t, t)
    g_mat[np.ix_(iy, ix)] = -red.beam.polar_inertia_kg_m2 * np.outer(t, t)
    g_mat[:4, :4] = mats.gyro_matrix
    hb = np.zeros((4, ng))
    for j, s in enumerate((rig.bearing1_position_m, rig.bearing2_position_m)):
        row = red.row(s)[cols]
        hb[2 * j, ix], hb[2 * j + 1, iy] = row, row
    hb[:, :4] = np.eye(4)  # the rigid shapes are the bearing coordinates
    k_mat = hb.T @ stiffness_matrix(coefficients) @ hb
    c_mat = hb.T @ damping_matrix(coefficients) @ hb
    if n_e:
        lam = stiffness_scale * red.elastic_eigenvalues
        k_mat[4:, 4:] += np.diag(np.tile(lam, 2))
        c_mat[4:, 4:] += np.diag(np.tile(2.0 * damping_ratio * np.sqrt(lam), 2))
    stations = force_stations(rig)
    b_f = np.zeros((ng, 2 * len(stations)))
    for j, s in enumerate(stations):
        row = red.row(s)[cols]
        b_f[ix, 2 * j], b_f[iy, 2 * j + 1] = row, row
    probes = np.zeros((4, ng))
    for j, s in enumerate((rig.probe1_position_m, rig.probe2_position_m)):
        row = red.row(s)[cols]
        probes[2 * j, ix], probes[2 * j + 1, iy] = row, row
    minv = np.eye(ng)
    minv[:4, :4] = mats.mass_inverse
    return ShaftModel(minv, c_mat, k_mat, g_mat, b_f, probes)


def point_forces(ctx: FitContext) -> tuple[np.ndarray, np.ndarray]:
    """Smooth (imbalances) and step (impact) point forces (N, 2 n_imbalances + 2), columns ``fx, fy`` per station.

    Each mass ``m r`` at phase ``phi`` pushes with ``m r (w^2 cos a + w' sin a, w^2 sin a - w' cos a)``,
    ``a = angle + phi`` (Eq. 5 before the lever rule).
    """
    rig = ctx.rig
    n_u = len(rig.imbalances)
    smooth = np.zeros((ctx.t_s.size, 2 * n_u + 2))
    for i, u in enumerate(rig.imbalances):
        smooth[:, 2 * i], smooth[:, 2 * i + 1] = rotating_mass_force(ctx, u.phase_rad, u.moment_kg_m)
    step = np.zeros_like(smooth)
    step[:, 2 * n_u:] = ctx.impact_force_n
    return smooth, step


def flexible_response(ctx: FitContext, red: ReducedShaft, coefficients: np.ndarray, stiffness_scale: float,
                      damping_ratio: float) -> np.ndarray:
    """Probe displacements and velocities (N, 8) of the coupled flexible model (exact discretization)."""
    model = shaft_model(ctx.rig, red, coefficients, stiffness_scale, damping_ratio)
    smooth, step = point_forces(ctx)
    out, _ = simulate_linear(model.state_matrix, model.input_matrix(), model.output_matrix(), ctx.period_s,
                             ctx.schedule, ctx.shaft.angle_rad, smooth, step)
    return out


@lru_cache(maxsize=8)
def _reduced_shaft_of(rig: RigConfig) -> ReducedShaft:
    return reduce_shaft(rig)


def reduced_shaft(ctx: FitContext) -> ReducedShaft:
    """The rig's reduced shaft, cached per rig (the joint refit builds a fresh context per trial)."""
    return _reduced_shaft_of(ctx.rig)


def decoupled_column(ctx: FitContext, frequency_hz: float, damping_ratio: float) -> np.ndarray:
    """Probe output (N, 4) of one pinned-pinned bending mode of unit modal mass, decoupled from Eq. 2.

    ``q'' + 2 zeta w q' + w^2 q = sum_i phi(s_i) f_i``, ``y = phi(s_probe) q``, ``phi`` the first
    pinned-pinned shape between the bearings (:func:`rotor_estimator.diagnosis.models.mode_shape`): the
    variant of the effect that matches the decoupled generator of :mod:`rotor_estimator.bench.effect_sim`.
    """
    rig = ctx.rig
    smooth, step = point_forces(ctx)
    phi = models.mode_shape(rig, np.array(force_stations(rig)))
    to_modal = np.zeros((smooth.shape[1], 2))
    to_modal[0::2, 0], to_modal[1::2, 1] = phi, phi
    b = np.vstack([np.eye(2), np.zeros((2, 2))])
    c = np.hstack([np.zeros((2, 2)), np.eye(2)])
    a = models.modal_state_matrix(frequency_hz, damping_ratio)
    q, _ = simulate_linear(lambda w: a, b, c, ctx.period_s, ctx.schedule, ctx.shaft.angle_rad, smooth @ to_modal,
                           step @ to_modal)
    p1, p2 = models.mode_shape(rig, rig.probe1_position_m), models.mode_shape(rig, rig.probe2_position_m)
    return np.column_stack([p1 * q[:, 0], p1 * q[:, 1], p2 * q[:, 0], p2 * q[:, 1]])


def variant(nl: np.ndarray, sample_rate_hz: float) -> tuple[bool, float]:
    """``(coupled, frequency_hz)`` encoded in ``nl[0]`` (see :class:`FlexibleShaft`)."""
    if nl[0] < VARIANT_SWITCH:
        return True, float(10 ** min(nl[0], np.log10(COUPLED_MAX_FACTOR * sample_rate_hz)))
    return False, float(10 ** min(max(nl[0] - DECOUPLED_OFFSET, np.log10(MIN_FREQUENCY_HZ)),
                                  np.log10(DECOUPLED_MAX_FACTOR * sample_rate_hz)))


@dataclass(frozen=True)
class FlexibleShaft(Effect):
    """Shaft flexibility: the equivalent beam on the fitted bearings, coupled to the rigid modes (gyroscopic).

    Two variants share the effect, selected by ``nl[0]`` and so by the fit's cost (every start
    of both is tried): *coupled* (:func:`flexible_response`, ``nl[0] = log10 f_pp`` the
    equivalent beam's first pinned-pinned frequency; its linear column is zero) and
    *decoupled* (:func:`decoupled_column`, ``nl[0] = DECOUPLED_OFFSET + log10 f``, linear gain
    the inverse modal mass). Both count 3 parameters.
    """

    name: ClassVar[str] = "shaft_bending"
    kind: ClassVar[str] = "structural"
    starts_from_prior: ClassVar[bool] = True
    responses: ClassVar[dict[str, str]] = {
        "speed_change": "1X grows towards the bending critical speed",
        "housing_sensor": "housing still; the shaft bends between the probes",
    }
    description: ClassVar[str] = ("shaft flexibility: equivalent flexible beam on the fitted bearings "
                                  "(coupled), or one decoupled bending mode")
    nl_names: ClassVar[tuple[str, ...]] = ("log10_frequency_hz", "log10_damping_ratio")

    def lin_names(self, ctx):
        return ("inverse_modal_mass_per_kg",)

    def nl_grid(self, ctx):
        coupled = np.linspace(np.log10(60.0), np.log10(4.0 * ctx.sample_rate_hz), 20)
        decoupled = DECOUPLED_OFFSET + np.linspace(np.log10(60.0), np.log10(0.4 * ctx.sample_rate_hz), 16)
        return [np.array([lf, np.log10(z)]) for lf in np.concatenate([coupled, decoupled]) for z in (0.01, 0.05)]

    def nl_bounds(self, ctx):
        hi = DECOUPLED_OFFSET + np.log10(DECOUPLED_MAX_FACTOR * ctx.sample_rate_hz)
        return np.array([np.log10(MIN_FREQUENCY_HZ), -3.0]), np.array([hi, -0.3])

    def refine_starts(self, ctx):
        # about the nominal fit's coefficients (dragged to absorb the flexibility) the coupled basin is
        # narrow in frequency: starts a factor 1.5 apart over the plausible range
        coupled = [np.log10(f) for f in (100.0, 150.0, 225.0, 340.0, 510.0, 760.0, 1150.0, 1700.0)]
        decoupled = [DECOUPLED_OFFSET + np.log10(f) for f in (80.0, 120.0, 180.0, 270.0, 400.0, 600.0, 900.0)]
        return [np.array([lf, np.log10(0.02)]) for lf in coupled + decoupled]

    @staticmethod
    def stiffness(red: ReducedShaft, frequency_hz: float) -> float:
        """``EI`` (N m^2) whose first pinned-pinned bending frequency is ``frequency_hz``."""
        return (2 * np.pi * frequency_hz) ** 2 / red.pinned_eigenvalue

    def basis(self, ctx, nl):
        coupled, f = variant(nl, ctx.sample_rate_hz)
        n = ctx.t_s.size
        if not coupled:
            return None, decoupled_column(ctx, f, 10 ** nl[1])[:, :, None]
        red = reduced_shaft(ctx)
        y = flexible_response(ctx, red, ctx.coefficients, self.stiffness(red, f), 10 ** nl[1])[:, :4]
        if not np.all(np.isfinite(y)):
            y = np.full_like(y, np.nan)
        return y - ctx.y_nom_m, np.zeros((n, 4, 1))

    def physical(self, nl, lin):
        coupled = nl[0] < VARIANT_SWITCH
        f = 10 ** (nl[0] if coupled else nl[0] - DECOUPLED_OFFSET)
        out = {"bending_frequency_hz": float(f), "bending_damping_ratio": float(10 ** nl[1]),
               "coupled": float(coupled), "inverse_modal_mass_per_kg": float(lin[0]) if len(lin) else 0.0}
        if not coupled and out["inverse_modal_mass_per_kg"]:  # the decoupled mode's own modal mass
            out["modal_mass_kg"] = 1.0 / out["inverse_modal_mass_per_kg"]
        return out
