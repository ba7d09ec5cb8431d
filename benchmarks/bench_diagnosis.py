#!/usr/bin/env python3
# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Blind benchmark of the sim-to-real diagnosis (a script, not a test; about 50 min for 36 cases on 2 cores).

    .venv/bin/python benchmarks/bench_diagnosis.py --cases 36 --seed 2024 [--out DIR] [--jobs 2] [--no-ross] [--json]

Same as ``rotor-estimator bench diagnosis``.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings


def main(argv: list[str] | None = None) -> int:
    import os

    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one BLAS thread per worker
        os.environ.setdefault(k, "1")
    from rotor_estimator.bench.diagnosis import format_score, run

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=36)
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--out", default=None, help="keep the blind set, labels and results in this directory")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--no-ross", action="store_true", help="skip the ROSS-generated cases")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    warnings.simplefilter("ignore")
    s = run(a.cases, a.seed, a.out, jobs=a.jobs, use_ross=not a.no_ross,
            progress=lambda cid: print(f"generated {cid}", file=sys.stderr, flush=True))
    print(json.dumps({k: v for k, v in s.items() if k != "rows"}, indent=1) if a.json else format_score(s))
    return 0


if __name__ == "__main__":
    sys.exit(main())
