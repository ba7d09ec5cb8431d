# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Report and plot writers never follow symbolic links (rotor_estimator.io.safe_write policy): a link
at a file name is replaced and its target left untouched; a linked output directory is refused."""
from __future__ import annotations

import ast
import errno
import logging
import os
from pathlib import Path

import numpy as np
import pytest

from rotor_estimator.core.errors import OutputError
from rotor_estimator.io.safe_write import output_directory, save_figure, save_npz, write_bytes, write_text

PACKAGE = Path(__file__).resolve().parents[3] / "rotor_estimator"
#: The modules that write reports and figures; each must write through safe_write only.
WRITERS = ["cli/plots.py", "virtual_sensing/plots.py", "diagnosis/report.py", "identification/plots.py",
           "cli/virtual_sensing.py", "cli/replay.py"]


@pytest.fixture
def outside(tmp_path):
    """A file outside the output directory, as a victim of a planted link."""
    victim = tmp_path / "outside" / "precious.txt"
    victim.parent.mkdir()
    victim.write_text("do not overwrite")
    return victim


def _plant(out: Path, name: str, victim: Path) -> Path:
    out.mkdir(exist_ok=True)
    link = out / name
    link.symlink_to(victim)
    return link


def test_symlink_at_the_file_name_is_replaced_and_its_target_untouched(tmp_path, outside, caplog):
    """Writing report.md where report.md is a link to an outside file leaves that file as it was,
    puts a regular file at report.md and logs that the link was replaced."""
    link = _plant(tmp_path / "rep", "report.md", outside)
    with caplog.at_level(logging.WARNING, logger="rotor_estimator"):
        write_text(link, "# report\n")
    assert outside.read_text() == "do not overwrite"
    assert not link.is_symlink() and link.read_text() == "# report\n"
    assert "replaced the symbolic link" in caplog.text
    assert sorted(p.name for p in link.parent.iterdir()) == ["report.md"]  # no temporary left


def test_hard_link_at_the_file_name_is_replaced_not_written_through(tmp_path, outside):
    """A hard link to an outside file is replaced by a new file (the outside inode keeps its bytes)."""
    (tmp_path / "rep").mkdir()
    hard = tmp_path / "rep" / "summary.json"
    os.link(outside, hard)
    write_bytes(hard, b"{}")
    assert outside.read_text() == "do not overwrite" and hard.read_bytes() == b"{}"


def test_linked_output_directory_is_refused_naming_the_link(tmp_path, outside):
    """`--report DIR` where DIR is a link to another directory is refused (message names the link and
    its target) and nothing is written there, by output_directory or by a direct file write."""
    linked = tmp_path / "rep"
    linked.symlink_to(outside.parent, target_is_directory=True)
    with pytest.raises(OutputError, match=rf"--report {linked}: is a symbolic link \(to {outside.parent}\)"):
        output_directory(linked, "--report")
    with pytest.raises(OutputError, match="its directory .* is a symbolic link"):
        write_text(linked / "report.md", "x")
    assert sorted(p.name for p in outside.parent.iterdir()) == ["precious.txt"]


def test_directory_at_the_file_name_and_file_as_directory_are_refused(tmp_path):
    """A directory where a file goes, and a file where the output directory goes, are OutputErrors."""
    (tmp_path / "a.png").mkdir()
    with pytest.raises(OutputError, match="a directory of that name exists"):
        write_bytes(tmp_path / "a.png", b"x")
    (tmp_path / "file").write_text("")
    with pytest.raises(OutputError, match="exists and is not a directory"):
        output_directory(tmp_path / "file", "--plots")


def test_failed_render_leaves_the_old_file_and_no_temporary(tmp_path):
    """A figure whose rendering fails, or a write that runs out of space (one OutputError line),
    leaves the previous file intact and no temporary behind."""
    class Broken:
        def savefig(self, *a, **k):
            raise RuntimeError("render failed")

    target = tmp_path / "orbit.png"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        save_figure(Broken(), target)
    def disk_full(fh, **arrays):
        fh.write(b"partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(np, "savez", disk_full)
        with pytest.raises(OutputError, match=r"cannot write .*orbit.npz: No space left on device"):
            save_npz(target.with_suffix(".npz"), x=np.zeros(1))
    assert target.read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["orbit.png"]


def test_save_npz_appends_the_suffix_like_numpy(tmp_path):
    """save_npz('est') writes est.npz, as numpy.savez does, and the arrays read back."""
    p = save_npz(tmp_path / "est", a=np.arange(3))
    assert p.name == "est.npz" and np.load(p)["a"].tolist() == [0, 1, 2]


def test_figure_writers_replace_planted_links(tmp_path, outside):
    """plots.coefficient_error_history and identification.plots.coefficients_vs_speed, given a
    directory holding links named like their outputs, write PNGs and leave the outside file alone."""
    from rotor_estimator.identification.plots import coefficients_vs_speed
    from rotor_estimator.identification.speed_dependent import SpeedTable
    from rotor_estimator.cli.plots import coefficient_error_history

    out = tmp_path / "plots"
    a = _plant(out, "coefficient_error_x.png", outside)
    b = _plant(out, "coefficients_vs_speed.png", outside)
    true = np.arange(1.0, 9.0)
    coefficient_error_history(np.linspace(0, 1, 5), np.tile(true, (5, 1)), true, a, "t")
    tab = SpeedTable(np.array([100.0, 200.0]), ("kxx",), np.ones((2, 1)), np.full((2, 1), 0.1))
    coefficients_vs_speed(tab, b)
    for p in (a, b):
        assert not p.is_symlink() and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert outside.read_text() == "do not overwrite"


def test_virtual_sensing_report_and_estimates_never_follow_links(tmp_path, outside, capsys):
    """`virtual-sensing --report DIR --estimates-out F` with leave_one_out.txt, an orbit PNG and F
    planted as links to an outside file: all three become regular files, the outside file is
    unchanged; a --report that is itself a link exits 2 with one error line."""
    from rotor_estimator.cli.main import main

    rep = tmp_path / "rep"
    links = [_plant(rep, "leave_one_out.txt", outside), _plant(rep, "orbit_disk1.png", outside),
             _plant(tmp_path, "est.npz", outside)]
    assert main(["virtual-sensing", "--samples", "400", "--hide", "probe1", "--report", str(rep),
                 "--estimates-out", str(tmp_path / "est.npz")]) == 0
    assert outside.read_text() == "do not overwrite"
    assert all(not p.is_symlink() for p in links)
    assert "probe1_x" in links[0].read_text() and "disk1_displacement_x" in np.load(links[2]).files
    linked = tmp_path / "linked"
    linked.symlink_to(outside.parent, target_is_directory=True)
    capsys.readouterr()
    assert main(["virtual-sensing", "--samples", "400", "--hide", "probe1", "--report", str(linked)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a symbolic link" in err
    assert sorted(p.name for p in outside.parent.iterdir()) == ["precious.txt"]


@pytest.mark.parametrize("module", WRITERS)
def test_report_writers_write_files_only_through_safe_write(module):
    """No report/plot module calls savefig on a path, Path.write_text/write_bytes, open() or
    numpy.savez* directly (each would follow a planted symbolic link)."""
    tree = ast.parse((PACKAGE / module).read_text())
    offending = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            owner = getattr(f.value, "id", "") if isinstance(f, ast.Attribute) else ""
            if name in ("write_text", "write_bytes", "savez", "savez_compressed", "save") and owner != "" \
                    and owner not in ("safe_write",):
                offending.append(f"{name} line {node.lineno}")
            if name == "open" and owner in ("", "io", "builtins"):
                modes = [a for a in node.args[1:2]] + [k.value for k in node.keywords if k.arg == "mode"]
                if any(not (isinstance(m, ast.Constant) and set(str(m.value)) <= set("rbt")) for m in modes):
                    offending.append(f"open for writing line {node.lineno}")
            if name == "savefig":
                offending.append(f"{name} line {node.lineno}")
            if name == "mkdir":
                offending.append(f"mkdir line {node.lineno}")
    assert offending == []
