# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Subcommands of ``rotor-estimator`` that live in their own modules.

Each module exposes ``add_parsers(subparsers)`` and, if it has benchmarks,
``add_bench_parsers(bench_subparsers)``; handlers set ``func`` and return an exit code.
"""
from __future__ import annotations

import importlib

COMMAND_MODULES = ("bag_commands", "import_data", "diagnose", "identify")


def _modules():
    for name in COMMAND_MODULES:
        try:
            yield importlib.import_module(f"rotor_estimator.cli.{name}")
        except ModuleNotFoundError as exc:  # a module still under construction
            if exc.name != f"{__name__}.{name}":
                raise


def add_parsers(subparsers) -> None:
    for module in _modules():
        module.add_parsers(subparsers)


def add_bench_parsers(bench_subparsers) -> None:
    for module in _modules():
        if hasattr(module, "add_bench_parsers"):
            module.add_bench_parsers(bench_subparsers)
