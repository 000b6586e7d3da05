"""imupipe.units: CF / UDUNITS and datasheet spellings of the same units give the same SI factors
(the table of docs/inputs.md), and the one definition of standard gravity and SI unit names."""

import math

import pytest

from imupipe.units import SI_UNITS, STANDARD_GRAVITY, UnitError, normalise_unit, parse_unit, rate_factor, to_si

DEG = math.pi / 180.0
G0 = 9.80665  # m/s^2, 3rd CGPM (1901): the defined value

RATES = [
    # spelling, sensor, SI factor (closed form)
    ("rad/s", "gyro", 1.0), ("rad s-1", "gyro", 1.0), ("rad.s-1", "gyro", 1.0), ("rad/sec", "gyro", 1.0),
    ("rad s^-1", "gyro", 1.0), ("mrad/s", "gyro", 1e-3), ("urad/s", "gyro", 1e-6),
    ("deg/s", "gyro", DEG), ("dps", "gyro", DEG), ("DPS", "gyro", DEG), ("°/s", "gyro", DEG), ("º/s", "gyro", DEG),
    ("deg s-1", "gyro", DEG), ("deg/sec", "gyro", DEG), ("degrees/s", "gyro", DEG), ("mdeg/s", "gyro", DEG / 1e3),
    ("deg/h", "gyro", DEG / 3600), ("deg/hr", "gyro", DEG / 3600), ("dph", "gyro", DEG / 3600), ("°/h", "gyro", DEG / 3600),
    ("deg/min", "gyro", DEG / 60), ("arcsec/s", "gyro", DEG / 3600),
    ("m/s^2", "accel", 1.0), ("m s-2", "accel", 1.0), ("m.s-2", "accel", 1.0), ("m/s2", "accel", 1.0),
    ("m/s/s", "accel", 1.0), ("m/s**2", "accel", 1.0), ("m/s²", "accel", 1.0), ("m s⁻²", "accel", 1.0),
    ("mm/s^2", "accel", 1e-3), ("mm/s2", "accel", 1e-3), ("g", "accel", G0), ("g0", "accel", G0),
    ("mg", "accel", G0 * 1e-3), ("milli-g", "accel", G0 * 1e-3), ("ug", "accel", G0 * 1e-6),
    ("µg", "accel", G0 * 1e-6), ("μg", "accel", G0 * 1e-6), ("micro-g", "accel", G0 * 1e-6),
]


@pytest.mark.parametrize("unit, sensor, factor", RATES, ids=[r[0] for r in RATES])
def test_rate_spellings(unit, sensor, factor):
    assert rate_factor(unit, sensor) == pytest.approx(factor, rel=1e-15)


DENSITIES = [
    ("deg/s/√Hz", "white", "gyro", DEG), ("°/s/√Hz", "white", "gyro", DEG), ("dps/rtHz", "white", "gyro", DEG),
    ("deg/s/sqrt(Hz)", "white", "gyro", DEG), ("deg/√h", "white", "gyro", DEG / 60), ("°/√hr", "white", "gyro", DEG / 60),
    ("mg/√Hz", "white", "accel", G0 * 1e-3), ("µg/√Hz", "white", "accel", G0 * 1e-6), ("ug/rtHz", "white", "accel", G0 * 1e-6),
    ("m/s/√h", "white", "accel", 1 / 60), ("(deg/h)/√s", "random_walk", "gyro", DEG / 3600),
]


@pytest.mark.parametrize("unit, quantity, sensor, factor", DENSITIES, ids=[d[0] for d in DENSITIES])
def test_density_spellings(unit, quantity, sensor, factor):
    # 1 deg/s/sqrt(Hz) = pi/180 rad/sqrt(s); 1 deg/sqrt(h) = pi/180/60 rad/sqrt(s) (sqrt(3600 s) = 60 sqrt(s))
    assert to_si(1.0, unit, quantity, sensor) == pytest.approx(factor, rel=1e-15)


def test_ppm_is_dimensionless():
    assert parse_unit("ppm") == (1e-6, (0, 0, 0))


def test_normalise_examples():
    assert normalise_unit("µg/√Hz") == "ug/sqrt(Hz)"
    assert normalise_unit("°/s") == "deg/s"
    assert normalise_unit("mg/rtHz") == "mg/sqrt(Hz)"


@pytest.mark.parametrize("unit, sensor", [("deg", "gyro"), ("m/s", "accel"), ("g", "gyro"), ("deg/s", "accel"), ("furlong/s", "gyro")])
def test_wrong_dimension_or_unknown_refused(unit, sensor):
    with pytest.raises(UnitError, match="gyro_unit"):
        rate_factor(unit, sensor, key="gyro_unit")


def test_one_definition():
    assert STANDARD_GRAVITY == G0
    assert SI_UNITS == {"gyro": "rad/s", "accel": "m/s^2"}
