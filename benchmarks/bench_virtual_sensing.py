#!/usr/bin/env python3
# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Paper-scale virtual-sensing benchmark (Neisi et al. 2022: UKF, 150 states, 8 observations,
8192 samples, "more than eight hours").

Same code as ``rotor-estimator bench virtual-sensing``::

    python benchmarks/bench_virtual_sensing.py [--json] [--samples 8192] [--alpha 0.01]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rotor_estimator.cli.virtual_sensing import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["bench", "virtual-sensing", *sys.argv[1:]]))
