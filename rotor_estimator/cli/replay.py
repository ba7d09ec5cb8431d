# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator replay``: runs the estimator node's logic
(:class:`~rotor_estimator.core.pipeline.EstimatorPipeline`
after :func:`~rotor_estimator.ros.pipeline_io.feed_message`) over a bag message by message, with no
ROS graph, and can write the node's output topics into a new MCAP bag. With ``passes: 2``
in the rig file (the seed rig's setting) it runs the paper's multi-pass use: pass 2 starts
from pass 1's final coefficients with the configured P0 and replays the same messages; only
the last pass's outputs are written and printed.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any


from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.cli.arguments import add_bag_argument, bag_from_args
from rotor_estimator.core.errors import InputError
from rotor_estimator.ros.replay import replay_bag

__all__ = ["replay_bag", "format_replay", "cmd_replay", "add_parser", "EXIT_DIVERGED"]

#: replay's exit codes: 0 an estimate; 2 bad input or usage; 3 nothing could be filtered (no
#: estimate, the cause is named); 4 an estimate was printed but the filter diverged (status ERROR).
EXIT_DIVERGED = 4


def format_replay(r: dict[str, Any]) -> str:
    c = r["consistency"]
    lines = [f"bag {r['bag']} (rig {r['rig']}, {r['passes']} pass{'es' if r['passes'] > 1 else ''}); "
             f"estimate at stamp {r['stamp_ns']} ns", "", r["table"], ""]
    if c["samples"] and c["nis_band"][0] == c["nis_band"][0]:
        lines += [f"fit: mean NIS {c['nis_mean']:.3f} (consistent: {c['nis_band'][0]:.3f}-{c['nis_band'][1]:.3f} for "
                  f"{c['nis_dof']} channels over {c['samples']} samples); innovation whiteness: RMS autocorrelation "
                  f"{c['rms_autocorrelation']:.3f} over lags 1-{len(c['autocorrelation_by_lag'])} "
                  f"(Ljung-Box p = {c['whiteness_p_value']:.2g})"]
        if c["model_mismatch"]:
            lines.append(f"MODEL MISMATCH: {c['reason']}. The model does not fit these data, so the coefficients "
                         f"absorb what it lacks and their std is not their error: run `rotor-estimator diagnose "
                         f"{r['bag']}` to find the effect")
        else:
            lines.append("the model fits these data to the noise; a wrong probe or hammer sensitivity can still "
                         "shift the coefficients unseen (calibration is outside the std): run `diagnose` to check")
    s = r["samples"]
    reasons = {k: v for k, v in s.items() if v and k not in ("processed", "rejected") and not
               k.startswith(("received", "pending", "reordered"))}
    lines += [f"samples: {s['processed']} processed, {s['rejected']} rejected"
              + (f" ({', '.join(f'{k} {v}' for k, v in reasons.items())})" if reasons else ""),
              f"status: {r['status']['message']}"]
    if r["out"]:
        lines.append(f"outputs: {r['outputs_written']} estimates written to {r['out']}")
    return "\n".join(lines)


def cmd_replay(args: argparse.Namespace) -> int:
    args.bag = bag_from_args(args)
    if not args.publish_rate_hz > 0:
        raise InputError(f"--publish-rate must be > 0 Hz, got {args.publish_rate_hz:g}")
    result = replay_bag(args.bag, args.rig, args.out, progress=not args.no_progress, salvage=args.salvage,
                        publish_period_s=1.0 / args.publish_rate_hz, csv_path=args.csv)
    print(json.dumps(result, indent=1) if args.json else format_replay(result))
    return EXIT_DIVERGED if result["status"]["level"] >= 2 else 0


def add_parser(subparsers: Any) -> None:
    """The ``replay`` subcommand."""
    p = subparsers.add_parser("replay", help="run the estimator node's logic over a bag (no ROS graph)")
    add_bag_argument(p, "rosbag2 directory or .mcap file with the input topics")
    p.add_argument("--rig", type=Path, default=None, help="rig YAML (default: the bundled seed rig)")
    p.add_argument("--out", type=Path, default=None, help="write the node's output topics to this new MCAP bag")
    p.add_argument("--publish-rate", dest="publish_rate_hz", type=float, default=200.0, metavar="HZ",
                   help="estimates per second of sample time written to --out and --csv (default 200)")
    p.add_argument("--csv", type=Path, default=None, metavar="FILE",
                   help="write the coefficient history (time_s, each coefficient and its std, NIS) as CSV")
    p.add_argument("--salvage", action="store_true", help=cli_types.SALVAGE_HELP)
    p.add_argument("--json", action="store_true", help="print JSON (SI units)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_replay)
