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


def run(count: int = 30, command: str = "replay", workers: tuple[int, ...] = (1, 2), duration_s: float = 0.1,
        rig_path: str | None = None) -> dict:
    """Time ``batch COMMAND`` over ``count`` bags for each worker count; rows must agree across runs."""
    from rotor_estimator.batch.driver import run_batch
    from rotor_estimator.batch.table import same_values
    from rotor_estimator.batch.tasks import BatchOptions

    if command == "diagnose" and rig_path is None:
        from rotor_estimator.core.config import SEED_RIG_PATH

        rig_path = str(SEED_RIG_PATH)
    out: dict = {"recordings": count, "command": command, "duration_s": duration_s, "runs": []}
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        paths = make_bags(Path(tmp), count, duration_s)
        reference = None
        for n in workers:
            t0 = time.perf_counter()
            s = run_batch(BatchOptions(command, rig_path=rig_path), paths, Path(tmp) / f"t{n}.parquet",
                          workers=n, progress=False)
            wall = time.perf_counter() - t0
            same = reference is None or all(same_values(a, b) for a, b in zip(reference, s.rows))
            reference = reference or s.rows
            out["runs"].append({"workers": n, "wall_s": wall, "errors": s.errors, "rows_identical": same,
                                "task_seconds_sum": sum(r.get("seconds") or 0.0 for r in s.rows)})
    base = out["runs"][0]["wall_s"]
    for r in out["runs"]:
        r["speedup_vs_first"] = base / r["wall_s"]
    return out


def format_result(r: dict) -> str:
    lines = [f"batch {r['command']} over {r['recordings']} simulated recordings ({r['duration_s']:g} s each):"]
    for x in r["runs"]:
        lines.append(f"  {x['workers']} worker(s): {x['wall_s']:.1f} s wall (cluster start included; tasks "
                     f"{x['task_seconds_sum']:.1f} s summed), {x['errors']} error(s), rows identical to the first "
                     f"run: {x['rows_identical']}, speed-up {x['speedup_vs_first']:.2f}x")
    return "\n".join(lines)
