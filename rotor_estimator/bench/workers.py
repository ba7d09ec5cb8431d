# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Process-pool workers of the benchmarks."""
from __future__ import annotations


def single_thread_worker() -> None:
    """Pool initializer: one BLAS thread per worker (``jobs`` workers on ``jobs`` cores, no oversubscription)."""
    import os

    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[k] = "1"
    try:
        from threadpoolctl import threadpool_limits

        globals()["LIMITS"] = threadpool_limits(1)
    except ImportError:
        pass
