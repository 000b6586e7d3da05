"""imupipe.specsheet: values validated once at the edge, errors naming the file and the key path."""

import math

import pytest

from imupipe.specsheet import SpecError, load_spec, parse_spec

DEG = math.pi / 180.0


def sheet(tmp_path, text):
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return path


def test_yaml11_exponent_string_is_a_number(tmp_path):
    # YAML 1.1 (PyYAML) reads 1.5e3 (no dot-sign form) as the string "1.5e3"
    path = sheet(tmp_path, "gyro:\n  gauss_markov:\n    - sigma: {value: 1.5, unit: deg/h}\n      T: {value: 1.5e3, unit: s}\n")
    spec = load_spec(path)
    assert spec.models["gyro"].gauss_markov == ((pytest.approx(1.5 * DEG / 3600), 1500.0),)


@pytest.mark.parametrize(
    "text, message",
    [
        ("gyro:\n  white: {value: 1.0e+300, unit: deg/sqrt(h)}\n",
         r"spec\.yaml: gyro\.white\.value = 1e\+300 deg/sqrt\(h\) is 2\.91e\+296 in SI, beyond the plausible limit 1000"),
        ("gyro:\n  gauss_markov:\n    - sigma: {value: 1.5, unit: deg/h}\n      T: {value: 1e12, unit: s}\n",
         r"spec\.yaml: gyro\.gauss_markov\[0\]\.T\.value = 1e\+12 s is 1e\+12 in SI, beyond the plausible limit 1e\+10"),
        ("gyro:\n  gauss_markov:\n    - sigma: {value: 'one', unit: deg/h}\n      T: {value: 10, unit: s}\n",
         r"spec\.yaml: gyro\.gauss_markov\[0\]\.sigma\.value = 'one' is not a number"),
        ("accel:\n  random_walk: {value: .nan, unit: m/s^2/sqrt(s)}\n",
         r"spec\.yaml: accel\.random_walk\.value must be a finite non-negative number, got nan"),
        ("accel:\n  white: '1.5e3'\n", r"spec\.yaml: accel\.white = '1\.5e3' has no unit"),
    ],
    ids=["1e300", "T_1e12", "not_a_number", "nan", "number_string_without_unit"],
)
def test_bad_values_name_the_key_path(tmp_path, text, message):
    with pytest.raises(SpecError, match=message):
        load_spec(sheet(tmp_path, text))


def test_square_of_every_accepted_value_is_finite():
    spec = parse_spec({"gyro": {"white": {"value": 999.0, "unit": "rad/sqrt(s)"}}})
    assert math.isfinite(spec.models["gyro"].white ** 2)
