# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator batch replay|identify|diagnose|virtual-sensing RECORDINGS... [--out TABLE]``: one
command over many recordings on Dask, one row per recording; ``batch plot TABLE``: its summary figure.
Thin shell over :mod:`rotor_estimator.batch` (dask is imported only when a batch runs)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from rotor_estimator.cli import arguments as cli_types

BATCH_COMMANDS = ("replay", "identify", "diagnose", "virtual-sensing")


def cmd_batch(args: argparse.Namespace) -> int:
    from rotor_estimator.batch.driver import run_batch
    from rotor_estimator.batch.table import table_bytes
    from rotor_estimator.batch.tasks import BatchOptions, expand_inputs

    # absolute: the workers may run in another directory (or on another machine with the same file system)
    options = BatchOptions(args.batch_command, rig_path=str(Path(args.rig).resolve()) if args.rig else None,
                           rotor=args.rotor, passes=args.passes, method=args.method,
                           salvage=args.salvage, decimate=args.decimate).validate()
    recordings, skipped_files = expand_inputs(args.inputs)
    if skipped_files:
        print(f"rotor-estimator: {skipped_files} file(s) matched but are not recordings (bag directory, .mcap "
              f"or .npz); left out", file=sys.stderr)
    summary = run_batch(options, recordings, args.out, workers=args.workers, scheduler=args.scheduler,
                        force=args.force, progress=not args.no_progress)
    if args.out is None:
        sys.stdout.write(table_bytes(summary.rows, options.command, "csv").decode())
    print(f"batch {options.command}: {len(recordings)} recording(s): {summary.computed} computed "
          f"({summary.errors} error(s)), {summary.skipped} skipped (already ok in the table); "
          f"{summary.seconds:.1f} s" + (f"; table {args.out}" if args.out else ""), file=sys.stderr)
    if args.plot:
        from rotor_estimator.batch.plots import plot_table

        print(f"figure written to {plot_table(summary.rows, options.command, args.plot, x=args.x)}", file=sys.stderr)
    return 1 if summary.errors else 0


def cmd_batch_plot(args: argparse.Namespace) -> int:
    from rotor_estimator.batch.plots import plot_table
    from rotor_estimator.batch.table import read_table
    from rotor_estimator.core.errors import InputError

    command, rows = read_table(args.table)
    if command is None:
        raise InputError(f"{args.table}: the table is empty")
    out = args.out or Path(args.table).with_suffix(".png")
    print(f"figure written to {plot_table(rows, command, out, x=args.x)}")
    return 0


def add_parser(subparsers: Any) -> None:
    """The ``batch`` subcommand."""
    batch = subparsers.add_parser(
        "batch", help="run replay, identify, diagnose or virtual-sensing over many recordings on Dask: one table",
        description="Every recording through one command, on a local Dask cluster of processes (one per core, "
                    "one BLAS thread each) or an existing cluster (--scheduler). One row per recording "
                    "(Parquet or CSV); a failing recording is a row with its error; rerunning skips the "
                    "recordings already ok in the table (--force: all).").add_subparsers(
        dest="batch_command", required=True, metavar="COMMAND")
    for name in BATCH_COMMANDS:
        p = batch.add_parser(name, help=f"`{name}` on every recording")
        p.add_argument("inputs", nargs="+", metavar="GLOB_OR_LIST",
                       help="bag directories, .mcap or .npz files, globs of them (quoted), or a .txt file listing "
                            "paths one a line")
        if name == "virtual-sensing":
            p.add_argument("--rotor", default="three_probe_rig",
                           help="rotor description YAML or a bundled name (default three_probe_rig)")
            p.set_defaults(rig=None)
        else:
            p.add_argument("--rig", type=Path, default=None, required=name == "diagnose",
                           help="rig YAML" + (" (required)" if name == "diagnose" else
                                              " (default: the bundled seed rig)"))
            p.set_defaults(rotor="three_probe_rig")
        if name == "diagnose":
            p.add_argument("--passes", type=cli_types.passes, default=2,
                           help="EKF passes of the nominal fit (default 2)")
            p.add_argument("--decimate", type=cli_types.decimation, default="auto", metavar="Q|auto",
                           help="as `diagnose --decimate` (default auto); the table's decimate column says what was "
                                "asked, decimation_factor the factor used")
        else:
            p.set_defaults(passes=2, decimate=None)
        if name == "identify":
            p.add_argument("--method", default="auto", help="auto (batch-ml), batch-ml, ekf+rts, ekf, ukf")
        else:
            p.set_defaults(method="auto")
        if name != "virtual-sensing":
            p.add_argument("--salvage", action="store_true", help=cli_types.SALVAGE_HELP)
        else:
            p.set_defaults(salvage=False)
        p.add_argument("--out", type=Path, default=None, metavar="TABLE",
                       help="the table, .parquet or .csv, written as rows arrive (default: CSV on stdout, no "
                            "resume)")
        p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on this Dask cluster (tcp://host:port of `dask scheduler`) instead of a local one")
        p.add_argument("--workers", type=cli_types.positive_int, default=None, metavar="N",
                       help="worker processes of the local cluster (default: one per core)")
        p.add_argument("--force", action="store_true", help="recompute the recordings already ok in the table")
        p.add_argument("--plot", type=Path, default=None, metavar="FILE.png", help="also write the summary figure")
        p.add_argument("--x", choices=("speed", "date"), default="speed",
                       help="x axis of the coefficient figure: speed (rpm) or the recording's start date")
        p.add_argument("--no-progress", action="store_true", help="no progress bar")
        p.set_defaults(func=cmd_batch)
    p = batch.add_parser("plot", help="summary figure of a batch table")
    p.add_argument("table", type=Path, help="a table written by `batch ... --out`")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.png", help="figure (default: TABLE with .png)")
    p.add_argument("--x", choices=("speed", "date"), default="speed",
                   help="x axis of the coefficient figure: speed (rpm) or the recording's start date")
    p.set_defaults(func=cmd_batch_plot)
