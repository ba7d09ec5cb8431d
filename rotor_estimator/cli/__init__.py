# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The ``rotor-estimator`` command line: :mod:`.main` builds the parser, one module per subcommand."""
