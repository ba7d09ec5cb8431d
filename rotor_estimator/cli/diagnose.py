# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator diagnose BAG --rig RIG [--report DIR] [--json]`` and ``bench diagnosis``.

Reading bags goes through :mod:`rotor_estimator.io.bags` here only (the diagnosis core imports
no ROS). A ``.npz`` recording (``stamps_ns, probes_m, pulse_stamps_ns, impact_force_n``,
as written by the blind-set generator) is accepted too.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.cli.arguments import add_bag_argument, bag_from_args
from rotor_estimator.io.recordings import load_recording_file

__all__ = ["load_recording_file", "cmd_diagnose", "add_parser"]


def cmd_diagnose(args: argparse.Namespace) -> int:
    import sys
    import warnings

    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.diagnosis.api import diagnose
    from rotor_estimator.diagnosis.report import write_report

    warnings.simplefilter("ignore", RuntimeWarning)
    rig_file = load_rig_file(args.rig)
    recording = load_recording_file(Path(bag_from_args(args)), args.salvage)
    recording.meta.setdefault("source", str(bag_from_args(args)))
    stage = None if args.no_progress else (lambda text: print(f"rotor-estimator: diagnose: {text}", file=sys.stderr,
                                                                flush=True))
    d = diagnose(recording, rig_file.rig, rig_file.estimator, passes=args.passes, decimate=args.decimate,
                 progress=stage)
    summary = write_report(d, args.report) if args.report else d.summary()
    for text in summary["data"]["warnings"]:
        print(f"rotor-estimator: warning: {text}", file=sys.stderr)
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(f"best effect: {summary['best_effect']}"
              + (f" (+ {summary['second_effect']})" if summary["second_effect"] != "none" else ""))
        tie = summary["tie"]
        if tie:
            print(f"tie: {' and '.join(tie['effects'])} explain the data equally well (misfit -2 ln L "
                  f"{tie['misfit_difference']:+.1f} with {tie['parameters'][1]} vs {tie['parameters'][0]} parameters); "
                  "to separate them: "
                  + "; ".join(f"{m['measurement']} ({m['how']})" for m in tie["separating_measurements"][:2]))
        gap_left = summary["unexplained"]
        if gap_left:
            print(f"unexplained: {gap_left['residual_over_noise']:.2f} x noise remains after the verdict: "
                  f"{gap_left['signature']}")
        w = summary["where"]
        print(f"gap: residual RMS {summary['residual_rms_before'] * 1e6:.3f} um = {w['gap_ratio']:.2f} x noise; "
              f"dominant channel {w['dominant_channel']}, band {w['dominant_band']}")
        print(f"after: {summary['residual_rms_after'] * 1e6:.3f} um, shrink ratio {summary['shrink_ratio']:.2f}")
        ranking = ", ".join(f"{r['effect']} {r['delta_bic']:.0f}" for r in summary["ranking"][:4])
        print("ranking (delta BIC): " + ranking)
        if args.report:
            print(f"report written to {args.report}/report.md")
    return 0




def add_parser(subparsers) -> None:
    """The ``diagnose`` subcommand."""
    p = subparsers.add_parser("diagnose", help="diagnose the sim-to-real gap of a recording (where, which effect, "
                                               "how far it shrinks)")
    add_bag_argument(p, "input bag (rosbag2 MCAP, e.g. from `rotor-estimator import`) or .npz")
    p.add_argument("--salvage", action="store_true", help=cli_types.SALVAGE_HELP)
    p.add_argument("--rig", type=Path, required=True, help="rig YAML (bearing coefficients are estimated)")
    p.add_argument("--report", metavar="DIR", default=None, help="write report.md, summary.json and PNGs to DIR")
    p.add_argument("--json", action="store_true", help="print the JSON summary")
    p.add_argument("--passes", type=cli_types.passes, default=2, help="EKF passes of the nominal fit (default 2)")
    p.add_argument("--decimate", type=cli_types.decimation, default="auto", metavar="Q|auto",
                   help="low-pass filter the record and keep every Q-th sample before the fits (fewer samples, the "
                        "same band up to 0.45 of the new rate; a factor putting 5x the running speed above it is "
                        "refused; the noise floor is read at the record's rate when 10x the speed is above 0.3 of the "
                        "new one); default auto: the largest up to 4 the speed allows while the filter's edges are at "
                        "most 10 %% of the record, else 1; 1 keeps the record's rate")
    p.set_defaults(func=cmd_diagnose)


