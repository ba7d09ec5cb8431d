# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The ``rotor-estimator`` command line: :mod:`.main` builds the parser, one module per subcommand."""
from __future__ import annotations

from typing import TYPE_CHECKING

from rotor_estimator.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from rotor_estimator.cli.main import build_parser, main

_EXPORTS = {"main": "rotor_estimator.cli.main", "build_parser": "rotor_estimator.cli.main"}
__all__ = ["main", "build_parser"]
__getattr__ = lazy_exports(__name__, _EXPORTS)
