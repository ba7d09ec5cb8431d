# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Every ``--seed`` and ``--passes`` of the command line refuses out-of-range values in argparse
(one error line naming the range, exit 2) instead of a numpy traceback or a zero-pass run."""
from __future__ import annotations

import argparse

import pytest

from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.cli.main import build_parser, main


def _subparsers(parser: argparse.ArgumentParser, path=()):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subparsers(sub, (*path, name))


def _options(flag):
    return [(path, sub, a) for path, sub in _subparsers(build_parser()) for a in sub._actions
            if flag in a.option_strings]


def test_every_seed_and_passes_option_uses_the_range_checked_type():
    """All commands that take --seed (reproduce, simulate, identify, bench identify/diagnosis,
    virtual-sensing, bench virtual-sensing) and --passes (diagnose) parse them with cli_types."""
    seeds, passes = _options("--seed"), _options("--passes")
    assert len(seeds) >= 6 and passes
    for path, _, action in seeds:
        assert action.type is cli_types.seed, " ".join(path)
    for path, _, action in passes:
        assert action.type is cli_types.passes, " ".join(path)


@pytest.mark.parametrize("flag, value, message", [
    ("--seed", "-1", "a seed must be an integer from 0 to 4294967295, got -1"),
    ("--seed", "4294967296", "a seed must be an integer from 0 to 4294967295, got 4294967296"),
    ("--seed", "1.5", "expected a seed, an integer from 0 to 4294967295; got '1.5'"),
    ("--passes", "0", "the number of passes must be an integer from 1 to 20, got 0"),
    ("--passes", "-3", "the number of passes must be an integer from 1 to 20, got -3"),
])
def test_out_of_range_value_exits_2_with_one_error_line(capsys, flag, value, message):
    """Each command taking the option exits 2 with '<prog>: error: argument <flag>: <range>' and
    no traceback; 0 and the limits themselves are accepted."""
    for path, _sub, _ in _options(flag):
        with pytest.raises(SystemExit) as info:
            main([*path, flag, value])
        err = capsys.readouterr().err
        assert info.value.code == 2, path
        assert f"error: argument {flag}: {message}" in err, (path, err)
        assert "Traceback" not in err
    assert cli_types.seed("0") == 0 and cli_types.seed(str(2**32 - 1)) == 2**32 - 1
    assert cli_types.passes("1") == 1 and cli_types.passes("20") == 20


def test_virtual_sensing_counts_are_checked():
    """--samples 0 and --burn-in -1 of virtual-sensing are refused by argparse."""
    for argv, text in ((["virtual-sensing", "--samples", "0"], "--samples"),
                       (["virtual-sensing", "--burn-in", "-1"], "--burn-in")):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 2, text
