# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Rig files load, validate, and reject bad input with a message naming the field."""
import os
import threading

import pytest
import yaml

from rotor_estimator.core.config import SEED_RIG_PATH, load_rig_file
from rotor_estimator.core.errors import ConfigError


def _write(tmp_path, mutate):
    data = yaml.safe_load(SEED_RIG_PATH.read_text())
    mutate(data)
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_seed_rig_matches_paper_table1_and_errata(seed_rig):
    assert seed_rig.shaft_mass_kg == 3.089
    assert seed_rig.bearing_span_m == pytest.approx(0.249)
    assert seed_rig.speed_rad_s == pytest.approx(20000 * 2 * 3.141592653589793 / 60)
    assert seed_rig.true_coefficients.kyx == -350e3 and seed_rig.true_coefficients.cyy == 1200.0


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d["rig"]["shaft"].pop("mass_kg"), "rig.shaft.mass_kg"),
    (lambda d: d["rig"]["shaft"].__setitem__("mass_kg", -3.0), "rig.shaft.mass_kg"),
    (lambda d: d["rig"]["shaft"].__setitem__("mass_kg", "3.089 kg"), "rig.shaft.mass_kg"),
    (lambda d: d["rig"]["operating"].__setitem__("sample_rate_hz", 0), "rig.operating.sample_rate_hz"),
    (lambda d: d["rig"]["operating"].__setitem__("speed_rpm", -10), "rig.operating.speed_rpm"),
    (lambda d: d["rig"]["bearings"]["bearing1"].__setitem__("axial_position_m", 0.5), "rig.bearings"),
    (lambda d: d["rig"]["probes"]["probe2"].__setitem__("axial_position_m", -0.1), "rig.probes"),
    (lambda d: d["rig"]["imbalances"][0].__setitem__("phase", 0), "rig.imbalances[0]"),
    (lambda d: d["estimator"]["initial_coefficient_std"].__setitem__("kxx_N_per_m", 0), "kxx_N_per_m"),
    (lambda d: d["estimator"].__setitem__("passes", 0), "estimator.passes"),
    (lambda d: d["rig"]["operating"].__setitem__("noise_std_m", float("nan")), "rig.operating.noise_std_m"),
])
def test_bad_rig_file_is_rejected_with_message_naming_the_field(tmp_path, mutate, field):
    with pytest.raises(ConfigError, match=field.replace("[", r"\[").replace("]", r"\]")):
        load_rig_file(_write(tmp_path, mutate))


def test_missing_file_and_non_yaml_give_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot be read"):
        load_rig_file(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("rig: [unclosed")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_rig_file(bad)


# ------------------------------------------------------------------ hostile-but-fair rig files
SEED_TEXT = SEED_RIG_PATH.read_text()


def _one_line_config_error(path, match):
    with pytest.raises(ConfigError, match=match) as info:
        load_rig_file(path)
    assert "\n" not in str(info.value)
    return str(info.value)


def _sections(data, prefix=""):
    """Every mapping-valued field of the seed rig, as a key path."""
    for key, value in data.items():
        if isinstance(value, dict):
            yield (*prefix, key)
            yield from _sections(value, (*prefix, key))


@pytest.mark.parametrize("section", list(_sections(yaml.safe_load(SEED_TEXT))), ids=".".join)
@pytest.mark.parametrize("scalar", [5, "text", None, [1, 2]], ids=["number", "string", "null", "list"])
def test_scalar_in_place_of_any_section_is_refused_naming_it(tmp_path, section, scalar):
    """`rig: 5` (or a string, null, list in place of any mapping section of the seed rig) gives one
    ConfigError naming that section, never a TypeError."""
    def mutate(d):
        for key in section[:-1]:
            d = d[key]
        d[section[-1]] = scalar
    name = section[-1]
    if scalar is None and section == ("rig", "true_coefficients"):
        pytest.skip("true_coefficients: null means 'none given', by design")
    _one_line_config_error(_write(tmp_path, mutate), rf"\b{name}\b")


def test_scalar_document_and_list_item_are_refused(tmp_path):
    """A document that is a bare number, and an imbalance list item that is a number, are refused
    with the field named."""
    top = tmp_path / "top.yaml"
    top.write_text("5\n")
    _one_line_config_error(top, "expected a mapping with 'rig' and 'estimator' sections, got the number 5")
    _one_line_config_error(_write(tmp_path, lambda d: d["rig"]["imbalances"].__setitem__(0, 7)),
                           r"rig\.imbalances\[0\]: expected a mapping")


def test_duplicate_key_is_refused_naming_it_and_both_lines(tmp_path):
    """PyYAML keeps the last of two equal keys silently (mass 30.89 kg instead of 3.089): the loader
    refuses the file, naming the key and both lines."""
    path = tmp_path / "dup.yaml"
    path.write_text(SEED_TEXT.replace("    mass_kg: 3.089\n", "    mass_kg: 3.089\n    mass_kg: 30.89\n"))
    assert yaml.safe_load(path.read_text())["rig"]["shaft"]["mass_kg"] == 30.89  # what it used to load
    line = SEED_TEXT.splitlines().index("    mass_kg: 3.089") + 1
    _one_line_config_error(path, rf"duplicate key 'mass_kg' at line {line + 1} \(first given at line {line}\)")


def test_yaml_merge_keys_are_not_duplicates(tmp_path):
    """A '<<' merge whose keys are then overridden is standard YAML, not a duplicate: it loads."""
    text = SEED_TEXT.replace("  bearings:\n    bearing1: {axial_position_m: -0.1245}",
                             "  bearings:\n    bearing1: &b {axial_position_m: -0.1245}")
    text = text.replace("    probe1: {axial_position_m: -0.1}", "    probe1: {<<: *b, axial_position_m: -0.1}")
    path = tmp_path / "merge.yaml"
    path.write_text(text)
    assert load_rig_file(path).rig.probe1_position_m == -0.1


def _alias_bomb(levels=10, fanout=9):
    lines = ["l0: &l0 [" + ", ".join(["lol"] * fanout) + "]"]
    for i in range(1, levels):
        lines.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * fanout) + "]")
    return "\n".join(lines) + "\n"


