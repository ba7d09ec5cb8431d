# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Fixtures of the batch tests: a few short simulated bags (0.1 s, replay takes about a second each) and
a real Dask cluster (scheduler + 2 worker processes) reached by its address."""
import dataclasses
import shutil

import pytest

from rotor_estimator.core.simulator import paper_scenario, simulate
from rotor_estimator.io.bags import write_input_bag

SEEDS = (1, 2, 3)


@pytest.fixture(scope="session")
def short_bags(tmp_path_factory, seed_rig):
    """Three 0.1 s imbalance+impact bags (seeds 1-3) in one folder, and the recordings they hold."""
    folder = tmp_path_factory.mktemp("batch_bags")
    scenario = dataclasses.replace(paper_scenario("imbalance+impact"), duration_s=0.1)
    recordings = {}
    for seed in SEEDS:
        rec = simulate(seed_rig, scenario, seed=seed).recording
        path = folder / f"run{seed}"
        write_input_bag(path, rec)
        recordings[str(path.resolve())] = rec
    return folder, recordings


@pytest.fixture
def bag_copy(short_bags, tmp_path):
    """A private copy of the bag folder (a test may damage or add files)."""
    folder = tmp_path / "bags"
    shutil.copytree(short_bags[0], folder)
    return folder


@pytest.fixture(scope="session")
def dask_cluster():
    """A distributed.LocalCluster with its own scheduler and 2 single-thread worker processes."""
    import logging

    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                           silence_logs=logging.CRITICAL)
    yield cluster
    cluster.close()
