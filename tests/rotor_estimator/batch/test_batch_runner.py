# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The shared runner: a task that kills its worker process is an error outcome while the others finish;
results come back complete; importing the batch package or the CLI imports no dask."""
import functools
import math
import operator
import subprocess
import sys

import dask
import distributed  # noqa: F401 (loads the distributed config keys)

from rotor_estimator.batch.runner import map_ordered, run_tasks


def test_a_worker_crash_is_an_error_outcome_and_the_other_tasks_complete():
    """On a local cluster of 2 processes, one task calls os._exit (the worker dies): its outcome carries
    the KilledWorker error, the four others return their value.

    The crashing task waits 0.5 s before it exits: a worker reports finished tasks in batches, and a
    worker that died within milliseconds of finishing a task loses that result too (with no retries
    allowed, Dask then reports that innocent task as KilledWorker as well: a CI run saw this)."""
    crash = functools.partial(exec, "import os, time\ntime.sleep(0.5)\nos._exit(3)")
    items = [functools.partial(math.sqrt, float(k)) for k in range(4)] + [crash]
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        outcomes = list(run_tasks(operator.call, items, workers=2, progress=False))
    assert sorted(o.index for o in outcomes) == [0, 1, 2, 3, 4]
    by_index = {o.index: o for o in outcomes}
    assert [by_index[k].result for k in range(4)] == [0.0, 1.0, math.sqrt(2), math.sqrt(3)]
    assert by_index[4].result is None and "KilledWorker" in by_index[4].error


def test_map_ordered_keeps_the_items_order_in_process_and_on_a_cluster(dask_cluster):
    """`map_ordered` (the benchmarks' pool): the same list in the items' order, inline and on a cluster."""
    items = [functools.partial(math.sqrt, float(k)) for k in range(6)]
    inline = map_ordered(operator.call, items, workers=1)
    remote = map_ordered(operator.call, items, scheduler=dask_cluster.scheduler_address)
    assert inline == remote == [math.sqrt(k) for k in range(6)]


def test_a_local_clusters_workers_keep_glibcs_adaptive_malloc(monkeypatch):
    """The local cluster's workers start without Dask's MALLOC_TRIM_THRESHOLD_ (its nanny's default 65536),
    which turns off glibc's adaptive mmap threshold and made the diagnosis 1.45-1.75x slower in a worker; the
    one BLAS thread per worker stays. Dask's own default is left as it was outside the cluster's start.

    A nanny writes its variables into its own process's environment, which the workers it spawns inherit: an
    earlier cluster of this test process (another test's) leaves the value there, so it is removed first."""
    import os

    from rotor_estimator.batch.runner import PRE_SPAWN_ENVIRON

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)

    def worker_env():
        return os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OMP_NUM_THREADS"), \
            dask.config.get("distributed.worker.profile.enabled")

    assert dask.config.get(f"{PRE_SPAWN_ENVIRON}.MALLOC_TRIM_THRESHOLD_") == 65536  # Dask's default, as shipped
    out = map_ordered(operator.call, [worker_env, worker_env], workers=2, inline=False)
    assert out == [(None, "1", False), (None, "1", False)]  # and no profiler: it feeds only the dashboard
    assert dask.config.get(f"{PRE_SPAWN_ENVIRON}.MALLOC_TRIM_THRESHOLD_") == 65536


def test_the_cli_and_the_batch_package_import_no_dask():
    """`rotor-estimator replay` starts without dask: building the parser and importing the batch package
    (names only) load neither dask nor distributed nor pyarrow."""
    code = ("import sys\nfrom rotor_estimator.cli.main import build_parser\nbuild_parser()\n"
            "import rotor_estimator.batch, rotor_estimator.batch.tasks, rotor_estimator.batch.driver\n"
            "heavy = [m for m in ('dask', 'distributed', 'pyarrow') if m in sys.modules]\nassert not heavy, heavy\n")
    subprocess.run([sys.executable, "-c", code], check=True)
