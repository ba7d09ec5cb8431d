# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Identification beyond the seed: imbalance-only sweeps, four methods, speed-dependent and
16-coefficient models, the excitation planner and the identifiability report.

Pure numerics (no ROS). Modules:

* :mod:`.problem` -- rig arrays, coefficient parameterization, test records;
* :mod:`.scenarios` -- test designs (sweeps, impacts, dwells, trial weights) and their simulation;
* :mod:`.information` -- Fisher information / CRLB of the generalized model;
* :mod:`.batch_ml`, :mod:`.kalman`, :mod:`.methods` -- the estimators and the defaults;
* :mod:`.speed_dependent`, :mod:`.bearings16` -- the extended models;
* :mod:`.planner` -- CRLB of candidate tests and the recommendation;
* :mod:`rotor_estimator.core.identifiability` -- what the data received determine (shared with replay).
"""
from rotor_estimator.core.identifiability import (IdentifiabilityReport, Thresholds, report_from_filter,
                                                  report_from_information)
from rotor_estimator.identification.methods import DEFAULT_LIVE, DEFAULT_OFFLINE, METHODS, identify
from rotor_estimator.identification.planner import Target, plan
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays, record_from_recording

__all__ = ["CoefficientModel", "Record", "RigArrays", "record_from_recording", "identify", "METHODS",
           "DEFAULT_OFFLINE", "DEFAULT_LIVE", "plan", "Target", "IdentifiabilityReport", "Thresholds",
           "report_from_filter", "report_from_information"]
