# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Package exceptions, one place (rosbags style). Each message says what to do."""


class RotorEstimatorError(Exception):
    """Base class of every error this package raises on purpose (the CLI exits with ``exit_code``)."""

    exit_code = 2


class ConfigError(RotorEstimatorError, ValueError):
    """A configuration file or value is missing, has the wrong type, unit or range.

    The message names the field (dotted path, e.g. ``rig.shaft.mass_kg``).
    """


class InputError(RotorEstimatorError, ValueError):
    """Input data (samples, pulses, bag contents) cannot be used as given."""


class FilterDivergedError(RotorEstimatorError, RuntimeError):
    """The filter's covariance lost positive definiteness or its state became non-finite."""


class NoDataError(InputError):
    """The input was read but no sample could be used (no estimate exists): exit code 3."""

    exit_code = 3


class BagError(RotorEstimatorError):
    """A bag cannot be opened or read (missing, truncated, corrupt, wrong topics)."""


class OutputError(RotorEstimatorError):
    """An output file or directory cannot be written safely (a symbolic link, not a directory, no space)."""
