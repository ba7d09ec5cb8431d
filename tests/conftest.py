"""Shared fixtures: the seed rig and small simulations."""
import pytest

from rotor_estimator.config import load_rig_file
from rotor_estimator.simulator import paper_scenario, simulate


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
