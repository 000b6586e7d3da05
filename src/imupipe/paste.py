"""The values a user pastes into a filter (the run summary's first screen): the exported filter model's terms and
the initial standard deviation of its bias state, and Kalibr's densities, each in the spec sheet's unit and in SI.
Plain dicts in (the contract and the Kalibr file as read), rows out; shown by :mod:`imupipe.summary`."""

from __future__ import annotations

import math
from collections.abc import Mapping

from imupipe.shown import KALIBR_SI, SI_SPELLING, in_spec_units, num

__all__ = ["paste_rows"]


#: Kalibr's noise fields per sensor (white, random walk).
_KALIBR_FIELDS = {"gyro": ("gyroscope_noise_density", "gyroscope_random_walk"),
                  "accel": ("accelerometer_noise_density", "accelerometer_random_walk")}


def paste_rows(sensor: str, bound: Mapping, kalibr: Mapping | None = None) -> list[tuple]:
    """The values a user pastes into a filter, each in the spec sheet's unit and in SI.

    Rows ``(file, parameter, value_spec, unit_spec, value_si, unit_si)``: from the contract (`bound`: ``model`` in
    SI, ``model_spec_units``) the exported filter model's white noise N (u/sqrt(Hz)), each GM's sigma (u) and T (s),
    random walk K (u/sqrt(s)), narrowband lines' sigma (u) and the initial standard deviation of the bias state p
    (u: the square root of its P0, ``bias_initialisation.p0_random_walk``, the variance the verification ran the
    filter with; a filter that starts p at less under-states its error); from the Kalibr file (`kalibr`, its fields
    as read) the sensor's noise density (u/sqrt(Hz)) and random walk (u/s/sqrt(Hz), which is u/sqrt(s)), converted
    to the spec sheet's N and K units. u = rad/s (gyro) or m/s^2 (accel). A term the model lacks (0) has no row; a
    spec-sheet unit the contract does not state gives the SI value in both columns."""
    rows = []
    m, mu = bound.get("model"), bound.get("model_spec_units")
    if isinstance(m, Mapping):
        mu = mu if isinstance(mu, Mapping) else {}

        def row(name, key, v_si, shown=None):
            if shown and isinstance(shown, Mapping) and shown.get("value") is not None and shown.get("unit"):
                vs, us = float(shown["value"]), str(shown["unit"])
            else:
                vs, us = in_spec_units({**bound, "sensor": sensor}, key, v_si)
            rows.append(("KF", name, vs, us, float(v_si), SI_SPELLING.get((sensor, key), "SI")))

        if m.get("white"):
            row("white noise N", "white", m["white"], mu.get("white"))
        gms = m.get("gauss_markov") or []
        gmu = mu.get("gauss_markov") or []
        for i, term in enumerate(gms):
            if not isinstance(term, Mapping) or not term.get("sigma"):
                continue
            tag = f" {i + 1}" if len(gms) > 1 else ""
            su = gmu[i] if i < len(gmu) and isinstance(gmu[i], Mapping) else {}
            row(f"GM sigma{tag}", "gm_sigma", term["sigma"], su.get("sigma"))
            rows.append(("KF", f"GM T{tag}", float(term.get("T")), "s", float(term.get("T")), "s"))
        if m.get("random_walk"):
            row("random walk K", "random_walk", m["random_walk"], mu.get("random_walk"))
        for t in m.get("narrowband") or []:
            if isinstance(t, Mapping) and t.get("sigma"):
                row(f"line at {num(t.get('f0_hz'))} Hz, sigma", "gm_sigma", t["sigma"])
        bi = bound.get("bias_initialisation")
        p0 = bi.get("p0_random_walk") if isinstance(bi, Mapping) else None
        if p0 is not None and float(p0) > 0:
            row("initial sd of the random-walk bias state p (sqrt P0)", "gm_sigma", math.sqrt(float(p0)))
    if isinstance(kalibr, Mapping) and not kalibr.get("refused") and sensor in _KALIBR_FIELDS:
        for field, key in zip(_KALIBR_FIELDS[sensor], ("white", "random_walk")):
            v = kalibr.get(field)
            if v is None:
                continue
            vs, us = in_spec_units({**bound, "sensor": sensor}, key, float(v))
            rows.append(("Kalibr", field, vs, us, float(v), KALIBR_SI[(sensor, key)]))
    return rows
