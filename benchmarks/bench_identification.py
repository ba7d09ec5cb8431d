#!/usr/bin/env python3
# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Identification benchmark as a script (same as ``rotor-estimator bench identification``).

EKF, UKF, EKF + RTS and batch output-error ML, over seeded runs of: the seed's
imbalance+impact case, the seed's imbalance-only case, 0.5 s and 2 s coast-downs
20000 -> 3000 rpm (imbalance known and unknown) and 5 impacts alternating x/y in 1 s.
Prints bias/CRLB, spread/CRLB and run time per scenario and method.

    python benchmarks/bench_identification.py --runs 20 --jobs 2 [--json]

About 9 minutes with ``--jobs 2`` on a 2-core machine for 20 runs (the UKF is ~75%
of it; ``--methods ekf ekf+rts batch-ml`` takes ~3 minutes).
"""
import sys

from rotor_estimator.cli.identify import add_bench_parsers


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(prog="bench_identification")
    add_bench_parsers(parser.add_subparsers(dest="bench", required=True))
    args = parser.parse_args(["identification", *(sys.argv[1:] if argv is None else argv)])
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
