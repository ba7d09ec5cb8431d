# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Finite-element rotor: Timoshenko shaft elements, rigid disks, linear bearings and
rigid pedestals (Eqs. 1-8 of Neisi et al.; element matrices of Nelson & McVaugh /
Friswell et al., *Dynamics of Rotating Machines*, ch. 5).

Degrees of freedom. Each shaft node has ``[x, y, phi_x, phi_y]`` where ``phi_x`` and
``phi_y`` are the cross-section rotations expressed as slopes (``phi_x ~ dx/dz``,
``phi_y ~ dy/dz``). With slope coordinates the bending matrices of the x-z and y-z
planes are identical. Pedestal DOFs follow the shaft DOFs: ``[x, y]`` and, when their
inertia is > 0, ``yaw`` (tilt of the x-z plane) and ``pitch`` (tilt of the y-z plane).

Equation of motion (Eq. 1): ``M q'' + (C + Omega G) q' + K q = F``. ``G`` is
skew-symmetric; for a disk ``Id phi_x'' + Omega Ip phi_y' = Q_x`` and
``Id phi_y'' - Omega Ip phi_x' = Q_y`` (spin from +x toward +y), which raises the
forward whirl frequency with speed (errata 6 of the seeds README; tested).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rotor_estimator.core.flexible.description import RotorDescription

__all__ = ["FERotor", "assemble", "timoshenko_element", "shear_coefficient", "mesh_nodes",
           "hermite_row", "hermite_shape", "subdivide", "DOF_PER_NODE"]

DOF_PER_NODE = 4
_PLANE_X = np.array([0, 2, 4, 6])  # [x1, phi_x1, x2, phi_x2] within an element's 8 DOFs
_PLANE_Y = np.array([1, 3, 5, 7])


def shear_coefficient(poisson_ratio: float, inner_diameter_m: float, outer_diameter_m: float) -> float:
    """Cowper's shear coefficient of a (hollow) circular section."""
    nu, m = poisson_ratio, inner_diameter_m / outer_diameter_m
    a = (1.0 + m * m) ** 2
    return 6.0 * (1.0 + nu) * a / ((7.0 + 6.0 * nu) * a + (20.0 + 12.0 * nu) * m * m)


