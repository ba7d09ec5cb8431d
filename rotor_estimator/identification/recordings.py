# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Identify the coefficients of recordings as ``rotor-estimator identify`` does (the core of ``identify``
and of ``batch identify``): trial weights, the fit, its identifiability report, the fit quality against
the chi-square band, and the imbalance per plane.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


def parse_trial_weight(text: str):
    """``MASS_G,RADIUS_MM,PLANE,ANGLE_DEG`` (e.g. ``2.0,30,1,90``: 2 g at 30 mm in imbalance plane 1,
    90 degrees from the keyphasor mark) or ``none``; a :class:`TrialWeight` or None."""
    import math

    from rotor_estimator.core.errors import InputError
    from rotor_estimator.identification.scenarios import TrialWeight

    if text.strip().lower() == "none":
        return None
    try:
        mass_g, radius_mm, plane, angle_deg = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--trial-weight: expected MASS_G,RADIUS_MM,PLANE,ANGLE_DEG (e.g. 2.0,30,1,90) or none, "
                         f"got {text!r}") from None
    if not (mass_g > 0 and radius_mm > 0 and plane in (1, 2)):
        raise InputError(f"--trial-weight {text!r}: mass and radius must be > 0 and the plane 1 or 2")
    return TrialWeight(mass_g * 1e-3, radius_mm * 1e-3, math.radians(angle_deg), int(plane) - 1)


def imbalance_rows(b_kg_m, std_kg_m=None) -> list[dict]:
    """Imbalance ``[a1, b1, a2, b2]`` (kg*m) per plane as g*mm at an angle from the keyphasor mark."""
    import numpy as np

    b = np.asarray(b_kg_m, float).reshape(-1, 2)
    rows = []
    for k, (a, q) in enumerate(b):
        row = {"plane": k + 1, "g_mm": float(np.hypot(a, q) * 1e6), "angle_deg": float(np.degrees(np.arctan2(q, a)))}
        if std_kg_m is not None:
            s = np.asarray(std_kg_m, float).reshape(-1, 2)[k]
            row["std_g_mm"] = float(np.sqrt(np.mean(s ** 2)) * 1e6)
        rows.append(row)
    return rows


def fit_quality(res, noise_std_m: float, n_used: int) -> dict:
    """Residual RMS against the probe noise and the mean normalized squared residual with its chi-square
    band (output-error analogue of the filter NIS): a fit outside it is a model mismatch."""
    from scipy.stats import chi2

    cost = res.extra.get("cost")
    if cost is None or n_used <= 0:
        return {}
    # chi-square with 4 n - (fitted parameters) degrees of freedom; two-sided at p = 0.001. The batch fit
    # uses the simulator's own model, so no tolerance is added (a 10-degree imbalance phase error gives 4.43
    # against a band of 3.79-4.22 on the seed case, a clean record 3.96)
    dof = 4 * n_used - int(res.extra.get("n_parameters", 0))
    mean = cost / n_used
    band = (float(chi2.ppf(5e-4, dof) / n_used), float(chi2.isf(5e-4, dof) / n_used))
    mismatch = not band[0] <= mean <= band[1]
    return {"residual_rms_m": float(res.extra["noise_std_estimate_m"]), "noise_std_m": float(noise_std_m),
            "residual_over_noise": float(res.extra["noise_std_estimate_m"] / noise_std_m),
            "normalized_squared_residual_mean": float(mean), "band": band, "samples": int(n_used),
            "model_mismatch": bool(mismatch)}


@dataclass
class IdentifyOutcome:
    """What ``identify`` computes for one set of records (8 or 16 coefficients, no speed polynomial):
    the fit, its identifiability report, the fit quality and the imbalance per plane."""

    res: Any
    report: Any
    quality: dict
    imbalance: list[dict]
    records: int
    trial_specs: list[str]

    def as_dict(self) -> dict:
        """The ``--json`` output of ``identify``."""
        res = self.res
        return {"method": res.method, "runtime_s": res.runtime_s, "converged": res.converged,
                "records": self.records, "trial_weights": self.trial_specs,
                "coefficients": [e.as_dict() for e in self.report.entries],
                "imbalance_estimated": res.imbalance_estimated, "imbalance": self.imbalance,
                "imbalance_kg_m": res.imbalance_kg_m.tolist(), "fit": self.quality}


