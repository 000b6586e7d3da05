r"""Kalibr ``imu.yaml`` from a bounding noise model (gyroscope and accelerometer of one IMU).

Kalibr's IMU model has, per axis, a continuous-time white measurement noise :math:`n(t)` with
:math:`E[n(t_1) n(t_2)] = \sigma^2 \delta(t_1 - t_2)` and a bias random walk :math:`\dot b = \sigma_b w(t)`
(``w`` unit white noise). The autocorrelation :math:`\sigma^2 \delta(\cdot)` is a **two-sided** PSD
:math:`\sigma^2`, which is imupipe's white noise :math:`S_2 = N^2`; the random walk's two-sided PSD is
:math:`\sigma_b^2/(2\pi f)^2`, imupipe's :math:`K^2/(2\pi f)^2`. Hence, in SI:

==============================  ==============  ====================================
Kalibr field                    imupipe         unit
==============================  ==============  ====================================
``gyroscope_noise_density``     N (gyro)        rad/s/sqrt(Hz)
``gyroscope_random_walk``       K_eff (gyro)    rad/s^2/sqrt(Hz)  (= (rad/s)/sqrt(s))
``accelerometer_noise_density`` N (accel)       m/s^2/sqrt(Hz)
``accelerometer_random_walk``   K_eff (accel)   m/s^3/sqrt(Hz)    (= (m/s^2)/sqrt(s))
``update_rate``                 IMU sample rate Hz
==============================  ==============  ====================================

Kalibr discretises with the IMU's own sample interval :math:`\Delta t = 1/\text{update\_rate}`:
:math:`\sigma_d = \sigma/\sqrt{\Delta t}` (white) and :math:`\sigma_{b,d} = \sigma_b\sqrt{\Delta t}` (random
walk), the same rules as docs/method.md, section "Slip: discrete driving noise". ``update_rate`` must therefore be the
rate of the recorded IMU messages, not the filter rate.

Kalibr has no Gauss-Markov state. Each GM term (sigma, T) is folded into the random walk so that the PSD
still bounds: :math:`2\sigma^2 T/(1 + (2\pi f T)^2) \le (2\sigma^2/T)/(2\pi f)^2` for every f > 0, so
:math:`K_{eff} = \sqrt{K^2 + \sum_i 2\sigma_i^2/T_i}` dominates GM + random walk at every frequency. A
narrowband (second-order GM) term of variance :math:`\sigma^2` cannot be folded into these two terms and
is refused.

The values written are **bounding** values: they already contain the inflation the bound found necessary.
Do not inflate them again (Kalibr's documentation suggests inflating identified values, e.g. x10; these
are not identified values). The file's comment block states this and the factor against the identified
values; a factor below 1 is no inflation and is said to be below, with the identified value's largest term (an
identified short GM folded into the random walk gives a large identified value that is no random walk).

References
----------
.. [1] Kalibr wiki, "IMU Noise Model" (ethz-asl/kalibr), continuous-time noise densities and their
       discretisation.
.. [2] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS
       Integration", ION GNSS+ 2021.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from imupipe.models import NoiseModel

__all__ = ["KALIBR_UNITS", "KalibrIMU", "dataset_rates", "imu_rate", "kalibr_imu", "kalibr_text", "model_of_bound",
           "model_of_kf", "read_kalibr", "rostopic_of", "with_bias_drift", "write_kalibr"]

#: Unit of every Kalibr field (SI, continuous time).
KALIBR_UNITS = {
    "accelerometer_noise_density": "m/s^2/sqrt(Hz)",
    "accelerometer_random_walk": "m/s^3/sqrt(Hz)",
    "gyroscope_noise_density": "rad/s/sqrt(Hz)",
    "gyroscope_random_walk": "rad/s^2/sqrt(Hz)",
    "update_rate": "Hz",
}
_FIELDS = tuple(KALIBR_UNITS)


@dataclass(frozen=True)
class KalibrIMU:
    """The five Kalibr fields plus the topic (SI, continuous time) and the inflation against identification.

    Attributes
    ----------
    accelerometer_noise_density : float
        m/s^2/sqrt(Hz).
    accelerometer_random_walk : float
        m/s^3/sqrt(Hz) (GM terms folded in).
    gyroscope_noise_density : float
        rad/s/sqrt(Hz).
    gyroscope_random_walk : float
        rad/s^2/sqrt(Hz) (GM terms folded in).
    update_rate : float
        IMU sample rate, Hz.
    rostopic : str
        Topic of the ``sensor_msgs/Imu`` messages.
    inflation : dict
        Field -> written value / the same quantity of the identified model (None where unknown or zero).
    below : dict
        Field -> why its ratio is below 1, where it is (then no inflation): the identified quantity's largest
        term (:func:`_below_reason`).
    """

    accelerometer_noise_density: float
    accelerometer_random_walk: float
    gyroscope_noise_density: float
    gyroscope_random_walk: float
    update_rate: float
    rostopic: str
    inflation: dict
    below: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The Kalibr fields in Kalibr's order of its example file (no inflation, no comments)."""
        return {k: float(getattr(self, k)) for k in _FIELDS} | {"rostopic": self.rostopic}


