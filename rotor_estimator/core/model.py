# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Rigid rotor on two identical linear bearings (Miller & Howard, Eqs. 1-6).

Coordinates ``z = [x1, y1, x2, y2]`` are the shaft displacements at the two bearing
centers (m), x horizontal, y vertical. The shaft spins about the +axial direction,
that is from +x toward +y; the imbalance forcing turns the same way, and the
gyroscopic matrix ``G`` below has the sign that makes forward whirl stiffen
with speed (errata 6 of the seeds README; checked by a test on the Campbell
diagram).

Neglected, and why: the ``Ip * dOmega/dt`` tilt term (below 1e-3 of the bearing
tilt stiffness for any sweep this package simulates), gravity (a static offset that
the probes' DC removal or the estimator's state absorbs), and shaft flexibility.

The state used by the filters follows Eq. 7: ``s = [v (4), z (4), r (8)]`` where
``v = dz/dt`` and ``r`` holds the coefficients in this package's order
``kxx kxy kyx kyy cxx cxy cyx cyy``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rotor_estimator.core.config import BearingCoefficients, RigConfig


@dataclass(frozen=True)
class RotorMatrices:
    """The constant matrices of Eq. 2-3 and the input maps of Eqs. 5-6 for one rig.

    Shapes: ``mass_matrix``, ``gyro_matrix`` (4, 4); ``imbalance_input`` (4, n_imbalances)
    maps each imbalance plane's force to generalized forces; ``impact_input`` (4,) maps
    a point force at the impact station; ``probe_from_bearing`` (4, 4) maps ``z`` to
    probe readings ``[xp1, yp1, xp2, yp2]``; ``bearing_from_probe`` is its inverse
    (Eq. 6 with the 1/(p1+p2) factor of errata 2).
    """

    mass_matrix: np.ndarray
    mass_inverse: np.ndarray
    gyro_matrix: np.ndarray
    imbalance_moments_kg_m: np.ndarray
    imbalance_phases_rad: np.ndarray
    imbalance_input: np.ndarray
    impact_input: np.ndarray
    probe_from_bearing: np.ndarray
    bearing_from_probe: np.ndarray


def point_force_weights(rig: RigConfig, axial_position_m: float) -> tuple[float, float]:
    """Share of a lateral point force at ``axial_position_m`` felt by bearing 1 and 2.

    Virtual work of a force on the rigid shaft (the lever factors of Eq. 5):
    ``w1 = (b2 - s)/L``, ``w2 = (s - b1)/L``.
    """
    b1, b2 = rig.bearing1_position_m, rig.bearing2_position_m
    span = b2 - b1
    return (b2 - axial_position_m) / span, (axial_position_m - b1) / span


def _lateral_map(w1: float, w2: float) -> np.ndarray:
    """4x2 map from a force (fx, fy) with weights (w1, w2) into ``[x1, y1, x2, y2]``."""
    return np.array([[w1, 0.0], [0.0, w1], [w2, 0.0], [0.0, w2]])


def mass_matrix(rig: RigConfig) -> np.ndarray:
    """M of Eq. 3 (kg): rigid-body translation plus tilt inertia in bearing coordinates."""
    m, it = rig.shaft_mass_kg, rig.transverse_inertia_kg_m2
    l1, l2 = -rig.bearing1_position_m, rig.bearing2_position_m
    span = l1 + l2
    a, b, c = m * l2 ** 2 + it, m * l1 * l2 - it, m * l1 ** 2 + it
    return np.array([[a, 0, b, 0], [0, a, 0, b], [b, 0, c, 0], [0, b, 0, c]], dtype=float) / span ** 2


def gyro_matrix(rig: RigConfig) -> np.ndarray:
    """G of Eq. 3 (kg, multiplied by the speed in rad/s); skew-symmetric, so it does no work."""
    ip, span = rig.polar_inertia_kg_m2, rig.bearing_span_m
    return np.array([[0, 1, 0, -1], [-1, 0, 1, 0], [0, -1, 0, 1], [1, 0, -1, 0]], dtype=float) * ip / span ** 2


