"""Rig files load, validate, and reject bad input with a message naming the field."""
import pytest
import yaml

from rotor_estimator.config import SEED_RIG_PATH, load_rig_file
from rotor_estimator.errors import ConfigError


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
