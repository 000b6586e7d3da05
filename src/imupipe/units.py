r"""Spec-sheet units to SI and back.

Spec sheets quote noise in units such as ``deg/sqrt(h)``, ``(deg/h)/sqrt(s)``, ``mg`` or
``m/s/sqrt(h)``; imupipe works in SI internally (gyro rad/s, accel m/s^2, time s; docs/method.md, section "Conventions: units").
This module converts once, at the edge, from a unit string named in the file.

Grammar
-------
::

    unit     := product
    product  := power (("*" | "/" | "." | " ") power)*  # left-associative: a/b/c == (a/b)/c
    power    := atom ("^" exponent | "**" exponent | CF_exponent)?
    CF_exponent := ["-"] NUMBER                     # UDUNITS / CF: "s-1", "m s-2", "s2"
    atom     := NAME | NUMBER | "sqrt" "(" product ")" | "(" product ")"
    exponent := ["-"] NUMBER | "(" ["-"] NUMBER ["/" NUMBER] ")"

Juxtaposition (a space) and ``.`` multiply, as in CF / UDUNITS (``rad s-1``, ``m.s-2``); an integer
right after a unit name is its exponent (``s-1``, ``s2``).  Exponents are exact fractions
(``h^(3/2)``, ``s^-0.5``).  Before parsing, :func:`normalise_unit` rewrites the common datasheet
spellings (table :data:`SPELLINGS`: ``°`` -> ``deg``, ``µ`` -> ``u``, ``√Hz`` / ``rtHz`` ->
``sqrt(Hz)``, ``dps`` -> ``deg/s``, ``²`` -> ``^2``, ...).

Unit names (case-sensitive)
---------------------------
======== ========================== ================================
name     SI factor                  dimension (angle, length, time)
======== ========================== ================================
rad      1                          (1, 0, 0)
deg      pi/180                     (1, 0, 0)
s        1                          (0, 0, 1)
min      60                         (0, 0, 1)
h, hr    3600                       (0, 0, 1)
Hz       1                          (0, 0, -1)
m        1                          (0, 1, 0)
g        9.80665 (standard gravity) (0, 1, -2)
mg       9.80665e-3                 (0, 1, -2)
ug       9.80665e-6                 (0, 1, -2)
ppm      1e-6                       (0, 0, 0)
mrad     1e-3                       (1, 0, 0)
urad     1e-6                       (1, 0, 0)
mdeg     pi/180e3                   (1, 0, 0)
arcmin   pi/10800                   (1, 0, 0)
arcsec   pi/648000                  (1, 0, 0)
ms       1e-3                       (0, 0, 1)
us       1e-6                       (0, 0, 1)
ns       1e-9                       (0, 0, 1)
mm       1e-3                       (0, 1, 0)
cm       1e-2                       (0, 1, 0)
km       1e3                        (0, 1, 0)
kHz      1e3                        (0, 0, -1)
======== ========================== ================================

Quantities
----------
With ``rate`` = angle/time (gyro) or length/time^2 (accel):

=============== ======================= ===========================================
quantity        dimension               examples
=============== ======================= ===========================================
rate            rate                    deg/h, mg (flicker coefficient B)
gm_sigma        rate                    deg/h, mg (Gauss-Markov sigma)
white           rate * time^(1/2)       deg/sqrt(h), (deg/s)/sqrt(Hz), m/s/sqrt(h)
random_walk     rate * time^(-1/2)      (deg/h)/sqrt(s), deg/h^(3/2), m/s^2/sqrt(s)
quantization    rate * time             deg, m/s
ramp            rate / time             deg/h^2, m/s^3
time            time                    s, h
=============== ======================= ===========================================

A random-walk coefficient K given with plain rate dimension (``deg/h``) is refused with a
hint: reading the +1/2 slope of an ADEV in deg/h at tau = 3 s gives K in (deg/h)/sqrt(s),
not deg/h (nor deg/h^(3/2), a factor 60 away) (docs/method.md, section "Slip: units of K").

Examples
--------
>>> f"{to_si(0.15, 'deg/sqrt(h)', 'white', 'gyro'):.4e}"
'4.3633e-05'
>>> to_si(1.0, "mg", "rate", "accel")
0.00980665
"""

