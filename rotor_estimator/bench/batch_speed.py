# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``bench batch``: wall time of a batch over short simulated recordings with 1 worker and with N, same
session; the ratio is the speed-up the local cluster gives on this machine."""
from __future__ import annotations

import dataclasses
import tempfile
import time
from pathlib import Path


def make_bags(folder: Path, count: int, duration_s: float = 0.1, first_seed: int = 1) -> list[str]:
    """``count`` imbalance+impact bags of ``duration_s`` simulated seconds (seeds from ``first_seed``)."""
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.core.simulator import paper_scenario, simulate
    from rotor_estimator.io.bags import write_input_bag

    rig = load_rig_file().rig
    scenario = dataclasses.replace(paper_scenario("imbalance+impact"), duration_s=duration_s)
    paths = []
    for k in range(count):
        path = folder / f"rec{k:03d}"
        write_input_bag(path, simulate(rig, scenario, seed=first_seed + k).recording)
        paths.append(str(path.resolve()))
    return paths


def truncated_bag(folder: Path, source: str) -> str:
    """A copy of the bag ``source`` whose MCAP file is cut in half (a recording interrupted mid-write)."""
    import shutil

    bad = folder / "truncated"
    shutil.copytree(source, bad)
    for f in bad.glob("*.mcap"):
        data = f.read_bytes()
        f.write_bytes(data[: len(data) // 2])
    return str(bad.resolve())


def run(count: int = 30, command: str = "replay", workers: tuple[int, ...] = (1, 2), duration_s: float = 0.1,
        rig_path: str | None = None, *, external_cluster: bool = False, corrupt: bool = False) -> dict:
    """Time ``batch COMMAND`` over ``count`` bags for each worker count; rows must agree across runs.

    ``external_cluster``: also run the set on a separately started LocalCluster (2 workers) reached by its
    address, and compare its rows; ``corrupt``: add a truncated bag to the set (it must be an error row)."""
    from rotor_estimator.batch.driver import run_batch
    from rotor_estimator.batch.table import same_values
    from rotor_estimator.batch.tasks import BatchOptions

    if command == "diagnose" and rig_path is None:
        from rotor_estimator.core.config import SEED_RIG_PATH

        rig_path = str(SEED_RIG_PATH)
    out: dict = {"recordings": count, "command": command, "duration_s": duration_s, "runs": []}
    options = BatchOptions(command, rig_path=rig_path)
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        paths = make_bags(Path(tmp), count, duration_s)
        if corrupt:
            paths.append(truncated_bag(Path(tmp), paths[0]))
        reference = None
        runs: list[tuple[str, int | None, str | None]] = [("local", n, None) for n in workers]
        cluster = None
        if external_cluster:
            import logging

            from distributed import LocalCluster

            cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=logging.CRITICAL)
            runs.append(("external LocalCluster by address", None, cluster.scheduler_address))
        try:
            for k, (kind, n, address) in enumerate(runs):
                t0 = time.perf_counter()
                s = run_batch(options, paths, Path(tmp) / f"t{k}.parquet", workers=n, scheduler=address,
                              progress=False)
                wall = time.perf_counter() - t0
                same = reference is None or (len(reference) == len(s.rows) and
                                             all(same_values(a, b) for a, b in zip(reference, s.rows)))
                reference = reference or s.rows
                out["runs"].append({"kind": kind, "workers": n if n is not None else 2, "wall_s": wall,
                                    "errors": s.errors, "rows_identical": same,
                                    "error_rows": [r["recording"].rsplit("/", 1)[-1] for r in s.rows
                                                   if r["status"] != "ok"],
                                    "task_seconds_sum": sum(r.get("seconds") or 0.0 for r in s.rows)})
        finally:
            if cluster is not None:
                cluster.close()
    base = out["runs"][0]["wall_s"]
    for r in out["runs"]:
        r["speedup_vs_first"] = base / r["wall_s"]
    return out


def format_result(r: dict) -> str:
    lines = [f"batch {r['command']} over {r['recordings']} simulated recordings ({r['duration_s']:g} s each):"]
    for x in r["runs"]:
        start = "cluster already running" if x["kind"] != "local" else "cluster start included"
        lines.append(f"  {x['kind']}, {x['workers']} worker(s): {x['wall_s']:.1f} s wall ({start}; tasks "
                     f"{x['task_seconds_sum']:.1f} s summed), {x['errors']} error(s), rows identical to the first "
                     f"run: {x['rows_identical']}, speed-up {x['speedup_vs_first']:.2f}x"
                     + (f", error rows: {', '.join(x['error_rows'])}" if x["error_rows"] else ""))
    return "\n".join(lines)
