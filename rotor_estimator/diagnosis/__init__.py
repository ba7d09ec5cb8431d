# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Sim-to-real gap diagnosis: where the residual lies, which unmodelled effect causes it, how far it shrinks.

No ROS imports (bags are read by :mod:`rotor_estimator.cli.diagnose`). Entry point:
:func:`diagnose`; report: :func:`rotor_estimator.diagnosis.report.write_report`; blind cases:
:mod:`rotor_estimator.bench.blind` (and :mod:`rotor_estimator.bench.ross_cases` when ROSS is installed).
"""
from rotor_estimator.diagnosis.api import Diagnosis, diagnose
from rotor_estimator.diagnosis.effects import EFFECT_NAMES, LIBRARY, effect_by_name

__all__ = ["Diagnosis", "diagnose", "EFFECT_NAMES", "LIBRARY", "effect_by_name"]
