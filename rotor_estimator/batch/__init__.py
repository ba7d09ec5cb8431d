# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Many recordings, one table: a command over every recording on Dask (local processes by default).

Dask is imported only when a batch runs (:mod:`.runner`), so importing this package is cheap.
"""
from __future__ import annotations

from rotor_estimator.lazy_exports import lazy_exports

# No TYPE_CHECKING imports of the modules: the benchmarks import batch.runner, and batch.tasks imports
# what the benchmarks define (the .npz recording format), so naming the modules here would close a cycle.
_EXPORTS = {"BatchSummary": "rotor_estimator.batch.driver", "run_batch": "rotor_estimator.batch.driver",
            "TaskOutcome": "rotor_estimator.batch.runner", "map_ordered": "rotor_estimator.batch.runner",
            "run_tasks": "rotor_estimator.batch.runner", "columns": "rotor_estimator.batch.table",
            "read_table": "rotor_estimator.batch.table", "write_table": "rotor_estimator.batch.table",
            "BatchOptions": "rotor_estimator.batch.tasks", "expand_inputs": "rotor_estimator.batch.tasks",
            "run_row": "rotor_estimator.batch.tasks"}
__all__ = ["BatchSummary", "run_batch", "TaskOutcome", "map_ordered", "run_tasks", "columns", "read_table",
           "write_table", "BatchOptions", "expand_inputs", "run_row"]
__getattr__ = lazy_exports(__name__, _EXPORTS)
