# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""What the commands share: argparse ``type=`` callables that refuse out-of-range numbers with a message
naming the range, the bag argument, and the progress bar.

argparse turns :class:`argparse.ArgumentTypeError` into ``<prog>: error: argument --seed: ...``
and exit status 2, so ``--seed -1`` or ``--passes 0`` never reach the numerical code (where they
used to end in a numpy traceback or a silent zero-pass run).
"""
from __future__ import annotations

import argparse
import math
import sys
from typing import Any, Callable

import numpy as np

#: Help of --salvage, the same for every command that reads a bag.
SALVAGE_HELP = ("use the intact part of a damaged bag (the messages lost are counted and reported on stderr); "
                "without it a damaged bag is an error")
#: Seeds are non-negative (numpy's SeedSequence refuses negatives); 32 bits, as numpy's legacy seeding.
SEED_MAX = 2**32 - 1
#: EstimatorConfig.passes allows 1 to 20 (config.EstimatorConfig.validate).
PASSES_MAX = 20


def int_in_range(low: int, high: int | None, what: str) -> Callable[[str], int]:
    """A type accepting a decimal integer in ``[low, high]`` (``high`` None: no upper bound)."""
    span = f"from {low} to {high}" if high is not None else f">= {low}"

    def parse(text: str) -> int:
        try:
            value = int(text.strip(), 10)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, an integer {span}; got {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"{what} must be an integer {span}, got {value}")
        return value

    parse.__name__ = what.replace(" ", "_")  # argparse names the type in some messages
    return parse


#: ``--seed``: a noise seed, 0 to 2^32 - 1.
seed = int_in_range(0, SEED_MAX, "a seed")
#: ``--passes``: EKF passes over the data, 1 to 20.
passes = int_in_range(1, PASSES_MAX, "the number of passes")
#: A count that must be at least 1 (``--samples``, ``--runs``...).
positive_int = int_in_range(1, None, "a positive count")


def decimation(text: str) -> int | str:
    """``--decimate``: ``auto`` or a positive integer factor."""
    if text.strip() == "auto":
        return "auto"
    try:
        return positive_int(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected auto or a positive integer factor, got {text!r}") from None


#: A count that may be 0 (``--burn-in``).
non_negative_int = int_in_range(0, None, "a count")


def add_bag_argument(parser: argparse.ArgumentParser, help_text: str) -> None:
    """The input bag of a one-bag command, as ``BAG`` or ``--bag BAG`` (as `identify` and
    `virtual-sensing` take it): one spelling works everywhere."""
    parser.add_argument("bag", nargs="?", metavar="BAG", default=None, help=help_text)
    parser.add_argument("--bag", dest="bag_option", metavar="BAG", default=None, help="the same, as an option")


def bag_from_args(args: argparse.Namespace) -> str:
    """The bag given as ``BAG`` or ``--bag`` (exactly one of them)."""
    from rotor_estimator.core.errors import InputError

    given = [b for b in (args.bag, getattr(args, "bag_option", None)) if b is not None]
    if len(given) != 1:
        raise InputError("give the input bag once, as BAG or --bag BAG" if given else
                         "no input bag: give BAG or --bag BAG")
    return str(given[0])


def progress_bar(total: int, desc: str, enabled: bool = True) -> Any:
    """A tqdm progress bar on stderr (``enabled=False``, ``--no-progress`` or ``TQDM_DISABLE``: silent)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, file=sys.stderr, disable=not enabled, leave=False)


def json_default(value: Any) -> Any:
    """``json.dumps(default=...)``: numpy scalars as numbers, NaN and infinities as ``null``."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(type(value).__name__)
