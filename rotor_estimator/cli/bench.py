# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator bench ...``: the benchmarks that print figures (speed, live nodes, diagnosis,
identification, virtual sensing). Each handler is a thin shell over :mod:`rotor_estimator.bench`."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any


from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.cli.arguments import progress_bar
from rotor_estimator.core.errors import RotorEstimatorError

def cmd_bench_speed(args: argparse.Namespace) -> int:
    from rotor_estimator.bench.speed import format_result, run

    result = run(rig_path=args.rig)
    print(json.dumps(result, indent=1) if args.json else format_result(result))
    return 0


def cmd_bench_live(args: argparse.Namespace) -> int:
    try:
        from rotor_estimator.bench.live_nodes import format_result, run
    except ImportError as exc:
        from rotor_estimator.core.errors import RotorEstimatorError

        raise RotorEstimatorError(f"bench live needs rclpy ({exc}); install the 'ros' extra or source ROS 2") from exc
    result = run(step_s=args.step_s, rates_hz=tuple(args.rates), progress=not args.json)
    print(json.dumps(result, indent=1) if args.json else format_result(result))
    return 0


def cmd_bench_diagnosis(args: argparse.Namespace) -> int:
    import sys
    import warnings

    from rotor_estimator.bench.diagnosis import format_score, run, score_sets
    from rotor_estimator.core.errors import InputError

    warnings.simplefilter("ignore")
    if args.score_only and args.set is None:
        raise InputError("--score-only scores sets already diagnosed (in part): give them with --set DIR [DIR ...]")
    if args.set is not None and len(args.set) > 1 and not args.score_only:
        raise InputError("several --set directories are scored together with --score-only; diagnose each first "
                         "(`bench diagnosis --set DIR`)")
    if args.score_only and args.fresh:
        raise InputError("--fresh diagnoses every case again; --score-only diagnoses none: give one of them")
    if args.score_only:
        s = score_sets(args.set, args.decimate)
    else:
        s = run(args.cases, args.seed, args.set[0] if args.set else args.out, jobs=args.jobs,
                use_ross=not args.no_ross, generator=args.generator, generate=args.set is None,
                progress=lambda cid: print(f"generated {cid}", file=sys.stderr, flush=True),
                on_diagnosed=lambda k, n: print(f"diagnosed {k} / {n}", file=sys.stderr, flush=True),
                decimate=args.decimate, fresh=args.fresh,
                on_kept=lambda k, n, d, other: print(
                    f"resuming: {k} of {n} cases already diagnosed in {d} are kept, not diagnosed again"
                    f"{f' ({other} of them made by other code than this run)' if other else ''} "
                    "(--fresh diagnoses every case)", file=sys.stderr, flush=True))
    if args.json:
        brief = {k: v for k, v in s.items() if k != "rows"}
        brief["by_generator"] = {g: {k: v for k, v in sub.items() if k != "rows"}
                                 for g, sub in s.get("by_generator", {}).items()}
        print(json.dumps(brief, indent=1))
    else:
        print(format_score(s))
    return 0


def cmd_bench_generate(args: argparse.Namespace) -> int:
    """Write a blind set (cases apart from labels) without diagnosing it."""
    import warnings
    from collections import Counter

    from rotor_estimator.bench.diagnosis import write_sets

    warnings.simplefilter("ignore")
    labels = write_sets(args.out_dir, args.cases, args.seed, generator=args.generator, use_ross=not args.no_ross,
                        progress=lambda cid: print(f"generated {cid}", file=sys.stderr, flush=True), jobs=args.jobs)
    forms = Counter(lab.get("form", "+".join(lab["effects"]) or "none") for lab in labels.values())
    print(f"{len(labels)} cases in {args.out_dir}/cases, labels in {args.out_dir}/labels/labels.json")
    for form, n in sorted(forms.items()):
        print(f"  {n:3d}  {form}")
    return 0


