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

def cmd_identify(args: argparse.Namespace) -> int:
    import numpy as np

    from rotor_estimator.core.config import COEFFICIENT_UNITS, load_rig_file
    from rotor_estimator.core.errors import InputError, RotorEstimatorError
    from rotor_estimator.identification import speed_dependent as sd
    from rotor_estimator.identification.problem import RigArrays, record_from_recording
    from rotor_estimator.identification.recordings import identify_recordings, parse_trial_weight

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
    if args.speed_order > 0:
        from rotor_estimator.identification.batch_ml import BatchOptions

        if len(recordings) > 1:
            raise InputError("--speed-order: one record at a time")
        for t in trial_specs:  # checked as before, though a speed polynomial fits one record without them
            parse_trial_weight(t)
        arrays = RigArrays.build(rig)
        record = record_from_recording(rig, recordings[0])
        res = sd.fit_polynomial(arrays, record, args.speed_order, rig_file.estimator.initial_coefficients.as_array(),
                                options=BatchOptions(noise_std_m=rig_file.estimator.measurement_noise_std_m,
                                                     estimate_imbalance=estimate_imbalance),
                                identical_bearings=args.bearings == 8)
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
    outcome = identify_recordings(rig_file, recordings, method=args.method, bearings=args.bearings,
                                  estimate_imbalance=estimate_imbalance, trial_specs=trial_specs)
    res, report, quality, imbalance = outcome.res, outcome.report, outcome.quality, outcome.imbalance
    records = recordings
    if args.json:
        print(json.dumps(outcome.as_dict(), indent=1))
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