def _model(m, name: str) -> NoiseModel:
    if isinstance(m, NoiseModel):
        return m
    if isinstance(m, Mapping):
        return NoiseModel.from_dict(m)
    raise TypeError(f"{name}: expected a NoiseModel or its to_dict(), got {type(m).__name__}")


def _drift_variance(m: NoiseModel) -> float:
    r""":math:`K_{eff}^2 = K^2 + \sum_i 2\sigma_i^2/T_i` (u^2/s): m's random walk with its GM terms folded in."""
    return m.random_walk**2 + sum(2.0 * s**2 / T for s, T in m.gauss_markov if T > 0)


def _k_eff(m: NoiseModel, name: str) -> float:
    """Random walk that bounds m's random walk plus its GM terms in PSD (u/sqrt(s))."""
    lines = [t for t in getattr(m, "narrowband", ()) or () if t[0] > 0]  # a sigma-0 term is no line (no KF state)
    if lines:
        raise ValueError(f"{name}: the model has {len(lines)} narrowband line(s); Kalibr's two-term model cannot "
                         "bound them (use the full Kalman-filter export instead)")
    return math.sqrt(_drift_variance(m))


def _below_reason(im: NoiseModel, kind: str) -> str:
    r"""Why a written value is below the identified model's (ratio < 1: no inflation), from the identified quantity's
    largest term. For the random walk, :math:`K_{eff}^2 = K^2 + \sum_i 2\sigma_i^2/T_i`: a GM term dominating it is a
    folded GM (its PSD asymptote :math:`2\sigma^2/T/(2\pi f)^2` exceeds the GM's own PSD at every f, by a factor
    :math:`1 + 1/(2\pi f T)^2`, large below :math:`1/(2\pi T)`), not a random walk of the data."""
    if kind == "noise_density":
        return "the identified white noise N is above the written one"
    terms = [(im.random_walk**2, None)] + [(2.0 * s**2 / T, (s, T)) for s, T in im.gauss_markov if T > 0]
    total = sum(v for v, _ in terms)
    v, gm = max(terms, key=lambda x: x[0])
    share = v / total if total > 0 else 0.0
    if gm is None:
        return f"the identified random walk K ({share:.0%} of the identified value, squared) exceeds the written value"
    return (f"{share:.0%} of the identified value (squared) is its GM with T = {gm[1]:.3g} s folded in, which "
            f"overstates that GM below 1/(2 pi T) = {1.0 / (2.0 * math.pi * gm[1]):.3g} Hz; it is no random walk the data "
            "show")


