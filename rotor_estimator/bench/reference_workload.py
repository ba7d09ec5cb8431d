# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""A fixed reference computation, timed beside each diagnosis benchmark case in the same process.

A case's wall-clock seconds depend on the machine and on what else runs on it (two fresh seeds of the same search
gave medians of 80 s and 219 s on this shared machine). Dividing them by the seconds of a fixed computation
measured in the same process just before and just after the case gives a figure that does not: the case's cost in
*reference units*. The workload is NumPy only, seeded, and shares no numerical code with the package, so optimizing the
package changes the case's seconds and not the reference; its mix is the diagnosis's: many small dense solves
(interpreter- and call-bound, like the re-simulations' set-up) and tall Gram products (BLAS-bound, like the
projections), on one BLAS thread as the diagnosis runs.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

#: Small complex solves (8 x 8, the rigid model's resolvent) and tall Gram products (19 200 x 40: four channels
#: of 4 800 samples against 40 columns) in one run of the workload; about 0.1 s on the development machine.
SMALL_SOLVES = 400
GRAM_PRODUCTS = 12


def run_workload(seed: int = 0) -> float:
    """One run of the fixed workload; returns a checksum (so no step can be skipped as unused)."""
    from rotor_estimator.core.linear_filters import single_threaded_blas

    rng = np.random.default_rng(seed)
    a = rng.normal(size=(8, 8))
    b = rng.normal(size=(8, 4)) + 0j
    tall = rng.normal(size=(19200, 40))
    total = 0.0
    with single_threaded_blas():
        for i in range(SMALL_SOLVES):
            x = np.linalg.solve(1j * (1.0 + i % 5) * np.eye(8) - a, b)
            total += float(np.abs(x[0, 0]))
        for _ in range(GRAM_PRODUCTS):
            total += float(np.trace(tall.T @ tall))
    return total


def reference_seconds(repeats: int = 3, clock: Callable[[], float] = time.perf_counter) -> float:
    """The median seconds of ``repeats`` runs of :func:`run_workload` (the median: one run caught by a burst of
    other load does not set it)."""
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    times = []
    for _ in range(repeats):
        t0 = clock()
        run_workload()
        times.append(clock() - t0)
    return float(np.median(times))