def stiffness_matrix(coefficients: np.ndarray) -> np.ndarray:
    """S of Eq. 4 from ``r = [kxx kxy kyx kyy ...]``: the same 2x2 block at both bearings."""
    k = np.asarray(coefficients, dtype=float)[:4].reshape(2, 2)
    out = np.zeros((4, 4))
    out[:2, :2] = k
    out[2:, 2:] = k
    return out


def damping_matrix(coefficients: np.ndarray) -> np.ndarray:
    """C of Eq. 4 from ``r = [... cxx cxy cyx cyy]``."""
    c = np.asarray(coefficients, dtype=float)[4:8].reshape(2, 2)
    out = np.zeros((4, 4))
    out[:2, :2] = c
    out[2:, 2:] = c
    return out


def probe_from_bearing(rig: RigConfig) -> np.ndarray:
    """Map ``z = [x1, y1, x2, y2]`` to probe readings ``[xp1, yp1, xp2, yp2]`` (rigid shaft)."""
    rows = []
    for s in (rig.probe1_position_m, rig.probe2_position_m):
        w1, w2 = point_force_weights(rig, s)  # same linear interpolation weights
        rows.append(_lateral_map(w1, w2).T)
    return np.vstack(rows)


def bearing_from_probe(rig: RigConfig) -> np.ndarray:
    """Eq. 6 with errata 2: bearing displacements from probe readings.

    ``x1 = ((p2 + l1) xp1 + (p1 - l1) xp2) / (p1 + p2)`` and likewise for the others.
    """
    b1, b2 = rig.bearing1_position_m, rig.bearing2_position_m
    s1, s2 = rig.probe1_position_m, rig.probe2_position_m
    out = np.zeros((4, 4))
    for row, b in ((0, b1), (2, b2)):
        # linear interpolation of the probe line at axial station b
        w_probe1, w_probe2 = (s2 - b) / (s2 - s1), (b - s1) / (s2 - s1)
        out[row, 0], out[row, 2] = w_probe1, w_probe2          # x
        out[row + 1, 1], out[row + 1, 3] = w_probe1, w_probe2  # y
    return out


def rotor_matrices(rig: RigConfig) -> RotorMatrices:
    """All constant matrices for ``rig``."""
    mass = mass_matrix(rig)
    moments = np.array([u.moment_kg_m for u in rig.imbalances], dtype=float)
    phases = np.array([u.phase_rad for u in rig.imbalances], dtype=float)
    imbalance_weights = np.array([point_force_weights(rig, u.axial_position_m) for u in rig.imbalances],
                                 dtype=float).reshape(-1, 2)
    w1i, w2i = point_force_weights(rig, rig.impact_position_m)
    return RotorMatrices(
        mass_matrix=mass,
        mass_inverse=np.linalg.inv(mass),
        gyro_matrix=gyro_matrix(rig),
        imbalance_moments_kg_m=moments,
        imbalance_phases_rad=phases,
        imbalance_input=imbalance_weights.T.copy(),  # (2, n): rows are bearing 1, bearing 2 weights
        impact_input=np.array([w1i, w2i]),
        probe_from_bearing=probe_from_bearing(rig),
        bearing_from_probe=bearing_from_probe(rig),
    )