def dataset_rates(sheet_rates: Mapping[str, float | None], curve_rates: Mapping[str, float]) -> dict:
    """Dataset -> sample rate (Hz) for :func:`imu_rate`: the dataset sheet's ``rate_hz`` where the sheet gives
    one, else the rate the record's timestamps gave, as the identify file states it per curve.

    Parameters
    ----------
    sheet_rates : mapping of str to float or None
        Dataset name -> the sheet's ``rate_hz`` (Hz), None where the cell is empty.
    curve_rates : mapping of str to float
        Curve label ``"<dataset>/<axis>"`` -> rate of its record (Hz): the ``rate_hz`` map of an identify file.

    Raises
    ------
    ValueError
        A dataset without a sheet rate and without a curve (named).
    """
    out = {}
    for name, rate in sheet_rates.items():
        if rate is None:
            found = [float(v) for k, v in curve_rates.items() if str(k).rsplit("/", 1)[0] == name]
            if not found:
                raise ValueError(f"update_rate: dataset {name!r} has no rate_hz in the sheet and no curve in the "
                                 f"identify file (curves: {', '.join(map(str, curve_rates)) or 'none'})")
            rate = found[0]  # the curves of one record share its rate
        out[name] = rate
    return out


def imu_rate(rates: Mapping[str, float] | float, rtol: float = 1e-9) -> float:
    """The one IMU sample rate of a run's datasets, Hz.

    Parameters
    ----------
    rates : mapping of str to float, or float
        Dataset name -> sample rate (Hz) from the dataset sheet, or one rate.
    rtol : float, optional
        Relative tolerance for "the same rate" (default 1e-9).

    Raises
    ------
    ValueError
        When the datasets differ in rate (Kalibr's ``update_rate`` is one number: write one file per rate)
        or a rate is not a positive number.
    """
    if not isinstance(rates, Mapping):
        rates = {"rate": rates}
    if not rates:
        raise ValueError("update_rate: no dataset rate given")
    vals = {}
    for k, v in rates.items():
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"update_rate: dataset {k!r} has rate_hz {v!r}, expected a positive number (Hz)") from None
        if not (v > 0 and math.isfinite(v)):
            raise ValueError(f"update_rate: dataset {k!r} has rate_hz {v!r}, expected a positive number (Hz)")
        vals[k] = v
    first = next(iter(vals.values()))
    if any(abs(v - first) > rtol * first for v in vals.values()):
        listing = ", ".join(f"{k}: {v:g} Hz" for k, v in vals.items())
        raise ValueError(f"update_rate: the datasets differ in sample rate ({listing}); Kalibr's update_rate is "
                         "the IMU's one sample rate: export one Kalibr file per rate")
    return first


def rostopic_of(topics: Mapping[str, str | None], default: str = "/imu0") -> str:
    """The one ``sensor_msgs/Imu`` topic of a run's datasets (the dataset sheet's ``topic`` column).

    Parameters
    ----------
    topics : mapping of str to str or None
        Dataset name -> topic cell (None or empty for files that are not bags).
    default : str, optional
        Returned when no dataset names a topic (default ``"/imu0"``, Kalibr's example).

    Raises
    ------
    ValueError
        When the datasets name different topics (one Kalibr file describes one IMU topic).
    """
    named = {k: str(v).strip() for k, v in topics.items() if v is not None and str(v).strip()
             and str(v).strip().lower() != "nan"}
    if not named:
        return default
    distinct = sorted(set(named.values()))
    if len(distinct) > 1:
        listing = ", ".join(f"{k}: {v}" for k, v in named.items())
        raise ValueError(f"rostopic: the datasets name different topics ({listing}); a Kalibr imu.yaml names one")
    return distinct[0]


