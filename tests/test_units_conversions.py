"""imupipe.units: spec-sheet units to SI and back, against hand-derived factors.

Derivations (SI: rad, m, s; deg = pi/180 rad; h = 3600 s; g0 = 9.80665 m/s^2):
  deg/sqrt(h)      = (pi/180) / sqrt(3600)  = (pi/180)/60 rad/sqrt(s)
  (deg/h)/sqrt(Hz) = (pi/180)/3600 * sqrt(s)   -> rad/sqrt(s)
  (deg/h)/sqrt(s)  = (pi/180)/3600 rad/s^(3/2);  deg/h^(3/2) = (pi/180)/3600^1.5 (60x smaller)
  m/s/sqrt(h)      = 1/60 m/s^(3/2);             m/s/h^(3/2) = 1/3600^1.5 m/s^(5/2)
The factors are exact products of floats, so rtol 1e-14 allows a few roundings.
"""

import math

import numpy as np
import pytest

from imupipe.specsheet import SpecError, parse_spec
from imupipe.units import UnitError, from_si, parse_unit, to_si

D = math.pi / 180.0
G0 = 9.80665

CASES = [
    # (value, unit, quantity, sensor, SI value)
    (0.15, "deg/sqrt(h)", "white", "gyro", 0.15 * D / 60),
    (1.0, "(deg/s)/sqrt(Hz)", "white", "gyro", D),
    (1.0, "deg/s/sqrt(Hz)", "white", "gyro", D),
    (1.0, "(deg/h)/sqrt(Hz)", "white", "gyro", D / 3600),
    (0.05, "m/s/sqrt(h)", "white", "accel", 0.05 / 60),
    (1.0, "ug/sqrt(Hz)", "white", "accel", G0 * 1e-6),
    (2e-2, "(deg/h)/sqrt(s)", "random_walk", "gyro", 2e-2 * D / 3600),
    (1.0, "deg/h^(3/2)", "random_walk", "gyro", D / 3600**1.5),
    (1.0, "deg / h ^ (3/2)", "random_walk", "gyro", D / 3600**1.5),
    (1.25e-6, "m/s^2/sqrt(s)", "random_walk", "accel", 1.25e-6),
    (1.0, "m/s/h^(3/2)", "random_walk", "accel", 1 / 3600**1.5),
    (1.0, "g/sqrt(s)", "random_walk", "accel", G0),
    (1.0, "m/s^2*s^-0.5", "random_walk", "accel", 1.0),
    (1.5, "deg/h", "gm_sigma", "gyro", 1.5 * D / 3600),
    (0.007, "deg/s", "rate", "gyro", 0.007 * D),
    (0.05, "mg", "gm_sigma", "accel", 0.05e-3 * G0),
    (1.0, "g", "rate", "accel", G0),
    (1.0, "ug", "rate", "accel", G0 * 1e-6),
    (1.0, "m/s^2", "rate", "accel", 1.0),
    (1500.0, "s", "time", "gyro", 1500.0),
    (2.0, "min", "time", "accel", 120.0),
    (1.0, "h", "time", "gyro", 3600.0),
    (1.0, "deg", "quantization", "gyro", D),
    (1.0, "m/s", "quantization", "accel", 1.0),
    (1.0, "deg/h^2", "ramp", "gyro", D / 3600**2),
    (1.0, "m/s^3", "ramp", "accel", 1.0),
]


class TestToSi:
    @pytest.mark.parametrize("value, unit, quantity, sensor, expected", CASES)
    def test_factor(self, value, unit, quantity, sensor, expected):
        assert to_si(value, unit, quantity, sensor) == pytest.approx(expected, rel=1e-14)

    def test_k_units_differ_by_60(self):
        a = to_si(1.0, "(deg/h)/sqrt(s)", "random_walk", "gyro")
        b = to_si(1.0, "deg/h^(3/2)", "random_walk", "gyro")
        assert a / b == pytest.approx(60.0, rel=1e-14)

    def test_array(self):
        v = np.array([0.1, 0.2, 0.3])
        np.testing.assert_allclose(to_si(v, "deg/sqrt(h)", "white", "gyro"), v * D / 60, rtol=1e-14)


class TestFromSi:
    @pytest.mark.parametrize("value, unit, quantity, sensor, expected", CASES)
    def test_round_trip(self, value, unit, quantity, sensor, expected):
        si = to_si(value, unit, quantity, sensor)
        assert from_si(si, unit, quantity, sensor) == pytest.approx(value, rel=1e-15)


class TestErrors:
    def test_k_as_plain_rate_names_key_and_hint(self):
        with pytest.raises(UnitError, match=r"gyro\.random_walk.*sqrt\(s\)"):
            to_si(2e-2, "deg/h", "random_walk", "gyro", key="gyro.random_walk")

    @pytest.mark.parametrize("unit, pattern", [
        ("furlong", "furlong"),
        ("", "empty"),
        ("(deg/h", "deg/h"),
        ("m/s^2", "dimension"),  # an accel unit for a gyro rate
    ])
    def test_bad_unit(self, unit, pattern):
        with pytest.raises(UnitError, match=pattern):
            to_si(1.0, unit, "rate", "gyro", key="gyro.flicker")

    def test_non_string(self):
        with pytest.raises(UnitError, match="string"):
            parse_unit(3.0)

    def test_unknown_quantity_and_sensor(self):
        with pytest.raises(UnitError, match="quantity"):
            to_si(1.0, "s", "colour", "gyro")
        with pytest.raises(UnitError, match="sensor"):
            to_si(1.0, "deg/h", "rate", "magnetometer")


class TestSpecSheet:
    def test_value_without_unit_names_the_key(self):
        with pytest.raises(SpecError, match=r"gyro\.white.*no unit"):
            parse_spec({"gyro": {"white": 0.15}}, where="s.yaml")

    def test_ambiguous_k_unit_names_file_and_key(self):
        with pytest.raises(SpecError, match=r"s\.yaml.*random_walk.*sqrt\(s\)"):
            parse_spec({"gyro": {"random_walk": {"value": 2e-2, "unit": "deg/h"}}}, where="s.yaml")

    def test_unknown_key(self):
        with pytest.raises(SpecError, match="bias"):
            parse_spec({"gyro": {"bias": {"value": 1, "unit": "deg/h"}}}, where="s.yaml")

    def test_stim300_table2_in_si(self):
        sheet = parse_spec({
            "gyro": {"white": {"value": 0.15, "unit": "deg/sqrt(h)"},
                     "gauss_markov": [{"sigma": {"value": 1.5, "unit": "deg/h"}, "T": {"value": 1500, "unit": "s"}}],
                     "random_walk": {"value": 2e-2, "unit": "(deg/h)/sqrt(s)"}},
        })
        m = sheet.models["gyro"]
        assert m.white == pytest.approx(0.15 * D / 60, rel=1e-14)
        assert m.gauss_markov[0] == pytest.approx((1.5 * D / 3600, 1500.0), rel=1e-14)
        assert m.random_walk == pytest.approx(2e-2 * D / 3600, rel=1e-14)