def imbalance_force(mats: RotorMatrices, angle_rad: float | np.ndarray, speed_rad_s: float | np.ndarray,
                    accel_rad_s2: float | np.ndarray = 0.0) -> np.ndarray:
    """Generalized imbalance force ``[F_x1, F_y1, F_x2, F_y2]`` (N), Eq. 5.

    ``angle_rad`` is the measured shaft angle (0 at the keyphasor mark), not ``Omega t``:
    with a varying speed the force follows the tachometer. Each mass ``m_i r_i`` at
    phase ``phi_i`` pushes with ``m r (w^2 cos a + dw/dt sin a, w^2 sin a - dw/dt cos a)``,
    ``a = angle + phi_i``. Broadcasts over arrays of angles (last axis gets the 4 forces).
    """
    angle = np.asarray(angle_rad, dtype=float)[..., None] + mats.imbalance_phases_rad
    w2 = np.asarray(speed_rad_s, dtype=float)[..., None] ** 2
    acc = np.asarray(accel_rad_s2, dtype=float)[..., None]
    cos_a, sin_a = np.cos(angle), np.sin(angle)
    fx = mats.imbalance_moments_kg_m * (w2 * cos_a + acc * sin_a)
    fy = mats.imbalance_moments_kg_m * (w2 * sin_a - acc * cos_a)
    w1, w2_ = mats.imbalance_input
    return np.stack([fx @ w1, fy @ w1, fx @ w2_, fy @ w2_], axis=-1)


def impact_force(mats: RotorMatrices, force_n: np.ndarray) -> np.ndarray:
    """Generalized force of an impact ``(fx, fy)`` (N) at the rig's impact station (Eq. 5)."""
    f = np.asarray(force_n, dtype=float)
    w1, w2 = mats.impact_input
    return np.stack([w1 * f[..., 0], w1 * f[..., 1], w2 * f[..., 0], w2 * f[..., 1]], axis=-1)


def state_matrix(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float) -> np.ndarray:
    """8x8 system matrix of Eq. 2 in first-order form, state ``[v, z]`` (Eq. 7 ordering)."""
    c_total = damping_matrix(coefficients) + speed_rad_s * mats.gyro_matrix
    a = np.zeros((8, 8))
    a[:4, :4] = -mats.mass_inverse @ c_total
    a[:4, 4:] = -mats.mass_inverse @ stiffness_matrix(coefficients)
    a[4:, :4] = np.eye(4)
    return a


def eigenfrequencies(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float) -> np.ndarray:
    """Damped natural frequencies (rad/s, positive imaginary parts) sorted ascending."""
    eig = np.linalg.eigvals(state_matrix(mats, coefficients, speed_rad_s))
    return np.sort(eig.imag[eig.imag > 0])


def whirl_modes(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float) -> list[tuple[float, float, str]]:
    """(frequency rad/s, damping ratio, 'forward'|'backward') for each mode of Eq. 2.

    Whirl direction from the bearing-1 orbit of the eigenvector: forward when the
    orbit turns from +x toward +y, the sense of the shaft's spin.
    """
    eigvals, eigvecs = np.linalg.eig(state_matrix(mats, coefficients, speed_rad_s))
    out = []
    for lam, vec in zip(eigvals, eigvecs.T):
        if lam.imag <= 0:
            continue
        z = vec[4:]
        # choose the bearing with the larger motion
        i = 0 if abs(z[0]) + abs(z[1]) >= abs(z[2]) + abs(z[3]) else 2
        x, y = z[i], z[i + 1]
        # x = Re(X e^{jwt}), y = Re(Y e^{jwt}); a forward circle (cos, sin) has Y = -jX,
        # so |X + jY| is the forward part and |X - jY| the backward part.
        forward = abs(x + 1j * y) > abs(x - 1j * y)
        out.append((float(lam.imag), float(-lam.real / abs(lam)), "forward" if forward else "backward"))
    return sorted(out)


def coefficients_array(coefficients: BearingCoefficients | np.ndarray) -> np.ndarray:
    """Coerce to the 8-vector ``[kxx kxy kyx kyy cxx cxy cyx cyy]``."""
    if isinstance(coefficients, BearingCoefficients):
        return coefficients.as_array()
    arr = np.asarray(coefficients, dtype=float)
    if arr.shape != (8,):
        raise ValueError(f"expected 8 coefficients, got shape {arr.shape}")
    return arr
