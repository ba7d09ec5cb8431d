# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Process-pool workers of the benchmarks: the benchmarks now run on :mod:`rotor_estimator.batch.runner`,
whose workers call :func:`single_thread_worker` (kept here under its old name)."""
from __future__ import annotations

from rotor_estimator.batch.runner import single_thread_worker

__all__ = ["single_thread_worker"]