from __future__ import annotations

import math
import re
from fractions import Fraction
from typing import NamedTuple

__all__ = [
    "UnitError",
    "split_unit_suffix",
    "header_rate_unit",
    "ParsedUnit",
    "QUANTITIES",
    "SENSORS",
    "STANDARD_GRAVITY",
    "SI_UNITS",
    "SPELLINGS",
    "normalise_unit",
    "rate_factor",
    "parse_unit",
    "expected_dimension",
    "format_dimension",
    "to_si",
    "from_si",
]

#: Standard gravity in m/s^2 (3rd CGPM, 1901). The one definition in imupipe: import it from here.
STANDARD_GRAVITY = 9.80665

#: SI unit of each sensor's rate (what imupipe stores and computes in). The one definition in imupipe.
SI_UNITS = {"gyro": "rad/s", "accel": "m/s^2"}

#: Quantities accepted by :func:`to_si` / :func:`from_si`.
QUANTITIES = ("rate", "gm_sigma", "white", "random_walk", "time", "quantization", "ramp")

#: Sensors accepted by :func:`to_si` / :func:`from_si`.
SENSORS = ("gyro", "accel")

_F = Fraction

# name -> (SI factor, (angle, length, time))
_UNITS = {
    "rad": (1.0, (_F(1), _F(0), _F(0))),
    "deg": (math.pi / 180.0, (_F(1), _F(0), _F(0))),
    "s": (1.0, (_F(0), _F(0), _F(1))),
    "min": (60.0, (_F(0), _F(0), _F(1))),
    "h": (3600.0, (_F(0), _F(0), _F(1))),
    "hr": (3600.0, (_F(0), _F(0), _F(1))),
    "Hz": (1.0, (_F(0), _F(0), _F(-1))),
    "m": (1.0, (_F(0), _F(1), _F(0))),
    "mrad": (1e-3, (_F(1), _F(0), _F(0))),
    "urad": (1e-6, (_F(1), _F(0), _F(0))),
    "mdeg": (math.pi / 180.0e3, (_F(1), _F(0), _F(0))),
    "arcmin": (math.pi / 180.0 / 60.0, (_F(1), _F(0), _F(0))),
    "arcsec": (math.pi / 180.0 / 3600.0, (_F(1), _F(0), _F(0))),
    "ms": (1e-3, (_F(0), _F(0), _F(1))),
    "us": (1e-6, (_F(0), _F(0), _F(1))),
    "ns": (1e-9, (_F(0), _F(0), _F(1))),
    "mm": (1e-3, (_F(0), _F(1), _F(0))),
    "cm": (1e-2, (_F(0), _F(1), _F(0))),
    "km": (1e3, (_F(0), _F(1), _F(0))),
    "g": (STANDARD_GRAVITY, (_F(0), _F(1), _F(-2))),
    "mg": (STANDARD_GRAVITY * 1e-3, (_F(0), _F(1), _F(-2))),
    "ug": (STANDARD_GRAVITY * 1e-6, (_F(0), _F(1), _F(-2))),
    "kHz": (1e3, (_F(0), _F(0), _F(-1))),
    "ppm": (1e-6, (_F(0), _F(0), _F(0))),
}

_RATE = {
    "gyro": (_F(1), _F(0), _F(-1)),
    "accel": (_F(0), _F(1), _F(-2)),
}

# time exponent added to the sensor's rate dimension
_TIME_SHIFT = {
    "rate": _F(0),
    "gm_sigma": _F(0),
    "white": _F(1, 2),
    "random_walk": _F(-1, 2),
    "quantization": _F(1),
    "ramp": _F(-1),
}


class UnitError(ValueError):
    """A unit string that is empty, unparseable, unknown or of the wrong dimension."""


