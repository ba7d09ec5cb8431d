# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Optional numba JIT: compiled when numba is importable, plain Python otherwise.

numba is a declared dependency; the fallback only keeps the package importable
(and correct, though slow) on a platform without a numba wheel.
"""
from __future__ import annotations

try:  # pragma: no cover - exercised by the environment, not by a test
    from numba import njit as _numba_njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    HAVE_NUMBA = False
    _numba_njit = None


def njit(*args, **kwargs):
    """``numba.njit`` when available (with ``cache`` and ``fastmath=False``), else identity."""
    if HAVE_NUMBA:
        kwargs.setdefault("cache", True)
        return _numba_njit(*args, **kwargs)
    if args and callable(args[0]):
        return args[0]
    return lambda f: f
