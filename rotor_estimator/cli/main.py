# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator``: the command-line entry point (argparse, one handler per subcommand).

Every subcommand is a thin shell over library functions; heavy imports happen inside
the handlers so ``rotor-estimator --help`` is instant.
"""
from __future__ import annotations

import argparse
import os
import sys

from rotor_estimator.cli import (batch, bench, diagnose, identify, import_data, plan, replay, reproduce, simulate,
                                 virtual_sensing)
from rotor_estimator.core.errors import RotorEstimatorError

#: The subcommands, in the order ``--help`` lists them; each module has ``add_parser(subparsers)``.
COMMANDS = (reproduce, bench, replay, simulate, import_data, diagnose, plan, identify, virtual_sensing, batch)


# ---------------------------------------------------------------------------------- parser
def _version() -> str:
    """The installed distribution's version (the package's own when run from a source tree)."""
    from importlib.metadata import PackageNotFoundError, version

    from rotor_estimator import __version__

    try:
        return version("rotor_estimator")
    except PackageNotFoundError:
        return __version__


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rotor-estimator",
        description="Identify rotor-bearing stiffness and damping (EKF) and diagnose model-vs-rig gaps. "
                    "All values SI.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}",
                        help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(sub)
    for leaf in _leaf_parsers(parser):
        if not any("--no-progress" in a.option_strings for a in leaf._actions):
            leaf.add_argument("--no-progress", action="store_true", help=SHARED_OPTION_HELP["--no-progress"])
        for action in leaf._actions:
            if not action.help and action.option_strings and action.option_strings[-1] in SHARED_OPTION_HELP:
                action.help = SHARED_OPTION_HELP[action.option_strings[-1]]
    return parser


# One wording for the options every command shares (used where a command gives none of its own).
SHARED_OPTION_HELP = {
    "--json": "print machine-readable JSON (SI units) instead of the text table",
    "--rig": "rig YAML file (default: the bundled Miller & Howard seed rig)",
    "--seed": "random seed, an integer from 0 to 2^32 - 1 (default %(default)s)",
    "--no-progress": "no progress bar on stderr",
}


def _leaf_parsers(parser: argparse.ArgumentParser):
    """Every command's own parser (the leaves of the subcommand tree)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield parser
    for action in subs:
        for child in dict.fromkeys(action.choices.values()):  # aliases map to the same parser
            yield from _leaf_parsers(child)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.no_progress:
        os.environ["TQDM_DISABLE"] = "1"  # every tqdm bar, also those deep in library code
    try:
        return int(args.func(args) or 0)
    except RotorEstimatorError as exc:
        print(f"rotor-estimator: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("rotor-estimator: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
