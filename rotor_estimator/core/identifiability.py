# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Which coefficients the data actually received determine, and how well.

Input: the Fisher information the data carried about the coefficients (from a batch
fit, from :mod:`.information`, or recovered from a running EKF as
``F = P_r^-1 - P0_r^-1``: the filter's posterior information minus its prior
information, :func:`information_from_filter`) and the current estimates. Output, per
coefficient: the predicted standard deviation (the Cramér-Rao bound of these data:
``sqrt((F^-1)_ii)``, infinite along directions the data do not inform) and a status:

* ``determined``: predicted std <= ``determined_rel`` (default 10%) of the scale;
* ``weakly determined``: <= ``weak_rel`` (default 25%; the same threshold as the
  reproduction's "NOT DETERMINED" flag);
* ``not determined``: above that, or no information at all. Such a coefficient is
  printed and published without a value (``value_for_display`` is None): the prior
  or a wandering filter state must not be read as a measurement.

The predicted std is a local (linearized) bound evaluated at the current estimates.
When some coefficient is not determined, that linearization point is itself unknown
by more than the linear range (on the seed's imbalance-only case the bound of cyy is
6% at a wandering estimate but 31% at the truth), so no coefficient is then called
``determined``: those that would be are downgraded to ``weakly determined``.

The scale of a coefficient is ``max(|estimate|, floor)``, the floor being
``floor_fraction`` (default 5%) of the mean magnitude of the direct coefficients of
the same kind (kxx, kyy for stiffness; cxx, cyy for damping), so that a small
cross-coupled term is judged against the bearing's own size rather than against
zero. Cost: one eigen-decomposition of an 8x8 (or 16x16) matrix, microseconds,
cheap enough to refresh every 0.5 s of streaming data.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rotor_estimator.core.config import COEFFICIENT_NAMES
from rotor_estimator.core.errors import ConfigError
from rotor_estimator.core.fisher import bound

DETERMINED = "determined"
WEAK = "weakly determined"
NOT_DETERMINED = "not determined"
LABEL_RULE = "determined <= 10 %, weakly determined <= 25 %, above: not determined (no value shown)"
LABEL_FLOOR_NOTE = "5 % of the direct coefficients of the same kind"


@dataclass(frozen=True)
class Thresholds:
    """Relative-std thresholds (fractions) and the floor fraction, see the module docstring."""

    determined_rel: float = 0.10
    weak_rel: float = 0.25
    floor_fraction: float = 0.05

    def __post_init__(self) -> None:
        if not 0 < self.determined_rel <= self.weak_rel:
            raise ConfigError("identifiability.thresholds: need 0 < determined_rel <= weak_rel")
        if not 0 <= self.floor_fraction < 1:
            raise ConfigError("identifiability.thresholds.floor_fraction: must be in [0, 1)")


@dataclass(frozen=True)
class CoefficientStatus:
    name: str
    estimate: float
    predicted_std: float
    relative_std: float
    status: str
    downgraded: bool = False  # would be "determined" on its own std, but another coefficient is not

    @property
    def value_for_display(self) -> float | None:
        """The estimate, or None when the data do not determine it."""
        return None if self.status == NOT_DETERMINED else self.estimate

    def as_dict(self) -> dict:
        return {"coefficient": self.name, "estimate": self.value_for_display, "predicted_std": self.predicted_std,
                "relative_std": self.relative_std, "status": self.status}


@dataclass(frozen=True)
class IdentifiabilityReport:
    entries: tuple[CoefficientStatus, ...]

    @property
    def all_determined(self) -> bool:
        return all(e.status == DETERMINED for e in self.entries)

    def with_status_override(self, status: str) -> "IdentifiabilityReport":
        """The same report with every determined or weak status replaced (e.g. under a model mismatch,
        where the information says nothing about the error)."""
        from dataclasses import replace

        return IdentifiabilityReport(tuple(e if e.status == NOT_DETERMINED else replace(e, status=status,
                                                                                         downgraded=False)
                                           for e in self.entries))

    def names_with(self, status: str) -> list[str]:
        return [e.name for e in self.entries if e.status == status]

    def format(self, posterior_std: np.ndarray | None = None, units: tuple[str, ...] | None = None) -> str:
        """The coefficient table every command prints (replay, identify): the label is decided by
        the printed ``rel.`` column alone (see :data:`LABEL_RULE`), a not-determined coefficient
        shows ``--``. ``posterior_std`` (a filter's, prior included) is printed beside it."""
        post = "" if posterior_std is None else f"{'std (filter)':>13}"
        lines = [f"{'coef':<6}{'estimate':>13}{post}{'std (data)':>12}{'rel.':>9}  {'unit':<7} status"]
        for i, e in enumerate(self.entries):
            val = "--" if e.value_for_display is None else f"{e.estimate:.6g}"
            rel = "inf" if not np.isfinite(e.relative_std) else f"{100 * e.relative_std:.3g} %"
            unit = units[i] if units is not None else ""
            extra = "" if posterior_std is None else f"{posterior_std[i]:>13.4g}"
            note = "*" if e.downgraded else ""
            lines.append(f"{e.name:<6}{val:>13}{extra}{e.predicted_std:>12.4g}{rel:>9}  {unit:<7} {e.status}{note}")
        if any(e.downgraded for e in self.entries):
            lines.append("* determined on its own rel., but another coefficient is not determined, so this local "
                         "bound is itself uncertain")
        lines.append(f"status from rel. = std (data) / |estimate| (floor: {LABEL_FLOOR_NOTE}):\n  {LABEL_RULE}")
        lines.append("std (data): the Cramer-Rao bound of these data alone"
                     + ("" if posterior_std is None else "; std (filter): the filter's, prior included")
                     + ".\n  No std includes calibration errors (probe or hammer sensitivity) or model errors.")
        bad = self.names_with(NOT_DETERMINED)
        if bad:
            lines.append(f"NOT DETERMINED by the data so far: {', '.join(bad)} (no value reported; add excitation: "
                         f"a coast-down/run-up through the rigid-body modes or impacts, see `rotor-estimator plan`)")
        return "\n".join(lines)


def _scales(estimates: np.ndarray, floor_fraction: float) -> np.ndarray:
    est = np.abs(np.asarray(estimates, dtype=float))
    scale = est.copy()
    for start in range(0, est.size, 8):  # per bearing block of 8 (kxx kxy kyx kyy cxx cxy cyx cyy)
        blk = est[start:start + 8]
        if blk.size < 8:
            break
        k_floor = floor_fraction * 0.5 * (blk[0] + blk[3])
        c_floor = floor_fraction * 0.5 * (blk[4] + blk[7])
        scale[start:start + 4] = np.maximum(blk[:4], k_floor)
        scale[start + 4:start + 8] = np.maximum(blk[4:8], c_floor)
    return np.where(scale > 0, scale, np.inf)


def report_from_std(std: np.ndarray, estimates: np.ndarray, names: tuple[str, ...] | None = None,
                    thresholds: Thresholds = Thresholds()) -> IdentifiabilityReport:
    """Report from predicted standard deviations (e.g. a CRLB) and estimates."""
    est = np.asarray(estimates, dtype=float)
    names = names or (COEFFICIENT_NAMES if est.size == 8 else tuple(f"{n}_{b}" for b in (1, 2)
                                                                   for n in COEFFICIENT_NAMES))
    rel = np.asarray(std, dtype=float) / _scales(est, thresholds.floor_fraction)
    rel = np.where(np.isfinite(est), rel, np.inf)
    out = []
    any_undetermined = bool(np.any(~(rel <= thresholds.weak_rel)))
    for n, e, s, r in zip(names, est, std, rel):
        status = (DETERMINED if r <= thresholds.determined_rel else WEAK if r <= thresholds.weak_rel
                  else NOT_DETERMINED)
        downgraded = status == DETERMINED and any_undetermined
        if downgraded:
            status = WEAK
        out.append(CoefficientStatus(n, float(e), float(s), float(r), status, downgraded))
    return IdentifiabilityReport(tuple(out))


def report_from_information(information: np.ndarray, estimates: np.ndarray, names: tuple[str, ...] | None = None,
                            thresholds: Thresholds = Thresholds()) -> IdentifiabilityReport:
    """Report from the Fisher information of ``[coefficients, nuisance...]`` (coefficients first)."""
    n = np.asarray(estimates).size
    return report_from_std(bound(np.asarray(information, dtype=float), n).std, estimates, names, thresholds)


def information_from_filter(posterior_cov: np.ndarray, prior_cov: np.ndarray) -> np.ndarray:
    """Information the data carried about the coefficients, from a Kalman filter:
    ``P^-1 - P0^-1`` (linearized Bayes: posterior information = prior + data), symmetrized
    and with negative eigenvalues (round-off where the data added nothing) set to 0."""
    p = np.asarray(posterior_cov, dtype=float)
    p0 = np.asarray(prior_cov, dtype=float)
    d = np.sqrt(np.diag(p0))
    # work in units of the prior std so both inverses are well scaled
    pn = p / np.outer(d, d)
    p0n = p0 / np.outer(d, d)
    info_n = np.linalg.inv(0.5 * (pn + pn.T)) - np.linalg.inv(0.5 * (p0n + p0n.T))
    w, v = np.linalg.eigh(0.5 * (info_n + info_n.T))
    info_n = (v * np.clip(w, 0, None)) @ v.T
    return info_n / np.outer(d, d)


def report_from_filter(posterior_cov: np.ndarray, prior_cov: np.ndarray, estimates: np.ndarray,
                       names: tuple[str, ...] | None = None,
                       thresholds: Thresholds = Thresholds()) -> IdentifiabilityReport:
    """Report for a running EKF (e.g. :class:`rotor_estimator.core.ekf.StreamingEKF`): pass its
    ``coefficient_covariance``, the prior covariance ``diag(initial_coefficient_std^2)``
    and its ``coefficients``. Cheap (8x8 algebra): meant to be refreshed every ~0.5 s."""
    info = information_from_filter(posterior_cov, prior_cov)
    return report_from_information(info, estimates, names, thresholds)


def report_for_result(result, thresholds: Thresholds = Thresholds(), prior_cov: np.ndarray | None = None):
    """Report for an :class:`~.result.IdentificationResult` (constant coefficients): from its
    Fisher information when it has one, else from its covariance and ``prior_cov``."""
    nc = result.model.n_coefficients
    if result.information is not None:
        return report_from_information(result.information, result.theta[:nc], result.model.coefficient_names,
                                       thresholds)
    if prior_cov is None:
        return report_from_std(result.std[:nc], result.theta[:nc], result.model.coefficient_names, thresholds)
    return report_from_filter(result.covariance[:nc, :nc], prior_cov[:nc, :nc], result.theta[:nc],
                              result.model.coefficient_names, thresholds)
