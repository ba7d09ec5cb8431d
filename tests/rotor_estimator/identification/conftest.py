# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures of the identification tests."""
import numpy as np
import pytest

from rotor_estimator.identification.problem import CoefficientModel, RigArrays


@pytest.fixture(scope="session")
def arrays(seed_rig):
    return RigArrays.build(seed_rig)


@pytest.fixture(scope="session")
def true8(seed_rig):
    return seed_rig.true_coefficients.as_array()


@pytest.fixture(scope="session")
def model8():
    return CoefficientModel()


@pytest.fixture(scope="session")
def r0(seed_rig_file):
    return seed_rig_file.estimator.initial_coefficients.as_array()


def relative(x, ref):
    return (np.asarray(x) - ref) / np.abs(ref)
