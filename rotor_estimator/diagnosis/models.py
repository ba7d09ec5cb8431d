# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""State-space forms of the nominal rigid rotor and of its structural augmentations.

Nominal (Miller & Howard, Eq. 2 in first-order form, state ``q = [v, z]``)::

    M dv/dt = F - (C + Omega G) v - K z,    dz/dt = v,    y = H_p z   (Eq. 6, errata 2)

Pedestal augmentation (foundation flexibility): each bearing housing is a mass
``m_p`` on a spring ``k_p`` and damper ``c_p`` to ground in x and y; the bearing
force acts on the relative motion, ``f_b = K (z - z_p) + C (v - v_p)``::

    M dv/dt = F - Omega G v - f_b,    m_p dv_p/dt = f_b - k_p z_p - c_p v_p.

Two forms of the foundation (``housing_map`` ``T``, bearing-housing motion ``= T z_p``): a separate
mass under each bearing (``T = I``, ``z_p = [x1, y1, x2, y2]``) or one common mass carrying both
housings (``z_p = [x, y]``, both housings move with it); the housing equation is then
``m_p dv_p/dt = T^T f_b - k_p z_p - c_p v_p``. The probes are fixed to ground (absolute shaft
motion, ``y = H_p z``) or to the housings (relative, ``y = H_p (z - T z_p)``).

Bending-mode augmentation: one isotropic modal coordinate per direction, pinned at the
bearings, shape ``phi(s) = sin(pi (s - s_b1) / L)``, decoupled from the rigid modes::

    q_b'' + 2 zeta_b omega_b q_b' + omega_b^2 q_b = sum_i phi(s_i) f_i / m_b,   y += phi(s_probe) q_b.
"""
from __future__ import annotations

import numpy as np

from rotor_estimator.core.config import RigConfig
from rotor_estimator.core.model import (RotorMatrices, damping_matrix, point_force_weights, state_matrix,
                                        stiffness_matrix)


def rigid_state_matrix(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float) -> np.ndarray:
    """8x8 ``A`` of Eq. 2 with state ``[v, z]`` (the core's :func:`rotor_estimator.core.model.state_matrix`)."""
    return state_matrix(mats, coefficients, speed_rad_s)


def rigid_input(mats: RotorMatrices) -> np.ndarray:
    """8x4 ``B`` mapping generalized bearing-coordinate forces into ``[v, z]``."""
    return np.vstack([mats.mass_inverse, np.zeros((4, 4))])


def rigid_output(mats: RotorMatrices) -> np.ndarray:
    """8x8 output map: rows 0-3 probe displacements, rows 4-7 probe velocities."""
    c = np.zeros((8, 8))
    c[:4, 4:] = mats.probe_from_bearing
    c[4:, :4] = mats.probe_from_bearing
    return c


#: Housing maps ``T`` of the two foundation forms: a separate mass under each bearing, one common mass.
HOUSING_MAPS = {"separate": np.eye(4), "common": np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [0.0, 1.0]])}


def pedestal_state_matrix(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float, mass_kg: float,
                          stiffness_n_per_m: float, damping_n_s_per_m: float,
                          housing_map: np.ndarray | None = None) -> np.ndarray:
    """``A`` for state ``[v, z, v_p, z_p]`` (see module docstring): 16x16 with separate housings, 12x12 common."""
    t = HOUSING_MAPS["separate"] if housing_map is None else np.asarray(housing_map, float)
    nh = t.shape[1]
    k, c = stiffness_matrix(coefficients), damping_matrix(coefficients)
    minv = mats.mass_inverse
    a = np.zeros((8 + 2 * nh, 8 + 2 * nh))
    vp, zp = slice(8, 8 + nh), slice(8 + nh, 8 + 2 * nh)
    a[:4, :4] = -minv @ (c + speed_rad_s * mats.gyro_matrix)
    a[:4, 4:8] = -minv @ k
    a[:4, vp] = minv @ c @ t
    a[:4, zp] = minv @ k @ t
    a[4:8, :4] = np.eye(4)
    a[vp, :4] = t.T @ c / mass_kg
    a[vp, 4:8] = t.T @ k / mass_kg
    a[vp, vp] = -(t.T @ c @ t + damping_n_s_per_m * np.eye(nh)) / mass_kg
    a[vp, zp] = -(t.T @ k @ t + stiffness_n_per_m * np.eye(nh)) / mass_kg
    a[zp, vp] = np.eye(nh)
    return a


def pedestal_input(mats: RotorMatrices, housing_map: np.ndarray | None = None) -> np.ndarray:
    nh = 4 if housing_map is None else np.asarray(housing_map).shape[1]
    return np.vstack([mats.mass_inverse, np.zeros((4 + 2 * nh, 4))])


def pedestal_output(mats: RotorMatrices, housing_map: np.ndarray | None = None, *,
                    relative: bool = False) -> np.ndarray:
    """Rows 0-3 probe displacements, 4-7 velocities: of the shaft (absolute) or of shaft minus housing (relative)."""
    t = HOUSING_MAPS["separate"] if housing_map is None else np.asarray(housing_map, float)
    nh = t.shape[1]
    c = np.zeros((8, 8 + 2 * nh))
    c[:4, 4:8] = mats.probe_from_bearing
    c[4:, :4] = mats.probe_from_bearing
    if relative:
        c[:4, 8 + nh:] = -mats.probe_from_bearing @ t
        c[4:, 8:8 + nh] = -mats.probe_from_bearing @ t
    return c


def mode_shape(rig: RigConfig, axial_position_m: float | np.ndarray) -> np.ndarray:
    """First pinned-pinned bending shape between the bearings, 1 at mid-span."""
    s = np.asarray(axial_position_m, dtype=float)
    return np.sin(np.pi * (s - rig.bearing1_position_m) / rig.bearing_span_m)


def modal_state_matrix(frequency_hz: float, damping_ratio: float) -> np.ndarray:
    """4x4 ``A`` for ``[dq_x, dq_y, q_x, q_y]`` of one isotropic bending mode (unit modal mass)."""
    w = 2 * np.pi * frequency_hz
    a = np.zeros((4, 4))
    a[:2, :2] = -2 * damping_ratio * w * np.eye(2)
    a[:2, 2:] = -w * w * np.eye(2)
    a[2:, :2] = np.eye(2)
    return a


def point_generalized_force(rig: RigConfig, axial_position_m: float, fx_n: np.ndarray,
                            fy_n: np.ndarray) -> np.ndarray:
    """Generalized force ``[F_x1, F_y1, F_x2, F_y2]`` (N,4) of a lateral point force (Eq. 5 lever rule)."""
    w1, w2 = point_force_weights(rig, axial_position_m)
    fx, fy = np.asarray(fx_n, dtype=float), np.asarray(fy_n, dtype=float)
    return np.stack([w1 * fx, w1 * fy, w2 * fx, w2 * fy], axis=-1)
