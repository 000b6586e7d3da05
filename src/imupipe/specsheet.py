r"""Spec sheets (and simulation truths): YAML files of noise parameters, each value with its unit.

A spec sheet states, per sensor type, the stochastic parameters of a manufacturer's data sheet.
Every value carries an explicit unit, converted once to SI by :mod:`imupipe.units`; a missing or
ambiguous unit is an error that names the file and the key. Components a sheet leaves out are
absent from the model (the bound then adds them only if the data need them, docs/method.md, section "The bound")::

    name: STIM-300
    source: Gallon et al. 2021, Table 2
    gyro:
      white: {value: 0.15, unit: deg/sqrt(h)}           # N (angle random walk)
      gauss_markov:                                     # first-order GM terms (bias instability)
        - sigma: {value: 1.5, unit: deg/h}
          T: {value: 1500, unit: s}
      random_walk: {value: 2.0e-2, unit: (deg/h)/sqrt(s)}  # K (rate random walk)
    accel:
      ...

Optional per sensor: ``flicker`` (B, rate unit), ``quantization`` (Q, e.g. deg or m/s),
``ramp`` (R, e.g. deg/h^2) and ``turn_on_bias`` (the turn-on bias or bias repeatability, 1 sigma, rate unit, e.g.
deg/h or mg: not a PSD term; it sets the least initial bias variance of the exported filter,
:mod:`imupipe.biasinit`). The same format describes the "true" model of simulated data.

Model PSDs are two-sided (docs/method.md, section "Conventions: the PSD"): :math:`S_2 = N^2 + \sum 2\sigma^2 T/(1 + (2\pi f T)^2)
+ K^2/(2\pi f)^2 + B^2/(2\pi f)`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from imupipe.models import NoiseModel
from imupipe.units import UnitError, from_si, to_si

__all__ = ["SpecError", "SpecSheet", "load_spec", "parse_spec", "display_units", "model_in_units", "inflation_rows",
           "SENSOR_KEYS"]

#: Keys allowed under a sensor, with the imupipe.units quantity of their value.
SENSOR_KEYS = {
    "white": "white",
    "gauss_markov": None,  # list of {sigma: gm_sigma, T: time}
    "random_walk": "random_walk",
    "flicker": "rate",
    "quantization": "quantization",
    "ramp": "ramp",
    "turn_on_bias": "rate",  # turn-on bias / bias repeatability, 1 sigma (not a PSD term: the filter's initial bias)
}
_TOP_KEYS = {"name", "source", "notes", "gyro", "accel"}


class SpecError(ValueError):
    """A spec sheet is missing, malformed, or has a value without a valid unit."""


@dataclass(frozen=True)
class SpecSheet:
    """A loaded spec sheet.

    Attributes
    ----------
    name : str
        Human-readable name (``name`` key, else the file stem).
    path : str
        File it came from.
    models : dict
        ``{sensor: NoiseModel}`` in SI for the sensors the sheet describes.
    units : dict
        ``{sensor: {quantity: unit}}`` as written in the sheet (``white``, ``gm_sigma``, ``time``,
        ``random_walk``, ``flicker``, ...), to report results in the sheet's own units.
    values : dict
        ``{sensor: {parameter: (value, unit)}}`` exactly as written (``gm_sigma_1``, ``gm_T_1`` for
        GM terms), for tables.
    turn_on_bias : dict
        ``{sensor: turn-on bias, 1 sigma, SI}`` for the sensors whose sheet gives one.
    """

    name: str
    path: str
    models: dict
    units: dict
    values: dict = field(default_factory=dict)
    turn_on_bias: dict = field(default_factory=dict)


#: Largest plausible SI value of a spec-sheet parameter (rate-based quantities in their SI unit built on
#: seconds, e.g. rad/sqrt(s) for a gyro white noise); the same limits as the readers' samples (gyro
#: 1e3, accel 1e4), and 1e10 s (~300 years) for a correlation time. Beyond them the value is a typo or
#: a wrong unit, and its square (the PSD level) may overflow.
PLAUSIBLE_SI = {"gyro": 1.0e3, "accel": 1.0e4, "time": 1.0e10}


def _is_float(text):
    try:
        float(text)
    except ValueError:
        return False
    return True


def _number(value, label):
    """A YAML value as a float: numbers, and strings such as ``1.5e3`` that YAML 1.1 leaves as strings."""
    if isinstance(value, str):
        try:
            return float(value.strip().replace("_", ""))
        except ValueError:
            raise SpecError(f"{label}.value = {value!r} is not a number") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(f"{label}.value must be a finite non-negative number, got {value!r}")
    return float(value)


def _quantity(sensor_block, key, quantity, sensor, where, path=None):
    item = sensor_block[key]
    label = f"{where}: {path or sensor}.{key}"
    if (isinstance(item, (int, float)) and not isinstance(item, bool)) or (isinstance(item, str) and _is_float(item)):
        raise SpecError(
            f"{label} = {item!r} has no unit; write it as {{value: {item!r}, unit: <unit>}} "
            f"(every value needs an explicit unit)"
        )
    if not isinstance(item, dict) or set(item) != {"value", "unit"}:
        raise SpecError(f"{label} must be a mapping with exactly the keys 'value' and 'unit', got {item!r}")
    value = _number(item["value"], label)
    if not math.isfinite(value) or value < 0:
        raise SpecError(f"{label}.value must be a finite non-negative number, got {item['value']!r}")
    try:
        si = float(to_si(value, item["unit"], quantity, sensor, key=label))
    except UnitError as exc:
        raise SpecError(str(exc)) from None
    limit = PLAUSIBLE_SI["time" if quantity == "time" else sensor]
    if not (math.isfinite(si) and si <= limit and math.isfinite(si * si)):
        raise SpecError(
            f"{label}.value = {value:g} {item['unit']} is {si:.3g} in SI, beyond the plausible limit "
            f"{limit:g} for the {sensor} {quantity} (a typo or a wrong unit?)"
        )
    return si, value, item["unit"]


def parse_spec(data, where: str = "<spec>") -> SpecSheet:
    """Build a :class:`SpecSheet` from already-parsed YAML (a dict); `where` names it in errors."""
    if not isinstance(data, dict):
        raise SpecError(f"{where}: a spec sheet is a mapping with keys gyro and/or accel, got {type(data).__name__}")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise SpecError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    sensors = [s for s in ("gyro", "accel") if s in data]
    if not sensors:
        raise SpecError(f"{where}: no 'gyro' or 'accel' section")
    models, units, values, turn_on = {}, {}, {}, {}
    for sensor in sensors:
        block = data[sensor]
        if not isinstance(block, dict) or not block:
            raise SpecError(f"{where}: {sensor} must be a non-empty mapping of noise parameters")
        bad = set(block) - set(SENSOR_KEYS)
        if bad:
            raise SpecError(f"{where}: {sensor}: unknown key(s) {sorted(bad)}; allowed: {sorted(SENSOR_KEYS)}")
        kw, u, v = {}, {}, {}
        for key, quantity in SENSOR_KEYS.items():
            if key not in block or key == "gauss_markov":
                continue
            si, raw, unit = _quantity(block, key, quantity, sensor, where)
            kw[key] = si
            u[key] = unit
            v[key] = (raw, unit)
        gms = block.get("gauss_markov") or []
        if isinstance(gms, dict):
            gms = [gms]
        if not isinstance(gms, list):
            raise SpecError(f"{where}: {sensor}.gauss_markov must be a list of {{sigma, T}} terms")
        terms = []
        for i, term in enumerate(gms, start=1):
            if not isinstance(term, dict) or set(term) != {"sigma", "T"}:
                raise SpecError(f"{where}: {sensor}.gauss_markov[{i - 1}] needs exactly the keys 'sigma' and 'T'")
            gm_path = f"{sensor}.gauss_markov[{i - 1}]"
            s_si, s_raw, s_unit = _quantity(term, "sigma", "gm_sigma", sensor, where, gm_path)
            t_si, t_raw, t_unit = _quantity(term, "T", "time", sensor, where, gm_path)
            if t_si <= 0:
                raise SpecError(f"{where}: {sensor}.gauss_markov[{i - 1}].T must be > 0")
            terms.append((s_si, t_si))
            u.setdefault("gm_sigma", s_unit)
            u.setdefault("time", t_unit)
            v[f"gm_sigma_{i}"] = (s_raw, s_unit)
            v[f"gm_T_{i}"] = (t_raw, t_unit)
        kw["gauss_markov"] = tuple(terms)
        if "turn_on_bias" in kw:
            turn_on[sensor] = kw.pop("turn_on_bias")
        models[sensor] = NoiseModel(**kw)
        units[sensor] = u
        values[sensor] = v
    return SpecSheet(name=str(data.get("name") or where), path=where, models=models, units=units, values=values,
                     turn_on_bias=turn_on)


def load_spec(path) -> SpecSheet:
    """Read a spec sheet YAML file (module docstring); errors name the file and the key.

    Parameters
    ----------
    path : str or Path
        YAML file.

    Returns
    -------
    SpecSheet
        Models in SI (gyro rad/s, accel m/s^2) and the sheet's own units.
    """
    import yaml

    p = Path(path)
    if not p.is_file():
        raise SpecError(f"spec sheet {str(p)!r} not found")
    from imupipe.io import DuplicateKeyError, read_yaml

    try:
        data = read_yaml(p)  # the project's one YAML loader: a key given twice is refused, naming both lines
    except DuplicateKeyError as exc:
        raise SpecError(str(exc)) from None
    except yaml.YAMLError as exc:
        raise SpecError(f"{p}: not valid YAML ({exc})") from None
    sheet = parse_spec(data, where=str(p))
    if not (isinstance(data, dict) and data.get("name")):
        sheet = SpecSheet(p.stem, str(p), sheet.models, sheet.units, sheet.values, sheet.turn_on_bias)
    return sheet


def _default_units(sensor):
    if sensor == "gyro":
        return {"white": "deg/sqrt(h)", "gm_sigma": "deg/h", "time": "s", "random_walk": "(deg/h)/sqrt(s)"}
    return {"white": "m/s/sqrt(h)", "gm_sigma": "mg", "time": "s", "random_walk": "m/s^2/sqrt(s)"}


def display_units(spec: SpecSheet, sensor: str) -> dict:
    """Units to report `sensor`'s parameters in: the sheet's own, completed by customary ones.

    Keys ``white``, ``gm_sigma``, ``time``, ``random_walk`` (and ``flicker`` if the sheet has it). A
    sheet without a GM term but with flicker reports GM sigma in the flicker's unit; otherwise gyro
    deg/sqrt(h), deg/h, s, (deg/h)/sqrt(s) and accel m/s/sqrt(h), mg, s, m/s^2/sqrt(s).
    """
    units = {**_default_units(sensor), **spec.units.get(sensor, {})}
    if "gm_sigma" not in spec.units.get(sensor, {}) and "flicker" in units:
        units["gm_sigma"] = units["flicker"]
    return units


def model_in_units(model: NoiseModel, units: dict, sensor: str) -> tuple[dict | None, str | None]:
    """A model's filter parameters in report units (e.g. :func:`display_units`), each value beside its unit.

    ``value_unit = value_SI / factor(unit)`` (:func:`imupipe.units.from_si`) for white noise N (key ``white``),
    random walk K (``random_walk``) and each Gauss-Markov term's sigma (``gm_sigma``) and correlation time T
    (``time``); a quantity whose key `units` lacks is left out (flicker, quantization and ramp are not filter
    states and are not converted).

    Parameters
    ----------
    model : NoiseModel
        Parameters in SI (u = rad/s gyro, m/s^2 accel: N u/sqrt(Hz), sigma u, T s, K u/sqrt(s)).
    units : dict
        Unit string per quantity key (``white``, ``random_walk``, ``gm_sigma``, ``time``).
    sensor : str
        ``gyro`` or ``accel`` (the unit's dimension is checked against it).

    Returns
    -------
    (dict or None, str or None)
        ``{"white": {"value", "unit"}, "random_walk": {...}, "gauss_markov": [{"sigma": {...}, "T": {...}}, ...]}``
        and None; or None and a note saying why the conversion failed (a unit of the wrong dimension), in
        which case a report keeps SI only.
    """
    def conv(v, q):
        return {"value": float(from_si(v, units[q], q, sensor, q)), "unit": units[q]}

    try:
        out = {q: conv(getattr(model, q), q) for q in ("white", "random_walk") if q in units}
        out["gauss_markov"] = [{k: conv(v, q) for k, v, q in (("sigma", s, "gm_sigma"), ("T", T, "time"))
                                if q in units}
                               for s, T in model.gauss_markov]
    except UnitError as exc:
        return None, f"unit conversion failed ({exc}); values in SI only"
    return out, None


def inflation_rows(spec: SpecSheet, sensor: str, bound_model: NoiseModel) -> list[dict]:
    """Table 2 rows: parameter, unit, spec value, bound value and their ratio, in the sheet's units.

    Units from :func:`display_units`. A parameter absent from the spec has spec value None and ratio
    None (the bound added it); a spec flicker B is listed with no bound value (no filter state: the
    bound's GM terms cover it). Each narrowband term of the bound (a spectral line the lines policy ``model``
    made a filter state: two states each) is a row of its sigma in the GM sigma's unit, named with its frequency
    and damping (a spec sheet lists none).
    """
    units = display_units(spec, sensor)
    specm = spec.models.get(sensor, NoiseModel())

    def conv(v, q):
        return float(from_si(v, units[q], "rate" if q == "flicker" else q, sensor)) if v else None

    rows = [("white noise N", "white", specm.white, bound_model.white)]
    n = max(len(specm.gauss_markov), len(bound_model.gauss_markov))
    for i in range(n):
        s = specm.gauss_markov[i] if i < len(specm.gauss_markov) else (0.0, 0.0)
        b = bound_model.gauss_markov[i] if i < len(bound_model.gauss_markov) else (0.0, 0.0)
        tag = f" {i + 1}" if n > 1 else ""
        rows.append((f"GM sigma{tag}", "gm_sigma", s[0], b[0]))
        rows.append((f"GM T{tag}", "time", s[1], b[1]))
    rows.append(("random walk K", "random_walk", specm.random_walk, bound_model.random_walk))
    if specm.flicker:  # not a filter state: the bound covers it with its GM terms, or its random walk without any
        by = "GM" if bound_model.gauss_markov else "random walk" if bound_model.random_walk > 0 else "white noise"
        rows.append((f"flicker B (covered by {by})", "flicker", specm.flicker, 0.0))
    # a line the bound gave no power (sigma 0: its bins covered by the broadband terms) is no filter state
    states = [ln for ln in getattr(bound_model, "narrowband", ()) or () if ln[0] > 0]
    for i, (sg, f0, zeta) in enumerate(states, start=1):
        rows.append((f"line {i} sigma ({f0:.4g} Hz, damping {zeta:.3g})", "gm_sigma", 0.0, sg))
    out = []
    for label, q, sv, bv in rows:
        a, b = conv(sv, q), conv(bv, q)
        out.append({
            "parameter": label,
            "unit": units[q],
            "spec": a,
            "bound": b,
            "ratio": (b / a) if (a and b is not None) else None,
        })
    return out
