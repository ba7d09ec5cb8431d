# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator plan``: the excitation planner (CRLB of candidate tests, the shortest one meeting a target),
printing the `simulate` and `identify` command lines of the recommended test."""
from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from rotor_estimator.cli.arguments import progress_bar

def cmd_plan(args: argparse.Namespace) -> int:
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.identification.planner import Target, candidate_designs, plan

    rig = load_rig_file(args.rig).rig
    target = Target.from_percent(args.target)
    coefficients = None
    if rig.true_coefficients is not None:
        coefficients = rig.true_coefficients.as_array()
    else:
        coefficients = load_rig_file(args.rig).estimator.initial_coefficients.as_array()
    designs = candidate_designs(rig, coefficients, bearings16=args.bearings == 16, hammer_force_n=args.hammer_force_n)
    results = []
    noises = args.noise or [None]
    with progress_bar(len(designs) * len(noises), "plan", not args.no_progress and not args.json) as bar:
        for noise in noises:
            results.append(plan(rig, target, coefficients=coefficients, designs=designs,
                                unknown_imbalance=not args.known_imbalance, bearings16=args.bearings == 16,
                                noise_std_m=noise, progress=bar.update, max_decel_rpm_per_s=args.decel_rpm_per_s))
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
        if p.recommended is not None and args.bearings == 8:
            print("\n" + "\n".join(closed_loop_commands(p.recommended.design, args)))
    return 0


def closed_loop_commands(design, args) -> list[str]:
    """The commands that make the recommended test on the simulator and identify from it (on the rig:
    record the same test, `import` each record, then the same `identify`)."""
    import math
    import shlex

    rig = f" --rig {shlex.quote(str(args.rig))}" if args.rig else ""
    hammer = f" --hammer-force-n {args.hammer_force_n:g}" if args.hammer_force_n != 515.0 else ""
    lines = ["Make the recommended test on the simulator, then identify from it (on the rig: record it, "
             "`rotor-estimator import` each record, then the same identify):"]
    bags = []
    for k in range(design.n_records):
        bags.append(f"record{k}")
        lines.append(f"  rotor-estimator simulate{rig} --design {shlex.quote(design.name)} --record {k}{hammer} "
                     f"--out record{k}")
    weights = ["none"] + [f"{w.mass_kg * 1e3:.6g},{w.radius_m * 1e3:.6g},{w.plane + 1},{math.degrees(w.phase_rad):.6g}"
                          for w in design.trial_weights]
    lines.append(f"  rotor-estimator identify{rig} " + " ".join(
        f"--bag {b}" + (f" --trial-weight {w}" if design.trial_weights else "") for b, w in zip(bags, weights)))
    return lines


def add_parser(subparsers: Any) -> None:
    """The ``plan`` subcommand."""
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
    p.add_argument("--decel-rpm-per-s", type=float, default=None, metavar="R",
                   help="the fastest speed change the machine can make (rpm/s, e.g. a free coast-down's); "
                        "tests asking for more are not recommended (default: no limit)")
    p.add_argument("--hammer-force-n", type=float, default=515.0, metavar="N",
                   help="peak force of the impact hammer, N (default 515, the seed paper's)")
    p.add_argument("--json", action="store_true", help="JSON rows instead of the table")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=cmd_plan)
