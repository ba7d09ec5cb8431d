# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Fisher information and Cramér-Rao bounds of the generalized model, for one or several records.

For Gaussian probe noise ``y_k = Hp z_k(p) + v_k``, ``v_k ~ N(0, R)``, the information is
``F = sum_k J_k^T R^-1 J_k`` with ``J_k = Hp dz_k/dp`` (same construction as
:mod:`rotor_estimator.core.crlb`, here for the generalized parameterization of
:mod:`.problem`). Parameters per record: the motion state at its first sample (8,
always a nuisance); shared by all records: ``theta`` and, when unknown, the rotor's
imbalance ``b`` (a nuisance). Each record's initial state is eliminated by the Schur
complement, then the records' information is summed (they are independent).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Iterable

import numpy as np

from rotor_estimator.identification import passes
from rotor_estimator.core.fisher import eliminate_nuisance
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays

if TYPE_CHECKING:
    from rotor_estimator.identification.scenarios import SimulatedRecord


def record_information(arrays: RigArrays, model: CoefficientModel, record: Record, theta: np.ndarray,
                       imbalance_kg_m: np.ndarray, q0: np.ndarray, *, estimate_imbalance: bool,
                       noise_std_m: float) -> np.ndarray:
    """Full information of ``[q0 (8), theta, b?]`` from one record (noise-free response from ``q0``)."""
    rinv = np.full(4, 1.0 / noise_std_m)
    _, _, fim, _ = passes.sensitivity_pass(
        np.asarray(q0, dtype=float), np.ascontiguousarray(theta, dtype=float),
        np.ascontiguousarray(imbalance_kg_m, dtype=float), estimate_imbalance, record.dt_s, record.angle_rad,
        record.speed_rad_s, record.accel_rad_s2, record.force_gen_n, np.zeros((0, 4)), record.use, arrays.hp, rinv,
        model.dmap(), model.powers(), model.speed_ref_rad_s, model.speed_scale_rad_s, arrays.minv, arrays.gyro,
        arrays.wimb)
    return fim


def design_information(arrays: RigArrays, model: CoefficientModel, records: Iterable[SimulatedRecord],
                       theta: np.ndarray, *,
                       estimate_imbalance: bool, noise_std_m: float) -> np.ndarray:
    """Summed information of ``[theta, b?]`` over simulated records (each record's initial
    state eliminated). ``records``: :class:`~.scenarios.SimulatedRecord` items."""
    total = None
    for sr in records:
        fim = record_information(arrays, model, sr.record, theta, sr.imbalance_true_kg_m, sr.q0_true,
                                 estimate_imbalance=estimate_imbalance, noise_std_m=noise_std_m)
        part = eliminate_nuisance(fim, 8)
        total = part if total is None else total + part
    return total
