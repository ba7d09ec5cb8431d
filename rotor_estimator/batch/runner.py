# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Run one function over many items on Dask: a local cluster of processes by default, or an existing
``distributed`` cluster given by its scheduler address. Used by ``rotor-estimator batch`` and the benchmarks.

Every worker runs one task at a time with one BLAS thread (``N`` workers on ``N`` cores, no
oversubscription). Dask is imported here only when a batch runs, so the other commands start fast.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from typing import Any, Callable, Generator, Sequence

from rotor_estimator.core.errors import InputError


@dataclass(frozen=True)
class TaskOutcome:
    """One item's result (``error`` None) or failure (``result`` None, ``error`` the exception's text)."""

    index: int
    item: Any
    result: Any
    error: str | None


def default_workers() -> int:
    """Worker processes of the local cluster: one per core."""
    return max(1, os.cpu_count() or 1)


def single_thread_worker() -> None:
    """One BLAS thread in this process (``N`` workers on ``N`` cores, no oversubscription): the thread
    environment variables for libraries loaded later, threadpoolctl for those already loaded."""
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[k] = "1"
    try:
        from threadpoolctl import threadpool_limits

        globals()["LIMITS"] = threadpool_limits(1)
    except ImportError:
        pass


def _single_thread_plugin() -> Any:
    """A worker plugin that limits BLAS to one thread in each worker (also on a remote cluster)."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class SingleThreadBlas(WorkerPlugin):
        name = "rotor-estimator-single-thread-blas"

        def setup(self, worker: Any) -> None:
            single_thread_worker()

    return SingleThreadBlas()


#: Dask's configuration of the environment its nanny sets before it starts a worker process.
PRE_SPAWN_ENVIRON = "distributed.nanny.pre-spawn-environ"


def open_client(workers: int | None = None, scheduler: str | None = None) -> tuple[Any, Any]:
    """(client, local cluster or None): connect to ``scheduler`` or start a local cluster of ``workers``
    processes with one thread and one BLAS thread each, without Dask's ``MALLOC_TRIM_THRESHOLD_`` and worker
    profiler (see the comment below)."""
    import logging
    import warnings

    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - a dependency of the package
        raise InputError(f"batch runs need dask.distributed ({exc}); pip install 'dask[distributed]'") from exc
    cluster = None
    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise InputError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    else:
        n = default_workers() if workers is None else int(workers)
        if n < 1:
            raise InputError(f"--workers must be >= 1, got {n}")
        import dask

        env = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
        # Dask's nanny starts each worker with MALLOC_TRIM_THRESHOLD_=65536 (to hand freed memory back to the OS);
        # setting it also turns off glibc's adaptive mmap threshold, so every array of more than 128 kB (a record's
        # re-simulation, a design matrix) is mapped and zeroed afresh: the same diagnosis ran 1.3x slower in a plain
        # process with that variable alone, and 1.45-1.75x slower in a worker that had it. The workers' statistical
        # profiler (every 10 ms) feeds only the dashboard, which this cluster does not start.
        quiet = {f"{PRE_SPAWN_ENVIRON}.MALLOC_TRIM_THRESHOLD_": None, "distributed.worker.profile.enabled": False}
        with warnings.catch_warnings(), dask.config.set(quiet):
            # "Port 8787 is already in use": another cluster's dashboard, harmless
            warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=logging.CRITICAL, env=env)
        client = Client(cluster)
    try:
        client.register_plugin(_single_thread_plugin())
    except BaseException:
        close_client(client, cluster)
        raise
    return client, cluster


def close_client(client: Any, cluster: Any) -> None:
    """Close the client and the local cluster it started (never a remote cluster)."""
    try:
        client.close()
    finally:
        if cluster is not None:
            cluster.close()


def _error_text(exc: BaseException) -> str:
    text = str(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def run_tasks(fn: Callable[[Any], Any], items: Sequence[Any], *, workers: int | None = None,
              scheduler: str | None = None, progress: bool = True, desc: str = "batch", inline: bool = False,
              raise_errors: bool = False, client: Any = None) -> Generator[TaskOutcome, None, None]:
    """Yield a :class:`TaskOutcome` for ``fn(item)`` of every item, in the order they finish.

    ``fn`` must be importable (a module-level function). ``inline``: run here, one after the other (no
    cluster). A task that raises, or whose worker dies, gives an outcome with ``error`` (``raise_errors``:
    the exception propagates instead). ``client``: an open :func:`open_client` client to reuse.
    Close the iterator (or exhaust it) to shut the local cluster down."""
    from tqdm import tqdm

    items = list(items)
    with tqdm(total=len(items), desc=desc, file=sys.stderr, disable=not progress, leave=False) as bar:
        if inline:
            for i, item in enumerate(items):
                try:
                    result = fn(item)
                except Exception as exc:
                    if raise_errors:
                        raise
                    yield TaskOutcome(i, item, None, _error_text(exc))
                else:
                    yield TaskOutcome(i, item, result, None)
                bar.update()
            return
        from distributed import as_completed

        own = client is None
        cluster = None
        if own:
            client, cluster = open_client(workers, scheduler)
        futures = []
        try:
            name = getattr(fn, "__name__", "task")
            futures = [client.submit(fn, item, pure=False, key=f"{name}-{i}-{os.getpid()}-{id(items)}")
                       for i, item in enumerate(items)]
            index = {f.key: i for i, f in enumerate(futures)}
            for fut in as_completed(futures):
                i = index[fut.key]
                try:
                    result = fut.result()
                except Exception as exc:  # the task raised, or its worker died (KilledWorker)
                    if raise_errors:
                        raise
                    outcome = TaskOutcome(i, items[i], None, _error_text(exc))
                else:
                    outcome = TaskOutcome(i, items[i], result, None)
                fut.release()
                bar.update()
                yield outcome
        finally:
            if futures:
                client.cancel([f for f in futures if not f.done()])
            if own:
                close_client(client, cluster)


def iter_ordered(fn: Callable[[Any], Any], items: Sequence[Any], *, workers: int = 1, scheduler: str | None = None,
                 inline: bool | None = None) -> Generator[Any, None, None]:
    """``fn(item)`` for each item through :func:`run_tasks`, yielded in the items' order as soon as every
    earlier one is done; the first error propagates. ``inline`` None: in this process when ``workers`` is 1
    and no scheduler is given (as the benchmarks ran before), else on a cluster."""
    items = list(items)
    if inline is None:
        inline = workers <= 1 and not scheduler
    done: dict[int, Any] = {}
    nxt = 0
    results = run_tasks(fn, items, workers=workers, scheduler=scheduler, progress=False, inline=inline,
                        raise_errors=True)
    try:
        for o in results:
            done[o.index] = o.result
            while nxt in done:
                yield done.pop(nxt)
                nxt += 1
    finally:
        results.close()


def map_ordered(fn: Callable[[Any], Any], items: Sequence[Any], *, workers: int = 1, scheduler: str | None = None,
                inline: bool | None = None, progress: Callable[[int], Any] | None = None) -> list[Any]:
    """``[fn(item) for item in items]`` through :func:`iter_ordered`; ``progress(1)`` after each result
    in order."""
    out = []
    for r in iter_ordered(fn, items, workers=workers, scheduler=scheduler, inline=inline):
        out.append(r)
        if progress:
            progress(1)
    return out


def call(thunk: Callable[[], Any]) -> Any:
    """``thunk()``: runs ``functools.partial`` tasks of different functions through one runner."""
    return thunk()


def worker_name() -> str:
    """The Dask worker running this task (its address), or ``local pid N`` outside a Dask worker."""
    if "distributed" in sys.modules:
        try:
            from distributed import get_worker

            return str(get_worker().address)
        except ValueError:
            pass
    return f"local pid {os.getpid()}"
