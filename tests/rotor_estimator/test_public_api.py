# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The subpackages' public API: what ``__all__`` promises resolves, and naming it costs no heavy import."""
import importlib
import subprocess
import sys

import pytest

SUBPACKAGES = ["rotor_estimator.core", "rotor_estimator.io", "rotor_estimator.virtual_sensing",
               "rotor_estimator.cli", "rotor_estimator.identification", "rotor_estimator.diagnosis",
               "rotor_estimator.diagnosis.effects", "rotor_estimator.batch"]


@pytest.mark.parametrize("name", SUBPACKAGES)
def test_every_name_in_all_resolves_to_a_public_object_of_the_package(name):
    """Each ``__all__`` entry is reachable as an attribute, public (no leading underscore), and listed once."""
    package = importlib.import_module(name)
    assert package.__all__ and len(set(package.__all__)) == len(package.__all__)
    for attr in package.__all__:
        assert not attr.startswith("_")
        assert getattr(package, attr) is not None, f"{name}.{attr}"
    with pytest.raises(AttributeError, match="no attribute"):
        package.no_such_name  # noqa: B018 (the lookup itself is what is tested)


def test_importing_the_core_package_imports_none_of_its_modules_until_a_name_is_used():
    """``import rotor_estimator.core`` loads no numba, scipy or rosbags; using ``load_rig_file`` loads only
    ``core.config`` (lazy exports, so ``rotor-estimator --help`` stays fast)."""
    code = ("import sys, rotor_estimator.core as c, rotor_estimator.io\n"
            "heavy = [m for m in ('numba', 'scipy', 'rosbags', 'rotor_estimator.core.ekf') if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "c.load_rig_file\n"
            "assert 'rotor_estimator.core.config' in sys.modules and 'rotor_estimator.core.ekf' not in sys.modules\n")
    subprocess.run([sys.executable, "-c", code], check=True)