def cmd_bench_identification(args: argparse.Namespace) -> int:
    from rotor_estimator.bench.identification import format_results, run, scenarios, to_rows
    from rotor_estimator.identification.methods import METHODS

    methods = tuple(args.methods) if args.methods else METHODS
    chosen = [s for s in scenarios() if not args.only or any(o in s.name for o in args.only)]
    with progress_bar(args.runs * len(chosen), "bench identification", not args.no_progress) as bar:
        cells = run(args.runs, rig_path=args.rig, methods=methods, jobs=args.jobs, first_seed=args.seed,
                    only=tuple(args.only or ()), progress=bar.update)
    print(json.dumps(to_rows(cells), indent=1) if args.json else format_results(cells))
    return 0


def cmd_bench_batch(args: argparse.Namespace) -> int:
    from rotor_estimator.bench.batch_speed import format_result, run

    result = run(args.recordings, args.command, tuple(args.workers), args.duration, args.rig,
                 external_cluster=args.external_cluster, corrupt=args.corrupt)
    print(json.dumps(result, indent=1) if args.json else format_result(result))
    return 0


def cmd_bench_virtual_sensing(args: argparse.Namespace) -> int:
    from rotor_estimator.bench.virtual_sensing import bench_virtual_sensing

    try:
        res = bench_virtual_sensing(args.samples, args.seed, args.alpha, args.beta, args.kappa)
    except RotorEstimatorError as exc:
        print(f"rotor-estimator: error: {exc}", file=sys.stderr)
        return 2
    table = res.pop("_table")
    if args.json:
        print(json.dumps(res, indent=2, default=cli_types.json_default))
        return 0
    n = res["n_samples"]
    print(f"virtual-sensing bench: {res['rotor']}, {res['n_states']} states, {res['n_observations']} "
          f"observations, {n} samples")
    print(f"  UKF (alpha={res['ukf_alpha']:g}, beta={res['ukf_beta']:g}, kappa={res['ukf_kappa']:g}): "
          f"{res['ukf_150_seconds']:.2f} s ({res['ukf_ms_per_sample']:.3f} ms/sample)")
    print(f"  Kalman filter: {res['kf_150_seconds']:.2f} s ({res['kf_ms_per_sample']:.3f} ms/sample)")
    print(f"  UKF vs KF: max mean difference {res['max_mean_difference_in_kf_sigmas']:.2e} KF sigmas, "
          f"max variance difference {100 * res['max_variance_relative_difference']:.2e} %")
    print(f"  leave-one-station-out (probes hidden): coverage {res['coverage_95']:.3f} of 95% intervals "
          f"(true state {res['coverage_95_true_state']:.3f}), mean width {res['interval_width_m']:.3e} m "
          f"(hidden signal rms {res['hidden_signal_rms_m']:.3e} m)")
    print(table)
    return 0



