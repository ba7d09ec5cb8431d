# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The benchmarks run their cases through the batch runner: the reproduction's Monte Carlo gives the same
numbers in this process and on a Dask cluster."""
import numpy as np

from rotor_estimator.bench.reproduce import run_case


def test_reproduction_monte_carlo_is_identical_inline_and_on_a_cluster(seed_rig_file, dask_cluster):
    """Three seeded runs of the imbalance+impact case: estimates, reported std and NIS equal bit for bit
    whether run here or by the 2 worker processes of a cluster (results kept in seed order)."""
    ticks = []
    here = run_case(seed_rig_file, "imbalance+impact", runs=3, first_seed=7)
    there = run_case(seed_rig_file, "imbalance+impact", runs=3, first_seed=7,
                     scheduler=dask_cluster.scheduler_address, progress=ticks.append)
    assert ticks == [1, 1, 1]
    np.testing.assert_array_equal(here.estimates, there.estimates)
    np.testing.assert_array_equal(here.reported_std, there.reported_std)
    np.testing.assert_array_equal(here.nis_mean, there.nis_mean)
    assert len({tuple(e) for e in here.estimates}) == 3  # three different noise draws