def timoshenko_element(length_m: float, outer_diameter_m: float, inner_diameter_m: float, density_kg_m3: float,
                       youngs_modulus_pa: float, shear_modulus_pa: float, poisson_ratio: float,
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, K, G) 8x8 of one Timoshenko shaft element in ``[x1 y1 phx1 phy1 x2 y2 phx2 phy2]``.

    ``M`` includes translational and rotary inertia; ``G`` is the gyroscopic matrix per
    unit speed (multiply by Omega in rad/s). Shear parameter ``Phi = 12 E I / (k G A L^2)``.
    """
    ell, do, di, rho = length_m, outer_diameter_m, inner_diameter_m, density_kg_m3
    area = math.pi / 4.0 * (do ** 2 - di ** 2)
    inertia = math.pi / 64.0 * (do ** 4 - di ** 4)
    kappa = shear_coefficient(poisson_ratio, di, do)
    phi = 12.0 * youngs_modulus_pa * inertia / (kappa * shear_modulus_pa * area * ell ** 2)
    L, p, d = ell, phi, (1.0 + phi)
    k = youngs_modulus_pa * inertia / (d * L ** 3) * np.array([
        [12, 6 * L, -12, 6 * L],
        [6 * L, (4 + p) * L ** 2, -6 * L, (2 - p) * L ** 2],
        [-12, -6 * L, 12, -6 * L],
        [6 * L, (2 - p) * L ** 2, -6 * L, (4 + p) * L ** 2]])
    m1, m2 = 13 / 35 + 7 * p / 10 + p * p / 3, 11 / 210 + 11 * p / 120 + p * p / 24
    m3, m4 = 9 / 70 + 3 * p / 10 + p * p / 6, 13 / 420 + 3 * p / 40 + p * p / 24
    m5, m6 = 1 / 105 + p / 60 + p * p / 120, 1 / 140 + p / 60 + p * p / 120
    mt = rho * area * L / d ** 2 * np.array([
        [m1, m2 * L, m3, -m4 * L],
        [m2 * L, m5 * L ** 2, m4 * L, -m6 * L ** 2],
        [m3, m4 * L, m1, -m2 * L],
        [-m4 * L, -m6 * L ** 2, -m2 * L, m5 * L ** 2]])
    m7, m8, m9, m10 = 6 / 5, 1 / 10 - p / 2, 2 / 15 + p / 6 + p * p / 3, -1 / 30 - p / 6 + p * p / 6
    mr = rho * inertia / (L * d ** 2) * np.array([
        [m7, m8 * L, -m7, m8 * L],
        [m8 * L, m9 * L ** 2, -m8 * L, m10 * L ** 2],
        [-m7, -m8 * L, m7, -m8 * L],
        [m8 * L, m10 * L ** 2, -m8 * L, m9 * L ** 2]])
    M, K, G = np.zeros((8, 8)), np.zeros((8, 8)), np.zeros((8, 8))
    for idx in (_PLANE_X, _PLANE_Y):
        M[np.ix_(idx, idx)] = mt + mr
        K[np.ix_(idx, idx)] = k
    # polar inertia per length is 2 rho I: G couples the two planes' rotation fields
    G[np.ix_(_PLANE_X, _PLANE_Y)] = 2.0 * mr
    G[np.ix_(_PLANE_Y, _PLANE_X)] = -2.0 * mr
    return M, K, G


def mesh_nodes(rotor: RotorDescription) -> np.ndarray:
    """Axial node positions (m): section ends, every feature station, then subdivided
    so no element is longer than ``options.max_element_length_m``."""
    ends = np.concatenate([[0.0], np.cumsum([s.length_m for s in rotor.sections])])
    feats = [d.station_axial_m for d in rotor.disks] + [b.station_axial_m for b in rotor.bearings] + \
            [u.station_axial_m for u in rotor.unbalances]
    return subdivide(np.concatenate([ends, feats]), rotor.options.max_element_length_m)


def subdivide(key_points_m: np.ndarray, max_element_length_m: float) -> np.ndarray:
    """Sorted unique key points (rounded to 1e-12 m), each interval split evenly so that no
    element is longer than ``max_element_length_m``."""
    key = np.unique(np.round(np.asarray(key_points_m, dtype=float), 12))
    nodes = [key[0]]
    for a, b in zip(key[:-1], key[1:]):
        n = max(1, int(math.ceil((b - a) / max_element_length_m - 1e-9)))
        nodes.extend(a + (b - a) * np.arange(1, n + 1) / n)
    return np.array(nodes)


def hermite_shape(nodes_m: np.ndarray, station_axial_m: float, slope: bool = False) -> tuple[int, np.ndarray]:
    """Element index and the 4 cubic Hermite shape values ``[w_a, w'_a, w_b, w'_b]`` at a station
    (their axial derivative with ``slope=True``); stations outside the mesh are clipped to its ends."""
    z = float(np.clip(station_axial_m, nodes_m[0], nodes_m[-1]))
    e = int(np.clip(np.searchsorted(nodes_m, z, side="right") - 1, 0, len(nodes_m) - 2))
    L = nodes_m[e + 1] - nodes_m[e]
    s = (z - nodes_m[e]) / L
    if slope:
        return e, np.array([(-6 * s + 6 * s ** 2) / L, 1 - 4 * s + 3 * s ** 2, (6 * s - 6 * s ** 2) / L,
                            -2 * s + 3 * s ** 2])
    return e, np.array([1 - 3 * s ** 2 + 2 * s ** 3, L * (s - 2 * s ** 2 + s ** 3), 3 * s ** 2 - 2 * s ** 3,
                        L * (-s ** 2 + s ** 3)])


def hermite_row(nodes_m: np.ndarray, station_axial_m: float, direction: str, n_dof: int) -> np.ndarray:
    """Row mapping q to the lateral displacement of the shaft at any station, by cubic
    Hermite interpolation of the element's end translations and slopes (exact at nodes)."""
    e, shape = hermite_shape(nodes_m, station_axial_m)
    row = np.zeros(n_dof)
    off = 0 if direction == "x" else 1
    base = DOF_PER_NODE * e
    row[[base + off, base + 2 + off, base + 4 + off, base + 6 + off]] = shape
    return row


@dataclass(frozen=True)
class FERotor:
    """Assembled matrices (SI) of Eq. 1-5: ``M, C, K`` and ``G`` per unit speed, all (n, n).

    ``nodes_m``: axial node positions; ``n_shaft_dof = 4 * len(nodes_m)``;
    ``pedestal_dofs[i]``: DOF indices of pedestal i as a dict ``{'x','y','yaw','pitch'}``.
    ``unbalance_input`` (n, 2): generalized force for ``u = Omega^2 [cos theta, sin theta]``
    (Eq. 7), theta the shaft angle from the keyphasor mark.
    """

    rotor: RotorDescription
    nodes_m: np.ndarray
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    G: np.ndarray
    pedestal_dofs: tuple[dict[str, int], ...]
    unbalance_input: np.ndarray

    @property
    def n_dof(self) -> int:
        return self.M.shape[0]

    @property
    def n_shaft_dof(self) -> int:
        return DOF_PER_NODE * len(self.nodes_m)

    def node_index(self, station_axial_m: float) -> int:
        return int(np.argmin(np.abs(self.nodes_m - station_axial_m)))

    def shaft_row(self, station_axial_m: float, direction: str) -> np.ndarray:
        """Row giving the absolute shaft displacement at a station (m)."""
        return hermite_row(self.nodes_m, station_axial_m, direction, self.n_dof)

    def pedestal_row(self, pedestal: int, station_axial_m: float, direction: str) -> np.ndarray:
        """Row giving the absolute displacement of a pedestal's point at a station (m)."""
        row = np.zeros(self.n_dof)
        dofs = self.pedestal_dofs[pedestal]
        row[dofs[direction]] = 1.0
        tilt = "yaw" if direction == "x" else "pitch"
        if tilt in dofs:
            row[dofs[tilt]] = station_axial_m - self.rotor.pedestals[pedestal].axial_position_m
        return row