def add_virtual_sensing_bench(bench: Any) -> argparse.ArgumentParser:
    """``bench virtual-sensing``."""
    p = bench.add_parser(
        "virtual-sensing", help="UKF vs Kalman filter at the paper's scale (150 states, 8 observations)",
        description="Time a UKF with 150 states and 8 observations over 8192 samples (Neisi et al.: more "
                    "than eight hours), the exact Kalman filter on the same model, their agreement, and "
                    "the leave-one-station-out coverage.")
    p.add_argument("--samples", type=cli_types.positive_int, default=8192,
                   help="samples filtered per run (default 8192)")
    p.add_argument("--seed", type=cli_types.seed, default=0)
    p.add_argument("--alpha", type=float, default=0.01, help="UKF alpha (Table 5 of the paper: 0.01)")
    p.add_argument("--beta", type=float, default=2.0, help="UKF beta (default 2)")
    p.add_argument("--kappa", type=float, default=0.0, help="UKF kappa (default 0)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_bench_virtual_sensing)
    return p


def add_parser(subparsers: Any) -> None:
    """The ``bench`` subcommand and its benchmarks."""
    bench = subparsers.add_parser("bench", help="benchmarks that print figures").add_subparsers(
        dest="bench", required=True, metavar="BENCH")
    b = bench.add_parser("speed", help="EKF microseconds per sample vs a filterpy EKF of the same model")
    b.add_argument("--json", action="store_true")
    b.add_argument("--rig", type=Path, default=None)
    b.set_defaults(func=cmd_bench_speed)

    b = bench.add_parser("live", help="live rclpy throughput and latency (publisher + estimator node)")
    b.add_argument("--json", action="store_true")
    b.add_argument("--step-s", type=float, default=3.0, help="seconds per rate step (default 3)")
    b.add_argument("--rates", type=float, nargs="+", default=[5000.0, 10000.0, 20000.0, 40000.0, 80000.0],
                   help="probe sample rates per plane to try, Hz (200-sample blocks)")
    b.set_defaults(func=cmd_bench_live)

    b = bench.add_parser("diagnosis", help="blind withheld-effect benchmark of `diagnose`")
    b.add_argument("--cases", type=int, default=36, help="blind cases to draw (default 36)")
    b.add_argument("--seed", type=cli_types.seed, default=2024)
    b.add_argument("--out", default=None, help="keep the blind set, labels and results here")
    b.add_argument("--jobs", type=int, default=2, help="cases diagnosed at once, one process each (default 2)")
    b.add_argument("--no-ross", action="store_true", help="leave out the ROSS flexible-shaft cases")
    b.add_argument("--generator", choices=("own", "independent", "both"), default="own",
                   help="cases from the package's own generator, the independent one, or both (scored apart)")
    b.add_argument("--set", type=Path, nargs="+", default=None, metavar="DIR",
                   help="diagnose the blind set already in DIR (from `bench generate`) instead of drawing one; with "
                        "--score-only, several sets are scored together")
    b.add_argument("--score-only", action="store_true",
                   help="with --set: score the cases diagnosed so far (results/ of each set, pooled), diagnose none; "
                        "a rerun without it resumes the others")
    b.add_argument("--fresh", action="store_true",
                   help="delete the set's kept results first and diagnose every case (without it, a "
                        "rerun resumes: the cases already diagnosed keep their results, from whatever code made "
                        "them, and the score says how many)")
    b.add_argument("--decimate", type=cli_types.decimation, default="auto", metavar="Q|auto",
                   help="the diagnosis's --decimate (default auto, as `diagnose`); the results are kept apart by it: "
                        "results_auto/, results/ for 1 (the full rate), results_decimate<Q>/")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_diagnosis)

    b = bench.add_parser("generate", help="write a blind diagnosis set (cases and labels apart), no diagnosis")
    b.add_argument("out_dir", type=Path, metavar="OUT_DIR", help="directory for cases/ and labels/ (created)")
    b.add_argument("--generator", choices=("own", "independent", "both"), default="independent",
                   help="the package's own generator, the independent one (default), or both")
    b.add_argument("--cases", type=cli_types.positive_int, default=24, help="cases per generator (default 24)")
    b.add_argument("--seed", type=cli_types.seed, default=7070)
    b.add_argument("--jobs", type=int, default=1, help="processes for the own generator (default 1)")
    b.add_argument("--no-ross", action="store_true", help="leave out the ROSS cases")
    b.set_defaults(func=cmd_bench_generate)

    b = bench.add_parser("identification", help="EKF, UKF, EKF+RTS and batch ML against the CRLB on "
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

    add_virtual_sensing_bench(bench)

    b = bench.add_parser("batch", help="wall time of `batch` over simulated recordings with 1 and 2 workers")
    b.add_argument("--recordings", type=cli_types.positive_int, default=30, help="simulated bags (default 30)")
    b.add_argument("--command", choices=("replay", "identify", "diagnose"), default="replay",
                   help="the batch command to time (default replay)")
    b.add_argument("--workers", type=cli_types.positive_int, nargs="+", default=[1, 2],
                   help="worker counts to time, in order (default 1 2)")
    b.add_argument("--duration", type=float, default=0.1, help="simulated seconds per bag (default 0.1)")
    b.add_argument("--external-cluster", action="store_true",
                   help="also run on a separately started LocalCluster (2 workers) by address; compare rows")
    b.add_argument("--corrupt", action="store_true", help="add a truncated bag to the set (an error row)")
    b.add_argument("--rig", type=Path, default=None)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_batch)
