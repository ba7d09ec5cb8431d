# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Virtual sensing (Neisi et al. 2022): the orbit of a flexible rotor at stations without probes, offline and live."""
