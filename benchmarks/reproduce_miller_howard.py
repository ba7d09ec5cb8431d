#!/usr/bin/env python3
# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Accuracy: Miller & Howard Table 3 side by side with ours and the CRLB.

Same as ``rotor-estimator reproduce miller-howard [--runs N] [--json] [--plots DIR]``. Targets
(imbalance+impact, >= 20 runs): |bias| < 0.5 CRLB and spread < 1.3 CRLB for every coefficient.
"""
import sys

from rotor_estimator.cli.main import main

if __name__ == "__main__":
    sys.exit(main(["reproduce", "miller-howard", *sys.argv[1:]]))
