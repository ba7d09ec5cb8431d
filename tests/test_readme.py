# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The README's Python example runs as printed (docs that cannot drift from the API)."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _python_api_block() -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split("## Python API", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match, "README: no python block under '## Python API'"
    return match.group(1)


@pytest.mark.slow
def test_readme_python_example_runs_and_prints_every_coefficient_and_a_verdict():
    """The example exits 0, prints all eight coefficients with units, and a diagnosis verdict."""
    done = subprocess.run([sys.executable, "-c", _python_api_block()], cwd=ROOT, capture_output=True, text=True,
                          timeout=600, env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.splitlines()
    for name in ("kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy"):
        assert any(line.startswith(f"{name} = ") and line.endswith(("N/m", "N*s/m")) for line in lines), name
    verdict, shrink = lines[-1].split()
    assert verdict and float(shrink) >= 1.0