def identify_recordings(rig_file, recordings: list, *, method: str = "auto", bearings: int = 8,
                        estimate_imbalance: bool = True, trial_specs: list[str] | None = None) -> IdentifyOutcome:
    """Fit the coefficients (and the imbalance) to ``recordings`` fitted together, as ``identify`` does."""
    import numpy as np

    from rotor_estimator.core.errors import InputError
    from rotor_estimator.core.identifiability import report_for_result
    from rotor_estimator.identification.methods import identify
    from rotor_estimator.identification.problem import CoefficientModel, RigArrays, record_from_recording

    rig = rig_file.rig
    trial_specs = list(trial_specs or [])
    if trial_specs and len(trial_specs) != len(recordings):
        raise InputError(f"--trial-weight: give one per --bag (or none at all): {len(recordings)} bag(s), "
                         f"{len(trial_specs)} trial weight(s); use 'none' for a record without one")
    arrays = RigArrays.build(rig)
    weights = [parse_trial_weight(t) for t in trial_specs] or [None] * len(recordings)
    trials = [np.zeros(arrays.n_imbalance) if w is None else w.imbalance_vector(arrays.n_imbalance // 2)
              for w in weights]
    records = [record_from_recording(rig, r) for r in recordings]
    model = CoefficientModel(identical_bearings=bearings == 8)
    check_stable_start(rig, rig_file.estimator.initial_coefficients.as_array(), records)
    res = identify(arrays, rig_file.estimator, records, method=method, model=model,
                   estimate_imbalance=estimate_imbalance, trial_imbalance_kg_m=trials)
    prior = None
    if res.information is None:
        std0 = rig_file.estimator.initial_coefficient_std.as_array()
        prior = np.diag(np.tile(std0, res.model.n_coefficients // 8) ** 2)
    report = report_for_result(res, prior_cov=prior)
    n_used = sum(int(r.use.sum()) for r in records)
    quality = fit_quality(res, rig_file.estimator.measurement_noise_std_m, n_used)
    nb = arrays.n_imbalance
    b_std = None
    if res.imbalance_estimated and res.information is not None:
        from rotor_estimator.core.fisher import bound

        b_std = np.sqrt(np.clip(np.diag(bound(res.information, res.information.shape[0]).covariance), 0, None))[
            res.model.n_theta:res.model.n_theta + nb]
    return IdentifyOutcome(res, report, quality, imbalance_rows(res.imbalance_kg_m, b_std), len(records),
                           trial_specs)


def check_stable_start(rig, coefficients, records) -> None:
    """A start from unstable coefficients cannot be fitted: say so, naming the coefficients (and not
    the imbalance, which cannot destabilize a linear rotor)."""
    import numpy as np

    from rotor_estimator.core.errors import InputError
    from rotor_estimator.core.model import rotor_matrices, state_matrix

    mats = rotor_matrices(rig)
    speeds = np.concatenate([r.speed_rad_s[r.use] for r in records]) if records else np.zeros(0)
    if speeds.size == 0:
        return
    for w in (float(speeds.min()), float(speeds.max())):
        growth = float(np.max(np.linalg.eigvals(state_matrix(mats, coefficients, w)).real))
        if growth > 0:
            raise InputError(f"the rig file's initial coefficients are unstable at {w * 60 / (2 * np.pi):.0f} rpm "
                             f"(a mode grows at {growth:.3g} 1/s), so no fit can start from them: check "
                             f"estimator.initial_coefficients (signs of the cross-coupled terms, damping > 0)")