def kalibr_imu(gyro, accel, *, update_rate_hz: float, rostopic: str = "/imu0", identified_gyro=None,
               identified_accel=None) -> KalibrIMU:
    r"""Kalibr fields of a bounding gyro and accel model.

    Parameters
    ----------
    gyro, accel : imupipe.models.NoiseModel or dict
        Bounding models, SI (rad/s, m/s^2): white N u/sqrt(Hz), GM sigma u and T s, random walk K u/sqrt(s).
    update_rate_hz : float
        IMU sample rate, Hz (the recorded messages' rate; see :func:`imu_rate`).
    rostopic : str, optional
        Topic of the IMU messages (the dataset sheet's ``topic``), default ``"/imu0"``.
    identified_gyro, identified_accel : NoiseModel or dict, optional
        Models identified from the Allan variance; give the inflation factors of the comment block.

    Returns
    -------
    KalibrIMU
        ``*_noise_density`` = N, ``*_random_walk`` = :math:`\sqrt{K^2 + \sum 2\sigma_i^2/T_i}`.
    """
    rate = imu_rate(update_rate_hz)
    if not isinstance(rostopic, str) or not rostopic.strip():
        raise ValueError(f"rostopic: expected a topic name such as '/imu0', got {rostopic!r}")
    g, a = _model(gyro, "gyro"), _model(accel, "accel")
    vals = {
        "gyroscope_noise_density": float(g.white),
        "gyroscope_random_walk": _k_eff(g, "gyro"),
        "accelerometer_noise_density": float(a.white),
        "accelerometer_random_walk": _k_eff(a, "accel"),
    }
    for k, v in vals.items():
        if not v > 0:
            raise ValueError(f"{k}: the bound gives {v!r}; Kalibr needs a positive value")
    inflation, below = {}, {}
    for prefix, ident in (("gyroscope", identified_gyro), ("accelerometer", identified_accel)):
        im = _model(ident, prefix) if ident is not None else None
        for kind, ref in (("noise_density", im.white if im else None),
                          ("random_walk", math.sqrt(_drift_variance(im)) if im else None)):
            key = f"{prefix}_{kind}"
            inflation[key] = (vals[key] / ref) if ref else None
            if inflation[key] is not None and inflation[key] < 1.0:
                below[key] = _below_reason(im, kind)
    return KalibrIMU(update_rate=rate, rostopic=rostopic.strip(), inflation=inflation, below=below, **vals)


def kalibr_text(imu: KalibrIMU, *, source: str = "", notes=()) -> str:
    """The ``imu.yaml`` text: a comment block (bounding values, units, the ratio to the identified values: an
    inflation when above 1, else said to be below with :attr:`KalibrIMU.below`'s reason) and the six fields.

    Parameters
    ----------
    imu : KalibrIMU
    source : str, optional
        One line naming where the values come from (spec sheet, run), written in the comment block.
    notes : sequence of str, optional
        Further comment lines (e.g. the exported filter model's reduction and the horizon it holds for).
    """
    lines = [
        "# Kalibr IMU noise model (imu.yaml) written by imupipe.",
        "# BOUNDING VALUES: these densities already bound the recorded noise and the spec sheet (PSD overbound,",
        "# Gallon, Joerger & Pervan, ION GNSS+ 2021). Use them as they are: no further inflation is needed",
        "# (do not apply the customary x10 for identified values).",
        "# Continuous time, SI, as Kalibr defines them; Kalibr discretises with dt = 1/update_rate.",
        "# Gauss-Markov terms are folded into the random walk: K_eff = sqrt(K^2 + sum 2 sigma^2/T) (bounds in PSD).",
    ]
    if source:
        lines.append(f"# Source: {source}")
    lines += [f"# {n}" for n in notes]
    known = {k: v for k, v in imu.inflation.items() if v is not None}
    if known:
        lines.append("# Against the values identified from the Allan variance (written / identified; above 1 an "
                     "inflation):")
        for k, v in known.items():
            if v < 1.0:
                why = imu.below.get(k) or "see the identify file"
                lines.append(f"#   {k}: x{v:.3g}, BELOW the identified value, not an inflation: {why}")
            else:
                lines.append(f"#   {k}: x{v:.3g}")
    body = [
        f"accelerometer_noise_density: {imu.accelerometer_noise_density:.6e}  # m/s^2/sqrt(Hz)",
        f"accelerometer_random_walk: {imu.accelerometer_random_walk:.6e}  # m/s^3/sqrt(Hz)",
        f"gyroscope_noise_density: {imu.gyroscope_noise_density:.6e}  # rad/s/sqrt(Hz)",
        f"gyroscope_random_walk: {imu.gyroscope_random_walk:.6e}  # rad/s^2/sqrt(Hz)",
        f"update_rate: {imu.update_rate:.10g}  # Hz, IMU sample rate",
        f"rostopic: {imu.rostopic}",
    ]
    return "\n".join(lines + body) + "\n"