class ParsedUnit(NamedTuple):
    """Result of :func:`parse_unit`.

    Attributes
    ----------
    factor : float
        Multiply a value in this unit by ``factor`` to get SI.
    dimension : tuple of fractions.Fraction
        Exponents of (angle, length, time).
    """

    factor: float
    dimension: tuple


_TOKEN = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>[A-Za-z_]+)|(?P<op>\*\*|[*/^()\-.]))"
)

#: Spellings rewritten by :func:`normalise_unit` before parsing (whole unit, case-insensitive), then
#: the symbol substitutions of :data:`_SYMBOLS` (anywhere in the unit).
SPELLINGS = {
    "dps": "deg/s",
    "dph": "deg/h",
    "deg/sec": "deg/s",
    "deg/hr": "deg/h",
    "rad/sec": "rad/s",
    "rad/hr": "rad/h",
    "m/s/s": "m/s^2",
    "m/s2": "m/s^2",
    "mm/s2": "mm/s^2",
    "g0": "g",
    "gee": "g",
    "micro-g": "ug",
    "micro g": "ug",
    "milli-g": "mg",
    "milli g": "mg",
    "sec": "s",
    "second": "s",
    "seconds": "s",
    "hour": "h",
    "hours": "h",
    "minute": "min",
    "minutes": "min",
    "degree": "deg",
    "degrees": "deg",
    "radian": "rad",
    "radians": "rad",
}
# (symbol or word inside a unit, replacement), applied in order
_SYMBOLS = (
    ("√(", "sqrt("),
    ("√", "sqrt "),  # "√Hz" -> "sqrt Hz" -> handled below
    ("µ", "u"),  # MICRO SIGN
    ("μ", "u"),  # GREEK SMALL LETTER MU
    ("°", "deg"),
    ("º", "deg"),  # masculine ordinal, often typed for a degree sign
    ("⁻¹", "^-1"),
    ("⁻²", "^-2"),
    ("²", "^2"),
    ("³", "^3"),
    ("½", "(1/2)"),
    ("·", "*"),
    ("⋅", "*"),
    ("×", "*"),
)
_SQRT_WORD = re.compile(r"(?:\bsqrt|\brt|\bsq)\s*(Hz|h|hr|s|sec|min)\b|\brt(Hz|h|hr|s)\b")
_DPS = re.compile(r"\bdps\b")
_DPH = re.compile(r"\bdph\b")
_SEC = re.compile(r"\b(?:secs?|seconds?)\b")
_WORDS = ((re.compile(r"\bdegrees?\b"), "deg"), (re.compile(r"\bradians?\b"), "rad"), (re.compile(r"\bhours?\b"), "h"))
_HR = re.compile(r"\bhrs\b")


def normalise_unit(unit):
    """Rewrite a datasheet / CF spelling of a unit into the module grammar.

    ``"°/s"`` -> ``"deg/s"``, ``"µg/√Hz"`` -> ``"ug/sqrt(Hz)"``, ``"mg/rtHz"`` -> ``"mg/sqrt(Hz)"``,
    ``"dps"`` -> ``"deg/s"``, ``"deg/sec"`` -> ``"deg/s"``, ``"m/s²"`` -> ``"m/s^2"``; CF forms
    such as ``"rad s-1"`` are left to the parser (juxtaposition multiplies, a trailing integer is an
    exponent). Whole-unit spellings: :data:`SPELLINGS`.

    Parameters
    ----------
    unit : str

    Returns
    -------
    str
    """
    text = " ".join(str(unit).split())
    whole = SPELLINGS.get(text.lower())
    if whole is not None:
        return whole
    for symbol, repl in _SYMBOLS:
        text = text.replace(symbol, repl)
    text = _SQRT_WORD.sub(lambda m: f"sqrt({m.group(1) or m.group(2)})", text)
    text = _DPS.sub("(deg/s)", text)
    text = _DPH.sub("(deg/h)", text)
    text = _SEC.sub("s", text)
    for pattern, repl in _WORDS:
        text = pattern.sub(repl, text)
    text = _HR.sub("h", text)
    text = text.replace("**", "^")
    return " ".join(text.split())


