# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator identify``: the coefficients from one or several bags (or a simulated test), with the
identifiability report and the fit quality. Thin shell over :mod:`rotor_estimator.identification`;
heavy imports inside the handler."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from rotor_estimator.cli import arguments as cli_types

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


def cmd_identify(args: argparse.Namespace) -> int:
    import numpy as np

    from rotor_estimator.core.config import COEFFICIENT_UNITS, load_rig_file
    from rotor_estimator.core.errors import InputError, RotorEstimatorError
    from rotor_estimator.identification import speed_dependent as sd
    from rotor_estimator.core.identifiability import report_for_result
    from rotor_estimator.identification.methods import identify
    from rotor_estimator.identification.problem import CoefficientModel, RigArrays, record_from_recording

    rig_file = load_rig_file(args.rig)
    rig = rig_file.rig
    estimate_imbalance = not args.known_imbalance
    trial_specs = args.trial_weight or []
    if args.bag:
        from rotor_estimator.io.bags import read_input_bag

        if trial_specs and len(trial_specs) != len(args.bag):
            raise InputError(f"--trial-weight: give one per --bag (or none at all): {len(args.bag)} bag(s), "
                             f"{len(trial_specs)} trial weight(s); use 'none' for a record without one")
        recordings = [read_input_bag(b, salvage=args.salvage) for b in args.bag]
    else:
        from rotor_estimator.bench.identification import scenarios
        from rotor_estimator.core.simulator import simulate

        named = {s.scenario.name: s for s in scenarios()}
        if args.simulate not in named:
            raise RotorEstimatorError(f"--simulate: choose one of {', '.join(sorted(named))}")
        recordings = [simulate(rig, named[args.simulate].scenario, seed=args.seed).recording]
    arrays = RigArrays.build(rig)
    weights = [parse_trial_weight(t) for t in trial_specs] or [None] * len(recordings)
    trials = [np.zeros(arrays.n_imbalance) if w is None else w.imbalance_vector(arrays.n_imbalance // 2)
              for w in weights]
    records = [record_from_recording(rig, r) for r in recordings]
    record = records[0]
    if args.speed_order > 0:
        from rotor_estimator.identification.batch_ml import BatchOptions

        if len(records) > 1:
            raise InputError("--speed-order: one record at a time")
        res = sd.fit_polynomial(arrays, record, args.speed_order, rig_file.estimator.initial_coefficients.as_array(),
                                options=BatchOptions(noise_std_m=rig_file.estimator.measurement_noise_std_m,
                                                     estimate_imbalance=estimate_imbalance),
                                identical_bearings=args.bearings == 8)
    else:
        model = CoefficientModel(identical_bearings=args.bearings == 8)
        _check_stable_start(rig, rig_file.estimator.initial_coefficients.as_array(), records)
        res = identify(arrays, rig_file.estimator, records, method=args.method, model=model,
                       estimate_imbalance=estimate_imbalance, trial_imbalance_kg_m=trials)
    if args.speed_order > 0:
        speeds = np.linspace(record.speed_rad_s[record.use].min(), record.speed_rad_s[record.use].max(), 9)
        tab = sd.table(res, speeds)
        if args.json:
            print(json.dumps(tab.as_rows(), indent=1))
        else:
            print(f"Speed-dependent coefficients (order {args.speed_order}, batch ML), 95% bands:")
            print(tab.format())
        if args.plots:
            from rotor_estimator.identification.plots import coefficients_vs_speed

            path = coefficients_vs_speed(tab, Path(args.plots) / "coefficients_vs_speed.png")
            print(f"figure written to {path}", file=sys.stderr)
        return 0
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
    imbalance = imbalance_rows(res.imbalance_kg_m, b_std)
    if args.json:
        print(json.dumps({"method": res.method, "runtime_s": res.runtime_s, "converged": res.converged,
                          "records": len(records), "trial_weights": trial_specs,
                          "coefficients": [e.as_dict() for e in report.entries],
                          "imbalance_estimated": res.imbalance_estimated, "imbalance": imbalance,
                          "imbalance_kg_m": res.imbalance_kg_m.tolist(), "fit": quality}, indent=1))
        return 0
    print(f"Method: {res.method} ({res.runtime_s:.2f} s{'' if res.converged else ', NOT converged'}), "
          f"{len(records)} record(s)" + (f" with trial weights {trial_specs}" if trial_specs else ""))
    print(f"Imbalance ({'estimated' if res.imbalance_estimated else 'as stated in the rig file (--known-imbalance)'}): "
          + "; ".join(f"plane {r['plane']}: {r['g_mm']:.4g} g*mm at {r['angle_deg']:.1f} deg"
                      + (f" (+- {r['std_g_mm']:.2g} g*mm)" if "std_g_mm" in r else "") for r in imbalance))
    if quality:
        print(f"Fit: residual RMS {quality['residual_rms_m'] * 1e6:.3g} um against probe noise "
              f"{quality['noise_std_m'] * 1e6:.3g} um ({quality['residual_over_noise']:.2f}x); mean normalized squared "
              f"residual {quality['normalized_squared_residual_mean']:.3f} (consistent: {quality['band'][0]:.3f}-"
              f"{quality['band'][1]:.3f} for 4 channels)")
        if quality["model_mismatch"]:
            print("MODEL MISMATCH: the model does not explain these data to the noise level, so the coefficients "
                  "absorb what it lacks and the std below is not their error"
                  + (" (the imbalance is fixed to the rig file's: a wrong stated imbalance does this; drop "
                     "--known-imbalance)" if not res.imbalance_estimated else "")
                  + "; run `rotor-estimator diagnose` on the record")
    print("Identifiability from the Fisher information of these data:" if res.information is not None else
          "Identifiability from the filter's covariance (P^-1 - P0^-1):")
    if quality.get("model_mismatch"):
        report = report.with_status_override("not trustworthy (model mismatch)")
    print(report.format(units=tuple(COEFFICIENT_UNITS) * (res.model.n_coefficients // 8)))
    return 0


def _check_stable_start(rig, coefficients, records) -> None:
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


def add_parser(subparsers: Any) -> None:
    """The ``identify`` subcommand."""
    i = subparsers.add_parser("identify", help="identify the coefficients from a bag or a simulated test, with "
                                               "the identifiability report")
    src = i.add_mutually_exclusive_group(required=True)
    src.add_argument("--bag", type=Path, action="append",
                     help="input bag (probe, keyphasor and impact topics); repeat for several records fitted "
                          "together (batch ML)")
    i.add_argument("--salvage", action="store_true", help=cli_types.SALVAGE_HELP)
    src.add_argument("--simulate", metavar="SCENARIO",
                     help="simulate a benchmark scenario: imbalance+impact, imbalance, cd0.5, cd2, 5imp")
    i.add_argument("--seed", type=cli_types.seed, default=1)
    i.add_argument("--rig", type=Path, default=None)
    i.add_argument("--method", default="auto", help="auto (batch-ml), batch-ml, ekf+rts, ekf, ukf")
    i.add_argument("--known-imbalance", action="store_true",
                   help="fix the imbalance to the rig file's instead of estimating it (the default estimates it "
                        "with the coefficients, as `plan` assumes)")
    i.add_argument("--unknown-imbalance", action="store_true",
                   help="estimate the imbalance with the coefficients (the default; kept for old scripts)")
    i.add_argument("--trial-weight", action="append", default=None, metavar="G,MM,PLANE,DEG",
                   help="the trial weight of each --bag in order: mass g, radius mm, imbalance plane 1 or 2, angle "
                        "deg from the keyphasor mark (e.g. 2.0,30,1,90), or none")
    i.add_argument("--bearings", type=int, choices=(8, 16), default=8,
                   help="8 coefficients (identical bearings, default) or 16 (each bearing its own)")
    i.add_argument("--speed-order", type=int, default=0,
                   help="> 0: coefficients as speed polynomials of this order (prints the table)")
    i.add_argument("--report", "--plots", dest="plots", metavar="DIR", default=None,
                   help="write the coefficient-versus-speed figure into DIR (--plots: the old name)")
    i.add_argument("--json", action="store_true")
    i.set_defaults(func=cmd_identify)