def write_kalibr(imu: KalibrIMU, path, *, source: str = "", notes=()) -> None:
    """Write :func:`kalibr_text` to `path` atomically."""
    from imupipe.io import write_text_atomic

    write_text_atomic(kalibr_text(imu, source=source, notes=notes), path)


def read_kalibr(path) -> dict:
    """Read an ``imu.yaml`` back: Kalibr's six fields, checked present and numeric (SI, Hz).

    Raises
    ------
    ValueError
        Naming the file and the missing or non-numeric field.
    """
    import yaml

    with open(path) as fh:
        data = yaml.safe_load(fh)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a YAML mapping of Kalibr's IMU fields")
    out = {}
    for k in _FIELDS:
        if k not in data:
            raise ValueError(f"{path}: Kalibr field {k!r} ({KALIBR_UNITS[k]}) is missing")
        try:
            out[k] = float(data[k])
        except (TypeError, ValueError):
            raise ValueError(f"{path}: {k} = {data[k]!r}, expected a number in {KALIBR_UNITS[k]}") from None
    out["rostopic"] = str(data.get("rostopic", ""))
    return out


def model_of_bound(bound_yaml: Mapping) -> NoiseModel:
    """The bound model of a per-sensor bound contract (``results/.../bound/{sensor}.yaml``), SI
    (:meth:`NoiseModel.from_dict` of its ``bound`` section: narrowband lines included)."""
    try:
        b = bound_yaml["bound"]
    except (KeyError, TypeError):
        raise ValueError("bound YAML: no 'bound' section (expected the per-sensor bound contract)") from None
    return NoiseModel.from_dict(b)


def with_bias_drift(exported: NoiseModel, bound: NoiseModel, sensor: str) -> tuple[NoiseModel, str | None]:
    r"""The exported model, or, when it has no bias-drift term, the same with the bound's drift terms.

    Kalibr's model has two terms, white noise and a bias random walk, and needs both positive. Its random walk
    is :math:`K_{eff} = \sqrt{K^2 + \sum_i 2\sigma_i^2/T_i}` (:func:`kalibr_imu`). When the verified reduction
    dropped every GM and random-walk state (a white-noise-only export for the configured horizon), the exported
    :math:`K_{eff}` is 0; the random walk and GM terms are then those of the bound before the reduction (white
    noise stays the exported one). More process noise than the verified export: a conservative drift for
    Kalibr, which propagates over whole calibration sequences, not one horizon.

    Returns
    -------
    (NoiseModel, str or None)
        The model to write and a sentence saying what was taken from the bound (None when nothing was).
    """
    from dataclasses import replace

    if _drift_variance(exported) > 0 or not _drift_variance(bound) > 0:
        return exported, None
    note = (f"{sensor}: the exported KF model has no bias drift (the verified reduction dropped every GM and "
            "random-walk state for the configured horizon); Kalibr needs a positive random walk: taken from the "
            "bound before the reduction (random walk and GM terms folded in), more than the export carries")
    return replace(exported, random_walk=bound.random_walk, gauss_markov=bound.gauss_markov), note


def model_of_kf(kf_yaml: Mapping, path: str = "KF file") -> NoiseModel:
    """The exported filter model of a KF file (``results/.../kf/{spec}/{sensor}.yaml``), SI: its ``parameters``
    (white u/sqrt(Hz), GM sigma u and T s, random_walk u/sqrt(s), narrowband sigma u, f0_hz Hz, zeta) as a
    :class:`NoiseModel`. This is the bound's model after the verified reduction, the model Kalibr's file must follow.

    Raises
    ------
    ValueError
        Naming `path` when the file has no ``parameters`` mapping.
    """
    params = kf_yaml.get("parameters") if isinstance(kf_yaml, Mapping) else None
    if not isinstance(params, Mapping):
        raise ValueError(f"{path}: no 'parameters' section (expected the KF export of imupipe's kf rule)")
    return NoiseModel.from_dict({k: v for k, v in params.items() if k != "units"})
