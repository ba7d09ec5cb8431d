# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator``: the command-line entry point (argparse, one handler per subcommand).

Every subcommand is a thin shell over library functions; heavy imports happen inside
the handlers so ``rotor-estimator --help`` is instant.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from rotor_estimator.core.errors import RotorEstimatorError
from rotor_estimator.cli import arguments as cli_types


def _progress(total: int, desc: str, enabled: bool = True):
    """A tqdm progress bar on stderr (silent when not a terminal unless forced)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, file=sys.stderr, disable=not enabled, leave=False)


# ---------------------------------------------------------------------------------- reproduce
def cmd_reproduce(args: argparse.Namespace) -> int:
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.bench.reproduce import CASES, format_table, run_case, to_json_rows

    if args.paper != "miller-howard":
        raise RotorEstimatorError(f"unknown paper {args.paper!r}; available: miller-howard")
    if args.runs < 2:
        raise RotorEstimatorError("--runs must be at least 2 (a spread needs two runs)")
    rig_file = load_rig_file(args.rig)
    results = []
    with _progress(args.runs * len(CASES), "reproduce", not args.no_progress) as bar:
        for case in CASES:
            results.append(run_case(rig_file, case, args.runs, first_seed=args.seed, progress=bar.update,
                                    keep_example=bool(args.plots)))
    if args.plots:
        _reproduce_plots(rig_file, results, Path(args.plots))
    if args.json:
        print(json.dumps([row for r in results for row in to_json_rows(r)], indent=1))
    else:
        print("Miller & Howard (2008) Table 3 vs rotor_estimator; exact values from the errata (seeds README).")
        print("bias/CRLB and std/CRLB: bias of the mean and spread in units of the Cramer-Rao bound; "
              "rep/std: the filter's reported std over the actual spread (1 = honest covariance).\n")
        for r in results:
            print(format_table(r))
            print()
        if args.plots:
            print(f"figures written to {args.plots}/")
    return 0


def _reproduce_plots(rig_file, results, out: Path) -> None:
    import numpy as np

    from rotor_estimator.cli.plots import coefficient_error_history, orbit_comparison
    from rotor_estimator.core.simulator import Scenario, paper_scenario, simulate
    from rotor_estimator.core.config import BearingCoefficients
    from rotor_estimator.io.safe_write import output_directory

    output_directory(out, "--plots")  # refuses a symbolic link (safe_write)
    rig = rig_file.rig
    for r in results:
        ex = r.example
        if not ex:
            continue
        tag = r.case.replace("+", "_")
        coefficient_error_history(ex["t_s"], ex["coefficients"], r.true, out / f"coefficient_error_{tag}.png",
                                  f"Coefficient error vs time, {r.case} (cf. Miller & Howard Fig. 4)")
        base = paper_scenario(r.case)
        resim = simulate(rig, Scenario(duration_s=base.duration_s, discard_initial_s=base.discard_initial_s,
                                       impacts=base.impacts, noise_std_m=0.0,
                                       coefficients=BearingCoefficients.from_array(ex["estimate"])), seed=None)
        samples_per_rev = int(round(2 * np.pi / rig.speed_rad_s * rig.sample_rate_hz))
        orbit_comparison(rig, ex["recording"].probes_m, resim.recording.probes_m, samples_per_rev,
                         out / f"orbit_{tag}.png", f"Bearing-2 orbit, last revolution, {r.case} (cf. Fig. 5)")


# ---------------------------------------------------------------------------------- bench
def cmd_bench_speed(args: argparse.Namespace) -> int:
    from rotor_estimator.bench.speed import format_result, run

    result = run(rig_path=args.rig)
    print(json.dumps(result, indent=1) if args.json else format_result(result))
    return 0


# ---------------------------------------------------------------------------------- parser
def _version() -> str:
    """The installed distribution's version (the package's own when run from a source tree)."""
    from importlib.metadata import PackageNotFoundError, version

    from rotor_estimator import __version__

    try:
        return version("rotor_estimator")
    except PackageNotFoundError:
        return __version__


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rotor-estimator",
        description="Identify rotor-bearing stiffness and damping (EKF) and diagnose model-vs-rig gaps. "
                    "All values SI.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}",
                        help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("reproduce", help="reproduce a seed paper's results (Table 3 of Miller & Howard)")
    p.add_argument("paper", choices=["miller-howard"], help="which paper")
    p.add_argument("--runs", type=int, default=50, help="seeded runs per case (default 50; the paper used 20)")
    p.add_argument("--seed", type=cli_types.seed, default=1, help="first noise seed (default 1)")
    p.add_argument("--rig", type=Path, default=None, help="rig YAML (default: the bundled seed rig)")
    p.add_argument("--json", action="store_true", help="print JSON rows instead of the table")
    p.add_argument("--report", "--plots", dest="plots", metavar="DIR", default=None,
                   help="write PNG figures (Fig. 4 and 5 analogues) to DIR (--plots: the old name)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_reproduce)

    bench = sub.add_parser("bench", help="benchmarks that print figures").add_subparsers(
        dest="bench", required=True, metavar="BENCH")
    b = bench.add_parser("speed", help="EKF microseconds per sample vs a filterpy EKF of the same model")
    b.add_argument("--json", action="store_true")
    b.add_argument("--rig", type=Path, default=None)
    b.set_defaults(func=cmd_bench_speed)

    _add_optional_commands(sub, bench)
    for leaf in _leaf_parsers(parser):
        if not any("--no-progress" in a.option_strings for a in leaf._actions):
            leaf.add_argument("--no-progress", action="store_true", help=SHARED_OPTION_HELP["--no-progress"])
        for action in leaf._actions:
            if not action.help and action.option_strings and action.option_strings[-1] in SHARED_OPTION_HELP:
                action.help = SHARED_OPTION_HELP[action.option_strings[-1]]
    return parser


# One wording for the options every command shares (used where a command gives none of its own).
SHARED_OPTION_HELP = {
    "--json": "print machine-readable JSON (SI units) instead of the text table",
    "--rig": "rig YAML file (default: the bundled Miller & Howard seed rig)",
    "--seed": "random seed, an integer from 0 to 2^32 - 1 (default %(default)s)",
    "--no-progress": "no progress bar on stderr",
}


def _leaf_parsers(parser: argparse.ArgumentParser):
    """Every command's own parser (the leaves of the subcommand tree)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield parser
    for action in subs:
        for child in dict.fromkeys(action.choices.values()):  # aliases map to the same parser
            yield from _leaf_parsers(child)


def _add_optional_commands(sub, bench) -> None:
    """Commands that live in their own modules (bags and nodes, diagnosis, identification, virtual sensing)."""
    from rotor_estimator.cli import commands
    from rotor_estimator.cli import virtual_sensing as virtual_sensing_cli

    commands.add_parsers(sub)
    commands.add_bench_parsers(bench)
    virtual_sensing_cli.add_virtual_sensing_parser(sub)
    virtual_sensing_cli.add_bench_parser(bench)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.no_progress:
        os.environ["TQDM_DISABLE"] = "1"  # every tqdm bar, also those deep in library code
    try:
        return int(args.func(args) or 0)
    except RotorEstimatorError as exc:
        print(f"rotor-estimator: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("rotor-estimator: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
