"""``rotor-estimator plan``, ``rotor-estimator identify`` and ``rotor-estimator bench identification``.

Thin shells over :mod:`rotor_estimator.identification`; heavy imports inside the handlers.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .. import cli_types


def _bar(total: int, desc: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, file=sys.stderr, disable=not enabled, leave=False)


# ----------------------------------------------------------------------------------------- plan
def cmd_plan(args: argparse.Namespace) -> int:
    from ..config import load_rig_file
    from ..identification.planner import Target, candidate_designs, plan

    rig = load_rig_file(args.rig).rig
    target = Target.from_percent(args.target)
    coefficients = None
    if rig.true_coefficients is not None:
        coefficients = rig.true_coefficients.as_array()
    else:
        coefficients = load_rig_file(args.rig).estimator.initial_coefficients.as_array()
    designs = candidate_designs(rig, coefficients, bearings16=args.bearings == 16)
    results = []
    noises = args.noise or [None]
    with _bar(len(designs) * len(noises), "plan", not args.no_progress and not args.json) as bar:
        for noise in noises:
            results.append(plan(rig, target, coefficients=coefficients, designs=designs,
                                unknown_imbalance=not args.known_imbalance, bearings16=args.bearings == 16,
                                noise_std_m=noise, progress=bar.update))
    if args.json:
        print(json.dumps([row for p in results for row in p.as_rows()], indent=1))
        return 0
    print(f"Excitation plan for rig '{rig.name}': Cramer-Rao bound of each coefficient per candidate test "
          f"({args.bearings} coefficients; imbalance {'known' if args.known_imbalance else 'unknown, estimated'}; "
          f"initial state unknown; bound at the rig's expected coefficients).")
    for noise, p in zip(noises, results):
        sigma = noise if noise is not None else rig.noise_std_m
        print(f"\nProbe noise {sigma * 1e6:g} um, {rig.sample_rate_hz:g} Hz:")
        print(p.format())
    return 0


# ------------------------------------------------------------------------------------- identify
def cmd_identify(args: argparse.Namespace) -> int:
    import numpy as np

    from ..config import load_rig_file
    from ..errors import RotorEstimatorError
    from ..identification import speed_dependent as sd
    from ..identification.identifiability import report_for_result
    from ..identification.methods import identify
    from ..identification.problem import CoefficientModel, RigArrays, record_from_recording

    rig_file = load_rig_file(args.rig)
    rig = rig_file.rig
    if args.bag:
        from ..bagio import read_input_bag

        recording = read_input_bag(args.bag, salvage=args.salvage)
    else:
        from ..identification.benchmark import scenarios
        from ..simulator import simulate

        named = {s.scenario.name: s for s in scenarios()}
        if args.simulate not in named:
            raise RotorEstimatorError(f"--simulate: choose one of {', '.join(sorted(named))}")
        recording = simulate(rig, named[args.simulate].scenario, seed=args.seed).recording
    record = record_from_recording(rig, recording)
    arrays = RigArrays.build(rig)
    if args.speed_order > 0:
        from ..identification.batch_ml import BatchOptions

        res = sd.fit_polynomial(arrays, record, args.speed_order, rig_file.estimator.initial_coefficients.as_array(),
                                options=BatchOptions(noise_std_m=rig_file.estimator.measurement_noise_std_m,
                                                     estimate_imbalance=args.unknown_imbalance),
                                identical_bearings=args.bearings == 8)
    else:
        model = CoefficientModel(identical_bearings=args.bearings == 8)
        res = identify(arrays, rig_file.estimator, record, method=args.method, model=model,
                       estimate_imbalance=args.unknown_imbalance)
    if args.speed_order > 0:
        speeds = np.linspace(record.speed_rad_s[record.use].min(), record.speed_rad_s[record.use].max(), 9)
        tab = sd.table(res, speeds)
        if args.json:
            print(json.dumps(tab.as_rows(), indent=1))
        else:
            print(f"Speed-dependent coefficients (order {args.speed_order}, batch ML), 95% bands:")
            print(tab.format())
        if args.plots:
            from ..identification.plots import coefficients_vs_speed

            path = coefficients_vs_speed(tab, Path(args.plots) / "coefficients_vs_speed.png")
            print(f"figure written to {path}", file=sys.stderr)
        return 0
    prior = None
    if res.information is None:
        std0 = rig_file.estimator.initial_coefficient_std.as_array()
        prior = np.diag(np.tile(std0, res.model.n_coefficients // 8) ** 2)
    report = report_for_result(res, prior_cov=prior)
    if args.json:
        print(json.dumps({"method": res.method, "runtime_s": res.runtime_s, "converged": res.converged,
                          "coefficients": [e.as_dict() for e in report.entries],
                          "imbalance_kg_m": res.imbalance_kg_m.tolist()}, indent=1))
        return 0
    print(f"Method: {res.method} ({res.runtime_s:.2f} s{'' if res.converged else ', NOT converged'}); "
          f"imbalance {'estimated' if res.imbalance_estimated else 'known'}: "
          + " ".join(f"{v:.3g}" for v in res.imbalance_kg_m) + " kg*m (in-phase, quadrature per plane)")
    print("Identifiability from the Fisher information of these data:" if res.information is not None else
          "Identifiability from the filter's covariance (P^-1 - P0^-1):")
    print(report.format())
    return 0


# ---------------------------------------------------------------------------------------- bench
def cmd_bench_identification(args: argparse.Namespace) -> int:
    from ..identification.benchmark import format_results, run, scenarios, to_rows
    from ..identification.methods import METHODS

    methods = tuple(args.methods) if args.methods else METHODS
    chosen = [s for s in scenarios() if not args.only or any(o in s.name for o in args.only)]
    with _bar(args.runs * len(chosen), "bench identification", not args.no_progress) as bar:
        cells = run(args.runs, rig_path=args.rig, methods=methods, jobs=args.jobs, first_seed=args.seed,
                    only=tuple(args.only or ()), progress=bar.update)
    print(json.dumps(to_rows(cells), indent=1) if args.json else format_results(cells))
    return 0


# --------------------------------------------------------------------------------------- parsers
def add_parsers(subparsers) -> None:
    p = subparsers.add_parser("plan", help="excitation planner: CRLB of candidate tests, shortest test meeting "
                                           "a target precision")
    p.add_argument("--rig", type=Path, default=None, help="rig YAML (default: the bundled seed rig)")
    p.add_argument("--target", type=float, nargs="+", default=[5.0], metavar="PCT",
                   help="max CRLB std in %% of each coefficient: one value for all, or two: direct cross-coupled "
                        "(default 5)")
    p.add_argument("--noise", type=float, nargs="+", default=None, metavar="M",
                   help="probe noise std(s) in m to plan for (default: the rig's)")
    p.add_argument("--bearings", type=int, choices=(8, 16), default=8,
                   help="8 (identical bearings, default) or 16 coefficients")
    p.add_argument("--known-imbalance", action="store_true",
                   help="assume the rotor imbalance known (default: unknown, estimated with the coefficients)")
    p.add_argument("--json", action="store_true", help="JSON rows instead of the table")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=cmd_plan)

    i = subparsers.add_parser("identify", help="identify the coefficients from a bag or a simulated test, with "
                                               "the identifiability report")
    src = i.add_mutually_exclusive_group(required=True)
    src.add_argument("--bag", type=Path, help="input bag (probe, keyphasor and impact topics)")
    i.add_argument("--salvage", action="store_true", help="use the intact part of a damaged bag (the messages lost are counted and reported on stderr); without it a damaged bag is an error")
    src.add_argument("--simulate", metavar="SCENARIO",
                     help="simulate a benchmark scenario: imbalance+impact, imbalance, cd0.5, cd2, 5imp")
    i.add_argument("--seed", type=cli_types.seed, default=1)
    i.add_argument("--rig", type=Path, default=None)
    i.add_argument("--method", default="auto", help="auto (batch-ml), batch-ml, ekf+rts, ekf, ukf")
    i.add_argument("--unknown-imbalance", action="store_true", help="estimate the imbalance jointly")
    i.add_argument("--bearings", type=int, choices=(8, 16), default=8,
                   help="8 coefficients (identical bearings, default) or 16 (each bearing its own)")
    i.add_argument("--speed-order", type=int, default=0,
                   help="> 0: coefficients as speed polynomials of this order (prints the table)")
    i.add_argument("--plots", metavar="DIR", default=None, help="coefficient-versus-speed figure into DIR")
    i.add_argument("--json", action="store_true")
    i.set_defaults(func=cmd_identify)


def add_bench_parsers(bench_subparsers) -> None:
    b = bench_subparsers.add_parser("identification", help="EKF, UKF, EKF+RTS and batch ML against the CRLB on "
                                                           "the seed cases, coast-downs and the 5-impact test")
    b.add_argument("--runs", type=int, default=20, help="seeded runs per scenario (default 20)")
    b.add_argument("--seed", type=cli_types.seed, default=1, help="first noise seed")
    b.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    b.add_argument("--methods", nargs="+", default=None, help="subset of: ekf ukf ekf+rts batch-ml")
    b.add_argument("--only", nargs="+", default=None, help="scenarios whose name contains one of these words")
    b.add_argument("--rig", type=Path, default=None)
    b.add_argument("--json", action="store_true",
                   help="JSON rows (scenario, method, coefficient, true, mean, std, crlb_std, ...)")
    b.add_argument("--no-progress", action="store_true")
    b.set_defaults(func=cmd_bench_identification)