def assemble(rotor: RotorDescription) -> FERotor:
    """Global M, C, K, G of the rotor, bearings and pedestals (Eqs. 2-5 of Neisi et al.)."""
    nodes = mesh_nodes(rotor)
    n_shaft = DOF_PER_NODE * len(nodes)
    ped_dofs: list[dict[str, int]] = []
    n = n_shaft
    for p in rotor.pedestals:
        d = {"x": n, "y": n + 1}
        n += 2
        for name, inertia in (("yaw", p.yaw_inertia_kg_m2), ("pitch", p.pitch_inertia_kg_m2)):
            if inertia > 0:
                d[name] = n
                n += 1
        ped_dofs.append(d)
    M, C, K, G = (np.zeros((n, n)) for _ in range(4))
    mat = rotor.material
    ends = np.cumsum([s.length_m for s in rotor.sections])
    for e in range(len(nodes) - 1):
        mid = 0.5 * (nodes[e] + nodes[e + 1])
        sec = rotor.sections[min(int(np.searchsorted(ends, mid)), len(rotor.sections) - 1)]
        me, ke, ge = timoshenko_element(nodes[e + 1] - nodes[e], sec.outer_diameter_m, sec.inner_diameter_m,
                                        mat.density_kg_m3, mat.youngs_modulus_pa, mat.shear_modulus_pa,
                                        mat.poisson_ratio)
        sl = slice(DOF_PER_NODE * e, DOF_PER_NODE * e + 8)
        M[sl, sl] += me
        K[sl, sl] += ke
        G[sl, sl] += ge
    C[:n_shaft, :n_shaft] += rotor.options.shaft_damping_stiffness_proportional_s * K[:n_shaft, :n_shaft]
    for disk in rotor.disks:
        b = DOF_PER_NODE * int(np.argmin(np.abs(nodes - disk.station_axial_m)))
        M[b, b] += disk.mass_kg
        M[b + 1, b + 1] += disk.mass_kg
        M[b + 2, b + 2] += disk.transverse_inertia_kg_m2
        M[b + 3, b + 3] += disk.transverse_inertia_kg_m2
        G[b + 2, b + 3] += disk.polar_inertia_kg_m2
        G[b + 3, b + 2] -= disk.polar_inertia_kg_m2
    for i, p in enumerate(rotor.pedestals):
        d = ped_dofs[i]
        for key, mass, k, c in (("x", p.mass_kg, p.kxx_N_per_m, p.cxx_N_s_per_m),
                                ("y", p.mass_kg, p.kyy_N_per_m, p.cyy_N_s_per_m),
                                ("yaw", p.yaw_inertia_kg_m2, p.k_yaw_N_m_per_rad, p.c_yaw_N_m_s_per_rad),
                                ("pitch", p.pitch_inertia_kg_m2, p.k_pitch_N_m_per_rad, p.c_pitch_N_m_s_per_rad)):
            if key in d:
                M[d[key], d[key]] += mass
                K[d[key], d[key]] += k
                C[d[key], d[key]] += c
    fe = FERotor(rotor, nodes, M, C, K, G, tuple(ped_dofs), np.zeros((n, 2)))
    for brg in rotor.bearings:
        # relative motion shaft - housing: L (2, n); force on the system -L^T Kb L q
        rel = np.stack([fe.shaft_row(brg.station_axial_m, "x"), fe.shaft_row(brg.station_axial_m, "y")])
        if brg.pedestal is not None:
            pi = rotor.pedestal_index(brg.pedestal)
            rel -= np.stack([fe.pedestal_row(pi, brg.station_axial_m, "x"),
                             fe.pedestal_row(pi, brg.station_axial_m, "y")])
        kb = np.array([[brg.kxx_N_per_m, brg.kxy_N_per_m], [brg.kyx_N_per_m, brg.kyy_N_per_m]])
        cb = np.array([[brg.cxx_N_s_per_m, brg.cxy_N_s_per_m], [brg.cyx_N_s_per_m, brg.cyy_N_s_per_m]])
        K += rel.T @ kb @ rel
        C += rel.T @ cb @ rel
    for u in rotor.unbalances:
        # F_x = m r W^2 cos(theta + psi), F_y = m r W^2 sin(theta + psi)  (Eq. 7)
        mr, cp, sp = u.mass_kg * u.radius_m, math.cos(u.phase_rad), math.sin(u.phase_rad)
        fe.unbalance_input[:, 0] += mr * (cp * fe.shaft_row(u.station_axial_m, "x")
                                          + sp * fe.shaft_row(u.station_axial_m, "y"))
        fe.unbalance_input[:, 1] += mr * (-sp * fe.shaft_row(u.station_axial_m, "x")
                                          + cp * fe.shaft_row(u.station_axial_m, "y"))
    return fe