def _tokenize(text):
    tokens = []
    pos = 0
    text = text.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise UnitError(f"unexpected character {text[pos:].strip()[:1]!r} at position {pos}")
        pos = m.end()
        if m.group("num") is not None:
            tokens.append(("num", m.group("num")))
        elif m.group("name") is not None:
            tokens.append(("name", m.group("name")))
        else:
            tokens.append(("op", m.group("op")))
    return tokens


class _Parser:
    def __init__(self, text):
        self.text = text
        self.tokens = _tokenize(text)
        self.i = 0

    def peek(self):
        return self.tokens[self.i] if self.i < len(self.tokens) else (None, None)

    def take(self, kind=None, value=None):
        tok = self.peek()
        if tok[0] is None or (kind is not None and tok[0] != kind) or (value is not None and tok[1] != value):
            want = value or kind or "a token"
            got = "end of unit" if tok[0] is None else repr(tok[1])
            raise UnitError(f"expected {want!r}, got {got}")
        self.i += 1
        return tok

    def parse(self):
        if not self.tokens:
            raise UnitError("empty unit")
        result = self.product()
        if self.i != len(self.tokens):
            raise UnitError(f"unexpected {self.peek()[1]!r} after a complete unit")
        return result

    def product(self):
        factor, dim = self.power()
        while self.peek() in (("op", "*"), ("op", "/"), ("op", ".")) or self.peek()[0] == "name" or self.peek() == (
            "op",
            "(",
        ):
            op = self.take()[1] if self.peek()[0] == "op" and self.peek()[1] in "*/." else "*"
            op = "*" if op == "." else op
            f2, d2 = self.power()
            if op == "*":
                factor, dim = factor * f2, tuple(a + b for a, b in zip(dim, d2))
            else:
                factor, dim = factor / f2, tuple(a - b for a, b in zip(dim, d2))
        return factor, dim

    def power(self):
        named = self.peek()[0] == "name"
        factor, dim = self.atom()
        if self.peek() in (("op", "^"), ("op", "**")):
            self.take()
            e = self.exponent()
            factor, dim = factor ** float(e), tuple(a * e for a in dim)
        elif named and (
            (self.peek()[0] == "num" and re.fullmatch(r"\d+", self.peek()[1]))
            or (
                self.peek() == ("op", "-")
                and self.i + 1 < len(self.tokens)
                and self.tokens[self.i + 1][0] == "num"
                and re.fullmatch(r"\d+", self.tokens[self.i + 1][1])
            )
        ):  # CF / UDUNITS exponent: "s-1", "m s-2", "s2"
            e = self._number()
            factor, dim = factor ** float(e), tuple(a * e for a in dim)
        return factor, dim

    def _number(self):
        sign = 1
        if self.peek() == ("op", "-"):
            self.take()
            sign = -1
        return sign * Fraction(self.take("num")[1])

    def exponent(self):
        if self.peek() == ("op", "("):
            self.take()
            e = self._number()
            if self.peek() == ("op", "/"):
                self.take()
                q = self._number()
                if q == 0:
                    raise UnitError("zero denominator in exponent")
                e = e / q
            self.take("op", ")")
            return e
        return self._number()

    def atom(self):
        kind, value = self.peek()
        if kind == "num":
            self.take()
            x = float(value)
            if x <= 0 or not math.isfinite(x):
                raise UnitError(f"numeric factor must be positive and finite, got {value}")
            return x, (_F(0), _F(0), _F(0))
        if kind == "name":
            self.take()
            if value == "sqrt":
                self.take("op", "(")
                factor, dim = self.product()
                self.take("op", ")")
                return math.sqrt(factor), tuple(a / 2 for a in dim)
            try:
                return _UNITS[value]
            except KeyError:
                known = ", ".join(sorted(_UNITS))
                raise UnitError(f"unknown unit name {value!r} (known: {known}, sqrt(...))") from None
        if (kind, value) == ("op", "("):
            self.take()
            result = self.product()
            self.take("op", ")")
            return result
        got = "end of unit" if kind is None else repr(value)
        raise UnitError(f"expected a unit name, number or '(', got {got}")


