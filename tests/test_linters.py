# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The checks a ROS package runs with ament_lint, without ROS: copyright headers (ament_copyright),
package.xml (ament_xmllint), ruff (ament_flake8 + ament_pep257) and mypy.

The ruff and mypy configuration is in pyproject.toml; ``.ci/lint`` runs the same two tools.
"""
import importlib.util
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Every Python file under these folders, and setup.py, carries the header.
LICENSED_DIRS = ("rotor_estimator", "msg_adapters", "tests", "launch", "tools", "benchmarks")
SPDX_LICENSE = "Apache-2.0"
HEADER_RE = (re.compile(r"# Copyright \d{4}(-\d{4})? rotor_estimator developers"),
             re.compile(rf"# SPDX-License-Identifier: {re.escape(SPDX_LICENSE)}"))


# ------------------------------------------------------------------ copyright (ament_copyright)
def header_problem(text: str) -> str | None:
    """None when the first two lines (after a shebang) are the copyright and SPDX lines, else what is wrong."""
    lines = text.splitlines()
    if lines and lines[0].startswith("#!"):
        lines = lines[1:]
    expected = ("# Copyright <year> rotor_estimator developers", f"# SPDX-License-Identifier: {SPDX_LICENSE}")
    for k, (pattern, want) in enumerate(zip(HEADER_RE, expected)):
        got = lines[k] if k < len(lines) else "<end of file>"
        if not pattern.fullmatch(got):
            return f"line {k + 1} (after any shebang) is {got!r}, expected {want!r}"
    return None


def _licensed_files() -> list[Path]:
    files = [ROOT / "setup.py"]
    for folder in LICENSED_DIRS:
        files += [p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts]
    return sorted(files)


def test_header_check_accepts_the_header_after_a_shebang_and_refuses_a_missing_or_wrong_one():
    """The checker itself: a shebang may precede the header; a missing, reordered or other-license header fails."""
    good = "# Copyright 2026 rotor_estimator developers\n# SPDX-License-Identifier: Apache-2.0\n\"\"\"Doc.\"\"\"\n"
    assert header_problem(good) is None
    assert header_problem("#!/usr/bin/env python3\n" + good) is None
    assert "line 1" in header_problem('"""Doc."""\n')
    swapped = "# SPDX-License-Identifier: Apache-2.0\n# Copyright 2026 rotor_estimator developers\n"
    assert "line 1" in header_problem(swapped)
    assert "line 2" in header_problem("# Copyright 2026 rotor_estimator developers\n# SPDX-License-Identifier: MIT\n")
    assert "<end of file>" in header_problem("# Copyright 2026 rotor_estimator developers")


def test_every_python_file_starts_with_the_copyright_and_spdx_lines():
    """ament_copyright's equivalent: every .py file in the package, tests, launch, tools and benchmarks
    and setup.py starts with the copyright line and the SPDX identifier of the package's license."""
    files = _licensed_files()
    assert len(files) > 100, f"only {len(files)} files found under {LICENSED_DIRS}"
    bad = [f"{p.relative_to(ROOT)}: {problem}" for p in files
           if (problem := header_problem(p.read_text(encoding="utf-8"))) is not None]
    assert not bad, "files without the license header:\n" + "\n".join(bad)


def test_the_spdx_license_is_the_one_package_xml_and_setup_py_declare():
    """The header's SPDX identifier, package.xml's <license> and setup.py's license= agree."""
    licenses = [e.text for e in ET.parse(ROOT / "package.xml").getroot().findall("license")]
    assert licenses == [SPDX_LICENSE]
    assert f'license="{SPDX_LICENSE}"' in (ROOT / "setup.py").read_text()


# ------------------------------------------------------------------ package.xml (ament_xmllint)
#: REP 149 (package format 3): the children of <package> in this order, with these counts
#: (min, max; None = unbounded). The dependency kinds form one group in any order.
FORMAT3_SEQUENCE = (
    (("name",), 1, 1),
    (("version",), 1, 1),
    (("description",), 1, 1),
    (("maintainer",), 1, None),
    (("license",), 1, None),
    (("url",), 0, None),
    (("author",), 0, None),
    (("build_depend", "build_export_depend", "buildtool_depend", "buildtool_export_depend", "exec_depend",
      "depend", "doc_depend", "test_depend", "conflict", "replace"), 0, None),
    (("group_depend",), 0, None),
    (("member_of_group",), 0, None),
    (("export",), 0, 1),
)
DEPENDENCY_ATTRIBUTES = {"version_lt", "version_lte", "version_eq", "version_gte", "version_gt", "condition"}
NAME_RE = re.compile(r"[a-z](_?[a-z0-9]+)*")
VERSION_RE = re.compile(r"[0-9]+\.[0-9]+\.[0-9]+")


