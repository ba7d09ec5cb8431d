"""Fisher information and Cramér-Rao bounds of the generalized model, for one or several records.

For Gaussian probe noise ``y_k = Hp z_k(p) + v_k``, ``v_k ~ N(0, R)``, the information is
``F = sum_k J_k^T R^-1 J_k`` with ``J_k = Hp dz_k/dp`` (same construction as
:mod:`rotor_estimator.crlb`, here for the generalized parameterization of
:mod:`.problem`). Parameters per record: the motion state at its first sample (8,
always a nuisance); shared by all records: ``theta`` and, when unknown, the rotor's
imbalance ``b`` (a nuisance). Each record's initial state is eliminated by the Schur
complement, then the records' information is summed (they are independent).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _kernel
from .problem import CoefficientModel, Record, RigArrays


def record_information(arrays: RigArrays, model: CoefficientModel, record: Record, theta: np.ndarray,
                       imbalance_kg_m: np.ndarray, q0: np.ndarray, *, estimate_imbalance: bool,
                       noise_std_m: float) -> np.ndarray:
    """Full information of ``[q0 (8), theta, b?]`` from one record (noise-free response from ``q0``)."""
    rinv = np.full(4, 1.0 / noise_std_m)
    _, _, fim, _ = _kernel.sensitivity_pass(
        np.asarray(q0, dtype=float), np.ascontiguousarray(theta, dtype=float),
        np.ascontiguousarray(imbalance_kg_m, dtype=float), estimate_imbalance, record.dt_s, record.angle_rad,
        record.speed_rad_s, record.accel_rad_s2, record.force_gen_n, np.zeros((0, 4)), record.use, arrays.hp, rinv,
        model.dmap(), model.powers(), model.speed_ref_rad_s, model.speed_scale_rad_s, arrays.minv, arrays.gyro,
        arrays.wimb)
    return fim


def eliminate_nuisance(fim: np.ndarray, n_nuisance: int = 8) -> np.ndarray:
    """Information of the trailing parameters with the first ``n_nuisance`` unknown (Schur complement)."""
    a = fim[:n_nuisance, :n_nuisance]
    b = fim[:n_nuisance, n_nuisance:]
    d = fim[n_nuisance:, n_nuisance:]
    scale = np.sqrt(np.clip(np.diag(a), 1e-300, None))
    an = a / np.outer(scale, scale)
    bn = b / scale[:, None]
    return d - bn.T @ np.linalg.lstsq(an, bn, rcond=1e-13)[0]


@dataclass(frozen=True)
class Bound:
    """Cramér-Rao bound of ``theta`` (the leading block of the parameters).

    ``covariance`` (ntheta, ntheta) and ``std`` (ntheta,), SI; ``std`` is ``inf`` for a
    parameter in the span of (numerically) zero information.
    """

    covariance: np.ndarray
    std: np.ndarray
    fisher: np.ndarray

    def relative(self, values: np.ndarray, floor: np.ndarray | None = None) -> np.ndarray:
        scale = np.abs(np.asarray(values, dtype=float))
        if floor is not None:
            scale = np.maximum(scale, floor)
        return self.std / scale


def bound(fisher: np.ndarray, n_theta: int, *, rel_tol: float = 1e-13) -> Bound:
    """Invert ``fisher`` (parameters ``[theta, nuisance...]``) and keep the ``theta`` block.

    Scaled symmetric eigen-decomposition; directions with eigenvalue below ``rel_tol``
    of the largest are treated as carrying no information (infinite bound).
    """
    scale = np.sqrt(np.clip(np.diag(fisher), 1e-300, None))
    fn = fisher / np.outer(scale, scale)
    w, v = np.linalg.eigh(fn)
    tol = max(w.max(), 1e-300) * rel_tol
    good = w > tol
    cov_n = (v[:, good] / w[good]) @ v[:, good].T
    cov = cov_n / np.outer(scale, scale)
    unidentified = (v[:, ~good] ** 2).sum(axis=1) > 1e-6
    c = cov[:n_theta, :n_theta]
    std = np.sqrt(np.clip(np.diag(c), 0, None))
    std[unidentified[:n_theta]] = np.inf
    return Bound(covariance=c, std=std, fisher=fisher)


def design_information(arrays: RigArrays, model: CoefficientModel, records, theta: np.ndarray, *,
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
