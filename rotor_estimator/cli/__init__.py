# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""cli"""
