# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures: the seed rig and small simulations."""
import pytest

from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.simulator import paper_scenario, simulate


@pytest.fixture(scope="session", autouse=True)
def one_blas_thread_per_worker():
    """BLAS on one thread in every test process: the README's test command runs one xdist worker per core,
    so BLAS threads on top only oversubscribe the cores. The small matrices of the fits gain nothing from
    them: with two BLAS threads per worker a test fitting outside ``rank_effects`` (which limits itself) ran
    2.2x slower. Tests that check a thread limit set their own with ``threadpool_limits``.

    SciPy's wheels bring their own OpenBLAS, loaded with ``scipy.linalg``: it is loaded first, since a limit acts
    only on the libraries already loaded."""
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits  # a dependency of the package (setup.py)

    with threadpool_limits(limits=1, user_api="blas"):
        yield


@pytest.fixture(scope="session")
def seed_rig_file():
    return load_rig_file()


@pytest.fixture(scope="session")
def seed_rig(seed_rig_file):
    return seed_rig_file.rig


@pytest.fixture(scope="session")
def impact_sim(seed_rig):
    """The paper's imbalance+impact case, one seeded run."""
    return simulate(seed_rig, paper_scenario("imbalance+impact"), seed=11)


@pytest.fixture(scope="session")
def cli_peak_rss():
    """Run ``rotor-estimator ARGS`` in a fresh process; return (stdout, its own peak RSS in MB).

    The peak is the child's VmHWM: ``ru_maxrss`` would carry the forking pytest worker's peak
    over exec and measure the worker, not the command."""
    import os
    import subprocess
    import sys

    def run(args: list[str]) -> tuple[str, float]:
        code = ("import sys\n"
                "from rotor_estimator.cli.main import main\n"
                f"rc = main({list(map(str, args))!r})\n"
                "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM:')][0].split()[1]\n"
                "print('PEAK_RSS_KB', hwm, file=sys.stderr)\n"
                "sys.exit(rc)\n")
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1200,
                              env={**os.environ, "OMP_NUM_THREADS": "1"})
        assert done.returncode == 0, done.stderr[-2000:]
        return done.stdout, int(done.stderr.split("PEAK_RSS_KB")[1].split()[0]) / 1024.0

    return run
