# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""State-space forms of the nominal rigid rotor and of its structural augmentations.

Nominal (Miller & Howard, Eq. 2 in first-order form, state ``q = [v, z]``)::

    M dv/dt = F - (C + Omega G) v - K z,    dz/dt = v,    y = H_p z   (Eq. 6, errata 2)

Pedestal augmentation (foundation flexibility): each bearing housing is a mass
``m_p`` on a spring ``k_p`` and damper ``c_p`` to ground in x and y; the bearing
force acts on the relative motion, ``f_b = K (z - z_p) + C (v - v_p)``::

    M dv/dt = F - Omega G v - f_b,    m_p dv_p/dt = f_b - k_p z_p - c_p v_p.

The probes are taken as fixed to ground (absolute shaft motion).

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


def pedestal_state_matrix(mats: RotorMatrices, coefficients: np.ndarray, speed_rad_s: float, mass_kg: float,
                          stiffness_n_per_m: float, damping_n_s_per_m: float) -> np.ndarray:
    """16x16 ``A`` for state ``[v, z, v_p, z_p]`` (see module docstring)."""
    k, c = stiffness_matrix(coefficients), damping_matrix(coefficients)
    minv = mats.mass_inverse
    a = np.zeros((16, 16))
    a[:4, :4] = -minv @ (c + speed_rad_s * mats.gyro_matrix)
    a[:4, 4:8] = -minv @ k
    a[:4, 8:12] = minv @ c
    a[:4, 12:16] = minv @ k
    a[4:8, :4] = np.eye(4)
    a[8:12, :4] = c / mass_kg
    a[8:12, 4:8] = k / mass_kg
    a[8:12, 8:12] = -(c + damping_n_s_per_m * np.eye(4)) / mass_kg
    a[8:12, 12:16] = -(k + stiffness_n_per_m * np.eye(4)) / mass_kg
    a[12:16, 8:12] = np.eye(4)
    return a


def pedestal_input(mats: RotorMatrices) -> np.ndarray:
    return np.vstack([mats.mass_inverse, np.zeros((12, 4))])


def pedestal_output(mats: RotorMatrices) -> np.ndarray:
    c = np.zeros((8, 16))
    c[:4, 4:8] = mats.probe_from_bearing
    c[4:, :4] = mats.probe_from_bearing
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
