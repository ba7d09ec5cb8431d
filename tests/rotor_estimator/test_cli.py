"""The command-line entry point: version and option help."""
import pytest

from rotor_estimator import __version__
from rotor_estimator.cli import main


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

    root = Path(__file__).resolve().parents[2]
    assert ET.parse(root / "package.xml").getroot().findtext("version") == __version__
    assert f'version="{__version__}"' in (root / "setup.py").read_text()