def package_xml_problems(text: str) -> list[str]:
    """What keeps ``text`` from being a valid format-3 package.xml (empty when it is one): well-formed
    XML, root ``<package format="3">``, REP 149's element order and counts, the name and version
    patterns, a maintainer email, non-empty description and license, known dependency attributes."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        return [f"not well-formed XML: {exc}"]
    if root.tag != "package":
        return [f"root element is <{root.tag}>, expected <package>"]
    problems = []
    if root.get("format") != "3":
        problems.append(f"<package format={root.get('format')!r}>: expected format=\"3\"")
    group_of = {tag: g for g, (tags, _, _) in enumerate(FORMAT3_SEQUENCE) for tag in tags}
    counts = [0] * len(FORMAT3_SEQUENCE)
    last_group = 0
    for child in root:
        if child.tag not in group_of:
            problems.append(f"<{child.tag}> is not a format-3 element of <package>")
            continue
        g = group_of[child.tag]
        if g < last_group:
            problems.append(f"<{child.tag}> after <{'/'.join(FORMAT3_SEQUENCE[last_group][0])}>: out of REP 149 order")
        last_group = max(last_group, g)
        counts[g] += 1
        if g == group_of["exec_depend"]:
            unknown = set(child.attrib) - DEPENDENCY_ATTRIBUTES
            if unknown:
                problems.append(f"<{child.tag}>{child.text}: unknown attribute(s) {sorted(unknown)}")
    for (tags, low, high), n in zip(FORMAT3_SEQUENCE, counts):
        if n < low or (high is not None and n > high):
            problems.append(f"<{'/'.join(tags)}> appears {n} time(s), expected {low}..{high if high else 'n'}")
    name, version = root.findtext("name", ""), root.findtext("version", "")
    if not NAME_RE.fullmatch(name.strip()):
        problems.append(f"<name>{name}</name>: lower-case letters, digits and single underscores, from a letter")
    if not VERSION_RE.fullmatch(version.strip()):
        problems.append(f"<version>{version}</version>: expected MAJOR.MINOR.PATCH")
    for m in root.findall("maintainer"):
        if not m.get("email") or not (m.text or "").strip():
            problems.append(f"<maintainer>{m.text}</maintainer>: needs a name and an email attribute")
    for tag in ("description", "license"):
        if any(not (e.text or "").strip() for e in root.findall(tag)):
            problems.append(f"<{tag}> is empty")
    return problems


def test_package_xml_check_refuses_what_the_format_3_schema_refuses():
    """The checker itself rejects: broken XML, format 2, a missing license, elements out of order,
    a bad version, a maintainer without email, an unknown element and an unknown dependency attribute."""
    text = (ROOT / "package.xml").read_text()
    assert package_xml_problems(text) == []
    broken = {
        "not well-formed": text.replace("</package>", ""),
        "format=": text.replace('format="3"', 'format="2"'),
        "<license> appears 0": re.sub(r"<license>.*?</license>", "", text),
        "out of REP 149 order": text.replace("<export>", "<name>x</name><export>", 1),
        "MAJOR.MINOR.PATCH": text.replace("<version>0.1.0</version>", "<version>0.1</version>"),
        "email attribute": re.sub(r'<maintainer email="[^"]*">', "<maintainer>", text),
        "not a format-3 element": text.replace("<export>", "<run_depend>x</run_depend><export>"),
        "unknown attribute": text.replace("<exec_depend>rclpy", '<exec_depend version="1">rclpy'),
    }
    for expected, variant in broken.items():
        assert variant != text, expected
        assert any(expected in p for p in package_xml_problems(variant)), expected


def test_package_xml_is_a_valid_format_3_manifest_for_an_ament_python_package():
    """ament_xmllint's equivalent: package.xml is well-formed (xmllint too, when installed) and follows
    the package format 3 schema's structure (REP 149), and declares build_type ament_python."""
    path = ROOT / "package.xml"
    assert package_xml_problems(path.read_text()) == []
    root = ET.parse(path).getroot()
    assert root.findtext("name") == "rotor_estimator"
    assert root.findtext("export/build_type") == "ament_python"
    if shutil.which("xmllint"):
        done = subprocess.run(["xmllint", "--noout", str(path)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr


# ------------------------------------------------------------------ ruff and mypy
def _require(module: str) -> None:
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed (pip install -e '.[test]' installs it)")


def test_ruff_finds_nothing():
    """ament_flake8 + ament_pep257's equivalent: `ruff check` (rules in pyproject.toml) passes on the tree."""
    _require("ruff")
    done = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-fix", "."], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


@pytest.mark.slow
def test_mypy_finds_nothing():
    """mypy (settings and per-module relaxations in pyproject.toml) passes on rotor_estimator and msg_adapters."""
    _require("mypy")
    done = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


def test_the_package_has_no_import_cycle_and_no_private_name_used_across_modules(tmp_path):
    """tools/import_graph.py finds no cycle and no private cross-module import in the tree; and it does
    find both in a small package written to have them (so the check can fail)."""
    import subprocess
    import sys

    run = subprocess.run([sys.executable, str(ROOT / "tools" / "import_graph.py")], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout
    assert "0 import cycles, 0 private cross-module imports" in run.stdout

    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import import_graph
    finally:
        sys.path.remove(str(ROOT / "tools"))
    pkg = tmp_path / "rotor_estimator"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from rotor_estimator.b import _hidden\n")
    (pkg / "b.py").write_text("from rotor_estimator import a\n_hidden = 1\n")
    (tmp_path / "msg_adapters").mkdir()
    (tmp_path / "msg_adapters" / "__init__.py").write_text("")
    old_root = import_graph.ROOT
    import_graph.ROOT = tmp_path
    try:
        assert import_graph.main() == 1
    finally:
        import_graph.ROOT = old_root
