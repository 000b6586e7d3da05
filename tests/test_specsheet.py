"""imupipe.specsheet: values validated once at the edge, errors naming the file and the key path."""

import math

import pytest

from imupipe.models import NoiseModel
from imupipe.specsheet import SpecError, display_units, load_spec, model_in_units, parse_spec

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


def test_model_in_units_gives_back_the_sheet(tmp_path):
    # to_si then from_si with the same factor: two roundings of at most 2^-53 relative each, so the round trip is
    # within 2^-52 relative (2^-51 leaves room for the rounding of the comparison itself)
    path = sheet(tmp_path, "gyro:\n  white: {value: 0.15, unit: deg/sqrt(h)}\n"
                           "  gauss_markov:\n    - sigma: {value: 1.5, unit: deg/h}\n      T: {value: 25, unit: min}\n"
                           "  random_walk: {value: 2.0e-2, unit: (deg/h)/sqrt(s)}\n")
    spec = load_spec(path)
    out, note = model_in_units(spec.models["gyro"], display_units(spec, "gyro"), "gyro")
    tol = 2.0**-51
    assert note is None
    assert out == {"white": {"value": pytest.approx(0.15, rel=tol), "unit": "deg/sqrt(h)"},
                   "random_walk": {"value": pytest.approx(2.0e-2, rel=tol), "unit": "(deg/h)/sqrt(s)"},
                   "gauss_markov": [{"sigma": {"value": pytest.approx(1.5, rel=tol), "unit": "deg/h"},
                                     "T": {"value": pytest.approx(25.0, rel=tol), "unit": "min"}}]}


def test_model_in_units_closed_form_and_missing_keys():
    # 1 deg/h = pi/180/3600 rad/s; 1 mg = 9.80665e-3 m/s^2; a quantity without a unit is left out. The factor
    # here and the one imupipe.units builds each carry at most 4 roundings of 2^-53, the division one more: < 2^-49
    m = NoiseModel(gauss_markov=((2.0 * DEG / 3600.0, 100.0),), random_walk=1e-5)
    out, note = model_in_units(m, {"gm_sigma": "deg/h"}, "gyro")
    assert note is None and out == {"gauss_markov": [{"sigma": {"value": pytest.approx(2.0, rel=2.0**-49),
                                                                 "unit": "deg/h"}}]}
    out, _ = model_in_units(NoiseModel(gauss_markov=((9.80665e-3, 10.0),)), {"gm_sigma": "mg", "time": "h"}, "accel")
    assert out["gauss_markov"] == [{"sigma": {"value": pytest.approx(1.0, rel=2.0**-49), "unit": "mg"},
                                    "T": {"value": pytest.approx(10.0 / 3600.0, rel=2.0**-49), "unit": "h"}}]


def test_model_in_units_wrong_dimension_keeps_si_and_says_why():
    out, note = model_in_units(NoiseModel(white=1e-3), {"white": "deg/h"}, "gyro")
    assert out is None and note.startswith("unit conversion failed (") and "deg/h" in note
