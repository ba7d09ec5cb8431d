# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator reproduce miller-howard``: Table 3 of Miller & Howard, side by side with ours and the CRLB."""
from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.cli.arguments import progress_bar
from rotor_estimator.core.errors import RotorEstimatorError

def cmd_reproduce(args: argparse.Namespace) -> int:
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.bench.reproduce import CASES, format_table, run_case, to_json_rows

    if args.paper != "miller-howard":
        raise RotorEstimatorError(f"unknown paper {args.paper!r}; available: miller-howard")
    if args.runs < 2:
        raise RotorEstimatorError("--runs must be at least 2 (a spread needs two runs)")
    rig_file = load_rig_file(args.rig)
    results = []
    with progress_bar(args.runs * len(CASES), "reproduce", not args.no_progress) as bar:
        for case in CASES:
            results.append(run_case(rig_file, case, args.runs, first_seed=args.seed, progress=bar.update,
                                    keep_example=bool(args.plots), workers=args.workers, scheduler=args.scheduler))
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


def add_parser(subparsers: Any) -> None:
    """The ``reproduce`` subcommand."""
    p = subparsers.add_parser("reproduce", help="reproduce a seed paper's results (Table 3 of Miller & Howard)")
    p.add_argument("paper", choices=["miller-howard"], help="which paper")
    p.add_argument("--runs", type=int, default=50, help="seeded runs per case (default 50; the paper used 20)")
    p.add_argument("--seed", type=cli_types.seed, default=1, help="first noise seed (default 1)")
    p.add_argument("--rig", type=Path, default=None, help="rig YAML (default: the bundled seed rig)")
    p.add_argument("--json", action="store_true", help="print JSON rows instead of the table")
    p.add_argument("--report", "--plots", dest="plots", metavar="DIR", default=None,
                   help="write PNG figures (Fig. 4 and 5 analogues) to DIR (--plots: the old name)")
    p.add_argument("--workers", type=cli_types.positive_int, default=1, metavar="N",
                   help="runs at once on a local Dask cluster of N single-thread processes (default 1: here)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the runs on this Dask cluster (tcp://host:port) instead")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_reproduce)