def parse_unit(unit):
    """Parse a unit string.

    Parameters
    ----------
    unit : str
        Unit in the grammar of the module docstring, e.g. ``"(deg/h)/sqrt(s)"``.

    Returns
    -------
    ParsedUnit
        ``factor`` (value in unit * factor = SI value) and ``dimension``
        (exponents of angle, length, time as fractions).

    Raises
    ------
    UnitError
        Empty, non-string, unknown or unparseable unit.
    """
    if not isinstance(unit, str):
        raise UnitError(f"unit must be a string, got {type(unit).__name__} {unit!r}")
    if not unit.strip():
        raise UnitError("empty unit")
    try:
        factor, dim = _Parser(normalise_unit(unit)).parse()
    except UnitError as exc:
        raise UnitError(f"cannot parse unit {unit!r}: {exc}") from None
    return ParsedUnit(float(factor), tuple(dim))


def expected_dimension(quantity, sensor):
    """Dimension (angle, length, time exponents) of ``quantity`` for ``sensor``.

    Parameters
    ----------
    quantity : {'rate', 'gm_sigma', 'white', 'random_walk', 'time', 'quantization', 'ramp'}
    sensor : {'gyro', 'accel'}

    Returns
    -------
    tuple of fractions.Fraction
    """
    if quantity not in QUANTITIES:
        raise UnitError(f"unknown quantity {quantity!r}; expected one of {', '.join(QUANTITIES)}")
    if sensor not in SENSORS:
        raise UnitError(f"unknown sensor {sensor!r}; expected one of {', '.join(SENSORS)}")
    if quantity == "time":
        return (_F(0), _F(0), _F(1))
    a, l, t = _RATE[sensor]
    return (a, l, t + _TIME_SHIFT[quantity])


def format_dimension(dim):
    """Human-readable form of a dimension tuple, e.g. ``'angle time^(-1/2)'``."""
    parts = []
    for name, e in zip(("angle", "length", "time"), dim):
        if e == 0:
            continue
        parts.append(name if e == 1 else f"{name}^({e})" if e.denominator != 1 or e < 0 else f"{name}^{e}")
    return " ".join(parts) or "dimensionless"


_EXAMPLES = {
    ("gyro", "rate"): "deg/h",
    ("gyro", "gm_sigma"): "deg/h",
    ("gyro", "white"): "deg/sqrt(h)",
    ("gyro", "random_walk"): "(deg/h)/sqrt(s)",
    ("gyro", "quantization"): "deg",
    ("gyro", "ramp"): "deg/h^2",
    ("accel", "rate"): "mg",
    ("accel", "gm_sigma"): "mg",
    ("accel", "white"): "m/s/sqrt(h)",
    ("accel", "random_walk"): "m/s^2/sqrt(s)",
    ("accel", "quantization"): "m/s",
    ("accel", "ramp"): "m/s^3",
}


def _check(unit, quantity, sensor, key):
    label = f"{key}: " if key else ""
    try:
        want = expected_dimension(quantity, sensor)
        parsed = parse_unit(unit)
    except UnitError as exc:
        raise UnitError(f"{label}{exc}") from None
    if parsed.dimension != want:
        example = _EXAMPLES.get((sensor, quantity), "s")
        msg = (
            f"{label}unit {unit!r} has dimension {format_dimension(parsed.dimension)}, "
            f"but the {sensor} {quantity} needs {format_dimension(want)} (e.g. {example!r})"
        )
        if quantity == "random_walk" and parsed.dimension == _RATE[sensor]:
            msg += (
                ". Common mistake: K read at tau = 3 s of an ADEV plotted in "
                f"{unit} is in ({unit})/sqrt(s), not {unit} (docs/method.md, section 'Slip: units of K'); "
                "name the unit explicitly"
            )
        elif quantity == "white" and parsed.dimension == _RATE[sensor]:
            msg += ". A noise density is rate/sqrt(Hz); an angle/velocity random walk is e.g. deg/sqrt(h)"
        raise UnitError(msg)
    return parsed.factor


