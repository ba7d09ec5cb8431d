# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The command-line entry point: version and option help."""
import pytest

from rotor_estimator import __version__
from rotor_estimator.cli.main import main


def test_version_prints_the_package_version(capsys):
    """`--version` exits 0 and prints the same version as the package and setup.py."""
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"rotor-estimator {__version__}"


def test_package_xml_and_package_agree_on_the_version():
    """package.xml (colcon, rosdep) and rotor_estimator.__version__ (pip, --version) name one version."""
    import xml.etree.ElementTree as ET
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    assert ET.parse(root / "package.xml").getroot().findtext("version") == __version__
    assert f'version="{__version__}"' in (root / "setup.py").read_text()


def _commands(parser=None, prefix=()):
    """Every leaf command's parser, with its command words."""
    import argparse

    from rotor_estimator.cli.main import build_parser

    parser = parser or build_parser()
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield prefix, parser
        return
    for name, child in subs[0].choices.items():
        yield from _commands(child, prefix + (name,))


def test_every_option_of_every_command_has_help_text():
    """`--help` explains every option: no option is listed without a description."""
    missing = [f"{' '.join(words)} {a.option_strings or a.dest}" for words, p in _commands()
               for a in p._actions if a.help is None or not str(a.help).strip()]
    assert not missing, missing


def test_every_long_running_command_accepts_no_progress():
    """Every command accepts --no-progress, so scripts and CI can silence stderr the same way everywhere."""
    lacking = [" ".join(words) for words, p in _commands()
               if not any("--no-progress" in a.option_strings for a in p._actions)]
    assert not lacking, lacking
