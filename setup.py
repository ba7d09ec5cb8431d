# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""ament_python package that also installs with plain pip on a machine without ROS."""
import glob
import os

from setuptools import find_packages, setup

PACKAGE = "rotor_estimator"

setup(
    name=PACKAGE,
    version="0.1.0",
    description="Identify rotor-bearing stiffness and damping while the machine runs, "
                "and diagnose why model and rig disagree (ROS 2 + offline).",
    long_description=open("README.md").read() if os.path.exists("README.md") else "",
    long_description_content_type="text/markdown",
    license="Apache-2.0",
    python_requires=">=3.10",
    packages=find_packages(exclude=["tests", "tests.*"]),
    # py.typed: both packages ship their annotations (PEP 561), so users' type checkers read them.
    package_data={PACKAGE: ["rigs/*.yaml", "rotors/*.yaml", "py.typed"], "msg_adapters": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob.glob("launch/*.py")),
        (f"share/{PACKAGE}/config", glob.glob("config/*.yaml")),
    ] + [
        # every example bag folder keeps its layout under share/rotor_estimator/bags/
        (f"share/{PACKAGE}/{folder}", [p for p in glob.glob(f"{folder}/*") if os.path.isfile(p)])
        for folder in ["bags"] + sorted(d for d in glob.glob("bags/*") if os.path.isdir(d))
    ],
    install_requires=[
        "numpy>=1.24",
        "scipy>=1.10",
        "numba>=0.58",
        "filterpy>=1.4.5",
        "pyyaml>=6.0",
        "rosbags>=0.10",
        "mcap>=1.1",
        "mcap-ros2-support>=0.5",
        "tqdm>=4.60",
        "matplotlib>=3.6",
        "threadpoolctl>=3.1",
        "h5py>=3.8",  # HDF5 DAQ exports (import)
        # `rotor-estimator batch` and the benchmarks' worker pool: a local Dask cluster or a remote one
        # (imported only when a batch runs); the batch table as Parquet or CSV
        "dask>=2023.1",
        "distributed>=2023.1",
        "pyarrow>=12",
    ],
    extras_require={
        # A real rclpy from the ROS 2 Kilted wheels, for machines without a system ROS 2.
        # On a rig with ROS 2 installed (colcon), do not install this extra: the system rclpy is used.
        "ros": [
            "ros-rclpy",
            "ros-rmw-fastrtps-cpp",
            "ros-std-msgs",
            "ros-sensor-msgs",
            "ros-geometry-msgs",
            "ros-diagnostic-msgs",
            "ros-std-srvs",
        ],
        # Optional independent cross-check of the finite-element rotor (ROSS 2.3.0 needs plotly<6).
        "ross": ["ross-rotordynamics==2.3.0", "plotly<6"],
        # -n 2: the diagnosis tests take minutes each. ruff and mypy run in tests/test_linters.py and .ci/lint;
        # minor versions pinned because a new release adds checks (the config is in pyproject.toml).
        "test": ["pytest>=7", "pytest-xdist>=3.2", "ruff>=0.17,<0.18", "mypy>=2.4,<2.5"],
    },
    zip_safe=True,
    maintainer="rotor_estimator developers",
    maintainer_email="dev@rotor-estimator.invalid",
    entry_points={
        "console_scripts": [
            "rotor-estimator = rotor_estimator.cli.main:main",
            "estimator_node = rotor_estimator.ros.estimator_node:main",
            "simulator_node = rotor_estimator.ros.simulator_node:main",
            "virtual_sensing_node = rotor_estimator.ros.virtual_sensing_node:main",
        ],
    },
)
