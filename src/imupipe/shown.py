"""How the run summary shows a value: three significant digits, and a value of the model in the spec sheet's unit
beside its SI one (the unit the contract states for it, else the unit data sheets use). Plain dicts in (the
contract's ``*_spec_units`` blocks), strings out; the conversions are :mod:`imupipe.units`'s."""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["KALIBR_SI", "SI_SPELLING", "SPEC_LIKE_UNITS", "both_units", "in_spec_units", "num", "p_text",
           "ratio_text", "spec_unit"]


def num(v, fmt="{:.3g}") -> str:
    """`v` formatted by `fmt` (three significant digits by default); ``"-"`` for None, the text of anything else
    that is not a number."""
    try:
        return fmt.format(float(v))
    except (TypeError, ValueError):
        return "-" if v is None else str(v)


def p_text(test: Mapping, label: bool = True) -> str:
    """``"p = 0.031"`` of a test's record (its ``p_value``), or ``"p <= 0.0099"`` where the p-value is the smallest
    its bootstrap can give (``p_value_resolution``, 1 / (1 + replicates)): no replicate reached the statistic, and
    the true p may be far smaller (a p below that floor is a tail p computed otherwise, shown as it is). Without
    `label` (a table's p column): ``"0.031"`` or ``"<= 0.0099"``."""
    p, res = test.get("p_value"), test.get("p_value_resolution")
    try:
        floor = res is not None and abs(float(p) - float(res)) <= 1e-9 * float(res)
    except (TypeError, ValueError):
        floor = False
    text = f"<= {num(res)}" if floor else num(p)
    return (f"p {text}" if floor else f"p = {text}") if label else text


def ratio_text(v) -> str:
    """A ratio to a limit of 1 (an MSE/P, an AV or PSD margin) with the digits that tell it from 1: three
    significant digits as :func:`num`, more where three round it to 1 (1.00015, not 1: a check that failed at
    1.00015 must not read "1"); ``"-"`` for None."""
    text = num(v)
    try:
        x = float(v)
    except (TypeError, ValueError):
        return text
    digits = 4
    while x != 1.0 and float(text) == 1.0 and digits <= 12:
        text, digits = f"{x:.{digits}g}", digits + 1
    return text


#: SI unit of each value a summary pastes, per sensor (u = rad/s or m/s^2): the KF file's white noise N and
#: random walk K (imupipe.units), Kalibr's fields as Kalibr spells them (its random walk rad/s^2/sqrt(Hz) is the
#: same dimension as rad/s/sqrt(s)).
SI_SPELLING = {
    ("gyro", "white"): "rad/s/sqrt(Hz)", ("gyro", "random_walk"): "rad/s/sqrt(s)", ("gyro", "gm_sigma"): "rad/s",
    ("accel", "white"): "m/s^2/sqrt(Hz)", ("accel", "random_walk"): "m/s^2/sqrt(s)", ("accel", "gm_sigma"): "m/s^2",
}
KALIBR_SI = {("gyro", "white"): "rad/s/sqrt(Hz)", ("gyro", "random_walk"): "rad/s^2/sqrt(Hz)",
             ("accel", "white"): "m/s^2/sqrt(Hz)", ("accel", "random_walk"): "m/s^3/sqrt(Hz)"}


def spec_unit(bound: Mapping, key: str) -> str | None:
    """The spec sheet's unit of `key` (``white``, ``random_walk`` or ``gm_sigma``) as the contract states it: the
    exported model's, else the bound's, else the spec sheet's (``*_spec_units`` blocks); None when none states it."""
    for block in ("model_spec_units", "bound_spec_units", "spec_spec_units"):
        b = bound.get(block)
        if not isinstance(b, Mapping):
            continue
        if key == "gm_sigma":
            gms = b.get("gauss_markov") or []
            v = gms[0].get("sigma") if gms and isinstance(gms[0], Mapping) else None
        else:
            v = b.get(key)
        if isinstance(v, Mapping) and v.get("unit"):
            return str(v["unit"])
    return None


#: The spec-sheet-like unit a value is shown in when the contract states no spec-sheet unit for it (a spec sheet
#: without a GM term, e.g. one that gives white noise and a bias-instability floor only): the units data sheets use.
SPEC_LIKE_UNITS = {
    ("gyro", "white"): "deg/sqrt(h)", ("gyro", "random_walk"): "(deg/h)/sqrt(s)", ("gyro", "gm_sigma"): "deg/h",
    ("accel", "white"): "m/s/sqrt(h)", ("accel", "random_walk"): "m/s^2/sqrt(s)", ("accel", "gm_sigma"): "mg",
}


def in_spec_units(bound: Mapping, key: str, value_si: float) -> tuple[float, str]:
    """`value_si` (SI) in the spec sheet's unit of `key` (:func:`spec_unit`, :func:`imupipe.units.from_si`; where the
    contract states none, the data sheets' usual unit :data:`SPEC_LIKE_UNITS`), or the SI value with its SI unit when
    the sensor is not gyro / accel."""
    from imupipe.units import UnitError, from_si

    sensor = bound.get("sensor")
    for unit in dict.fromkeys((spec_unit(bound, key), SPEC_LIKE_UNITS.get((sensor, key)))):
        if unit and sensor in ("gyro", "accel"):
            try:
                return float(from_si(float(value_si), unit, key, sensor)), unit
            except UnitError:  # a unit of another quantity or sensor: the next one
                continue
    return float(value_si), SI_SPELLING.get((sensor, key), "SI")


def both_units(sensor: str, bound: Mapping | None, key: str, value_si) -> str:
    """``"<value> <spec unit> (<value> <SI unit>)"``: a value of `key` (``white``, ``random_walk``, ``gm_sigma``)
    given in SI, shown in the spec sheet's unit (:func:`in_spec_units`) and in SI; ``"-"`` for no number."""
    try:
        v = float(value_si)
    except (TypeError, ValueError):
        return "-"
    vs, us = in_spec_units({**(bound or {}), "sensor": sensor}, key, v)
    si = SI_SPELLING.get((sensor, key), "SI")
    return f"{num(vs)} {us}" + ("" if us == si else f" ({num(v)} {si})")