def to_si(value, unit, quantity, sensor, key=None):
    """Convert ``value`` given in ``unit`` to SI after checking its dimension.

    Parameters
    ----------
    value : float or array_like
        Value in ``unit``.
    unit : str
        Unit string (module grammar), e.g. ``"deg/sqrt(h)"``.
    quantity : {'rate', 'gm_sigma', 'white', 'random_walk', 'time', 'quantization', 'ramp'}
        What the value is (module docstring table).
    sensor : {'gyro', 'accel'}
        Gyro rate is angle/time (SI rad/s), accel rate is length/time^2 (SI m/s^2).
    key : str, optional
        Name of the value (e.g. ``"gyro.random_walk"``), quoted in error messages.

    Returns
    -------
    float or ndarray
        Value in SI: rad, m, s combinations, e.g. rad/sqrt(s) for a gyro ``white``.

    Raises
    ------
    UnitError
        Unit empty, unparseable, unknown, or of the wrong dimension for the quantity;
        unknown quantity or sensor.
    """
    return value * _check(unit, quantity, sensor, key)


def from_si(value_si, unit, quantity, sensor, key=None):
    """Convert an SI value to ``unit``; inverse of :func:`to_si` (same parameters and errors).

    Parameters
    ----------
    value_si : float or array_like
        Value in SI.
    unit, quantity, sensor, key
        As in :func:`to_si`.

    Returns
    -------
    float or ndarray
        Value in ``unit``.
    """
    return value_si / _check(unit, quantity, sensor, key)


def rate_factor(unit, sensor, key=None):
    """SI factor of a sensor's rate unit (rad/s per gyro unit, m/s^2 per accel unit).

    Accepts every spelling of :func:`parse_unit` / :func:`normalise_unit` (``deg/s``, ``dps``, ``°/s``,
    ``mrad/s``, ``mdeg/s``, ``rad s-1``, ``g``, ``mg``, ``µg``, ``mm/s^2``, ``m s-2``, ...).

    Parameters
    ----------
    unit : str
        Unit of the stored samples.
    sensor : {'gyro', 'accel'}
    key : str, optional
        Where the unit comes from, quoted in errors.

    Returns
    -------
    float
        ``x_SI = factor * x``.

    Raises
    ------
    UnitError
        Unparseable unit, or not a rate of ``sensor`` (angle/time for gyro, length/time^2 for accel).
    """
    return float(_check(unit, "rate", sensor, key))


_UNIT_SUFFIX = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]+?)\s*[\])]\s*$")


def split_unit_suffix(name: str) -> tuple[str, str | None]:
    """(name without a bracketed unit suffix, the unit or None) of a column header: ``"gx [deg/s]"`` ->
    ``("gx", "deg/s")``, ``"t (s)"`` -> ``("t", "s")``, ``"gx"`` -> ``("gx", None)``."""
    m = _UNIT_SUFFIX.match(str(name))
    return (m.group(1), m.group(2)) if m else (str(name), None)


def header_rate_unit(name: str, sensor: str) -> str | None:
    """The rate unit a column header states for `sensor` (``"gx [rad/s]"`` -> ``"rad/s"``), or None when the header
    has no bracketed suffix or its suffix is not a rate unit of `sensor` (``"gx (filtered)"``: a note, not a unit).
    A header's unit is the file's statement of its unit, as a netCDF variable's ``units`` attribute is."""
    unit = split_unit_suffix(name)[1]
    if unit is None:
        return None
    try:
        rate_factor(unit, sensor)
    except UnitError:
        return None
    return unit
