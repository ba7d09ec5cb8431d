# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Public names of a subpackage, imported from their modules on first use (PEP 562).

A subpackage's ``__init__`` names its API once, in a ``{name: module}`` table; importing the
subpackage stays cheap (``rotor-estimator --help`` needs no numba, rosbags or scipy), and
``from rotor_estimator.core import load_rig_file`` imports ``core.config`` only.
"""
from __future__ import annotations

import importlib
from typing import Any, Callable


def lazy_exports(package: str, exports: dict[str, str]) -> Callable[[str], Any]:
    """The module ``__getattr__`` of ``package`` that resolves each name of ``exports`` from its module."""
    def __getattr__(name: str) -> Any:
        if name in exports:
            return getattr(importlib.import_module(exports[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