def test_alias_bomb_is_refused_before_it_is_built(tmp_path):
    """A 'billion laughs' file of under 3 kB (10 levels of 9 aliases: 9^10 values) is refused by
    the alias-expansion limit, and so is a recursive alias."""
    text = _alias_bomb()
    assert len(text.encode()) < 3000
    path = tmp_path / "bomb.yaml"
    path.write_text(text + "rig:\n  name: *l9\n")
    _one_line_config_error(path, "refused, its aliases expand to more than")
    rec = tmp_path / "recursive.yaml"
    rec.write_text("rig: &a [*a]\n")
    _one_line_config_error(rec, "recursive")


def test_python_tags_are_refused(tmp_path):
    """A `!!python/object/apply` rig is refused (the loader is a SafeLoader: switching it to
    unsafe_load would run os.system here and fail this test)."""
    marker = tmp_path / "pwned"
    path = tmp_path / "evil.yaml"
    path.write_text(f"rig: !!python/object/apply:os.system ['touch {marker}']\nestimator: {{}}\n")
    _one_line_config_error(path, r"refused the tag !!python/object/apply:os.system at line 1")
    assert not marker.exists()


def test_size_encoding_and_directory_are_refused(tmp_path):
    """A file over the size limit, a Latin-1 file, a directory and a named pipe (which would block
    the read) each give one line naming the cause."""
    from rotor_estimator.core.config import MAX_YAML_BYTES

    big = tmp_path / "big.yaml"
    big.write_text(SEED_TEXT + "#" * MAX_YAML_BYTES)
    _one_line_config_error(big, "larger than 1024 KiB")
    latin = tmp_path / "latin1.yaml"
    latin.write_bytes(SEED_TEXT.replace("miller_howard_2008", "m\u00fcller").encode("latin-1"))
    _one_line_config_error(latin, r"not UTF-8 text \(byte 0xfc at offset \d+\)")
    _one_line_config_error(tmp_path, "is a directory")
    fifo = tmp_path / "rig.fifo"
    os.mkfifo(fifo)  # opening it for reading blocks until a writer appears
    threading.Thread(target=_feed_fifo, args=(fifo, b"rig: 5\n"), daemon=True).start()  # unblocks a reader
    _one_line_config_error(fifo, "not a regular file")


def _feed_fifo(fifo, data, timeout_s=5.0):
    """Write ``data`` into ``fifo`` if a reader opens it within ``timeout_s`` (never blocks)."""
    import time

    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError:
            time.sleep(0.05)
            continue
        os.write(fd, data)
        os.close(fd)
        return


def test_huge_integer_and_deep_nesting_are_refused(tmp_path):
    """A 400-digit mass (float() overflows) and 100000 nested brackets (PyYAML recurses) give
    ConfigErrors, not OverflowError / RecursionError."""
    _one_line_config_error(_write(tmp_path, lambda d: d["rig"]["shaft"].__setitem__("mass_kg", 10 ** 400)),
                           r"rig\.shaft\.mass_kg: number too large")
    deep = tmp_path / "deep.yaml"
    deep.write_text("rig: " + "[" * 100_000 + "]" * 100_000 + "\n")
    _one_line_config_error(deep, "nested too deeply")


def test_yaml_syntax_error_is_one_line_with_position(tmp_path):
    """PyYAML's multi-line error becomes one line with the line and column."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("rig:\n  name: [unclosed\nestimator: {}\n")
    _one_line_config_error(bad, r"not valid YAML: .* at line \d+, column \d+")


def test_rotor_files_get_the_same_limits(tmp_path):
    """Rotor description files (virtual sensing) load through the same strict loader: a duplicate
    key and a !!python tag are refused naming the rotor file."""
    from rotor_estimator.core.flexible.description import ROTORS_DIR, load_rotor_description

    text = (ROTORS_DIR / "three_probe_rig.yaml").read_text()
    first = next(line for line in text.splitlines() if line.strip().startswith("name:"))
    dup = tmp_path / "dup.yaml"
    dup.write_text(text.replace(first + "\n", first + "\n" + first + "\n", 1))
    with pytest.raises(ConfigError, match=r"rotor file .*dup.yaml: duplicate key 'name'"):
        load_rotor_description(dup)
    evil = tmp_path / "evil.yaml"
    evil.write_text("rotor: !!python/object/apply:os.getcwd []\n")
    with pytest.raises(ConfigError, match=r"rotor file .*evil.yaml: refused the tag !!python/object/apply"):
        load_rotor_description(evil)
