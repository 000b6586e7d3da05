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
``gyroscope_random_walk``       K (gyro)        rad/s^2/sqrt(Hz)  (= (rad/s)/sqrt(s))
``accelerometer_noise_density`` N (accel)       m/s^2/sqrt(Hz)
``accelerometer_random_walk``   K (accel)       m/s^3/sqrt(Hz)    (= (m/s^2)/sqrt(s))
``update_rate``                 IMU sample rate Hz
==============================  ==============  ====================================

Kalibr discretises with the IMU's own sample interval :math:`\Delta t = 1/\text{update\_rate}`:
:math:`\sigma_d = \sigma/\sqrt{\Delta t}` (white) and :math:`\sigma_{b,d} = \sigma_b\sqrt{\Delta t}` (random
walk), the same rules as docs/method.md, section "Slip: discrete driving noise". ``update_rate`` must therefore be the
rate of the recorded IMU messages, not the filter rate.

Kalibr has no Gauss-Markov state, no flicker and no line. Its two densities are chosen in Kalibr's own family
(:func:`kalibr_pair`): the pair (N, K) whose two-sided PSD :math:`N^2 + K^2/(2\pi f)^2` bounds the exported model's
continuous two-sided PSD :math:`S(f)` at every frequency of :math:`[1/\text{horizon}, f_u/2]`, with
:math:`f_u` = ``update_rate`` (Kalibr's filter runs at the IMU's rate, so its white noise must cover the model up to
that Nyquist frequency; over the 1 Hz reference filter's 0.5 Hz alone the LP may trade white noise for random
walk and leave the density below the model's white noise above the band) and that minimises the
log-frequency mean over the band of :math:`(N^2 + K^2/(2\pi f)^2)/S(f)`, the pair's mean power inflation over the
model (dimensionless). A 2-variable LP in :math:`(N^2, K^2)` (``scipy.optimize.linprog``, HiGHS), its rows the
ratio to S on a log-uniform grid plus the model's corner frequencies, refined by cutting planes at the local minima
of the ratio between grid points. With per-axis models, each axis's exported model gets its pair and Kalibr's one
value per sensor is the largest of each (the comment names the axis that set it); (max N, max K) bounds every axis.
A narrowband (second-order GM) term cannot be carried by these two terms and is refused.

The values written are **bounding** values: they already contain the inflation the bound found necessary.
Do not inflate them again (Kalibr's documentation suggests inflating identified values, e.g. x10; these
are not identified values). The file's comment block states this and the factor against the identified
values (the identified model's pair by the same rule and band); a factor below 1 is no inflation and is said to be
below, with the identified model's terms that act as that term in band.

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
from dataclasses import dataclass, field, replace

import numpy as np

from imupipe.inband import PER_DECADE, band_grid, corner_frequencies
from imupipe.models import NoiseModel

__all__ = ["KALIBR_UNITS", "KalibrIMU", "KalibrPair", "LP_FEASIBILITY_TOL", "RATE_RTOL", "dataset_rates", "imu_rate",
           "kalibr_imu",
           "kalibr_pair", "kalibr_text", "model_of_bound", "model_of_kf", "read_kalibr", "rostopic_of",
           "with_bias_drift", "write_kalibr"]

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
        m/s^3/sqrt(Hz).
    gyroscope_noise_density : float
        rad/s/sqrt(Hz).
    gyroscope_random_walk : float
        rad/s^2/sqrt(Hz).
    update_rate : float
        IMU sample rate, Hz.
    rostopic : str
        Topic of the ``sensor_msgs/Imu`` messages.
    inflation : dict
        Field -> written value / the same quantity of the identified model (None where unknown or zero).
    below : dict
        Field -> why its ratio is below 1, where it is (then no inflation) (:func:`_below_reason`).
    set_by : dict
        Field -> the label (axis, or "global") whose pair gave the value (the largest over the set).
    band_hz : tuple
        The band the pairs bound the models over, Hz.
    pairs : dict
        "gyroscope"/"accelerometer" -> label -> (N, K) of each model's own pair.
    """

    accelerometer_noise_density: float
    accelerometer_random_walk: float
    gyroscope_noise_density: float
    gyroscope_random_walk: float
    update_rate: float
    rostopic: str
    inflation: dict
    below: dict = field(default_factory=dict)
    set_by: dict = field(default_factory=dict)
    band_hz: tuple = ()
    pairs: dict = field(default_factory=dict)

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


#: HiGHS primal and dual feasibility tolerance of the pair LP. Its rows are ratios to the model's PSD (right-hand side
#: 1), so a row met to this tolerance is met to this relative tolerance in PSD; :func:`kalibr_pair` then scales the
#: pair by at most 1 + this so that every evaluated row holds exactly.
LP_FEASIBILITY_TOL = 1e-9


@dataclass(frozen=True)
class KalibrPair:
    """Kalibr's two densities of one model (:func:`kalibr_pair`), SI.

    Attributes
    ----------
    noise_density : float
        N, u/sqrt(Hz) (two-sided PSD N^2, Kalibr's ``*_noise_density``).
    random_walk : float
        K, u/sqrt(s) (two-sided PSD K^2/(2 pi f)^2, Kalibr's ``*_random_walk``).
    band_hz : tuple
        [lo, hi] Hz the pair bounds the model over.
    active_hz : tuple
        Frequencies (Hz) where the pair touches the model's PSD (ratio within 1e-6 of 1).
    min_ratio : float
        Smallest (N^2 + K^2/(2 pi f)^2) / S(f) over every frequency evaluated (>= 1).
    n_rows : int
        Rows of the final LP (grid, corners and cutting planes).
    """

    noise_density: float
    random_walk: float
    band_hz: tuple
    active_hz: tuple
    min_ratio: float
    n_rows: int


def _check_lines(m: NoiseModel, name: str) -> None:
    lines = [t for t in getattr(m, "narrowband", ()) or () if t[0] > 0]  # a sigma-0 term is no line (no KF state)
    if lines:
        raise ValueError(f"{name}: the model has {len(lines)} narrowband line(s); Kalibr's two-term model cannot "
                         "bound them (use the full Kalman-filter export instead)")


def kalibr_pair(model, band_hz, *, per_decade: int = PER_DECADE, tol: float = LP_FEASIBILITY_TOL,
                name: str = "model", max_rounds: int = 30) -> KalibrPair:
    r"""The smallest Kalibr pair (N, K) whose PSD bounds `model`'s over `band_hz`.

    Minimise :math:`\overline{(x_1 + x_2/(2\pi f)^2)/S(f)}` (mean over a log-uniform grid of the band: the pair's
    mean power inflation over the model in log-frequency, dimensionless) subject to
    :math:`x_1 + x_2/(2\pi f_i)^2 \ge S(f_i)` at every row frequency :math:`f_i` and :math:`x \ge 0`, with
    :math:`x_1 = N^2` (u^2/Hz), :math:`x_2 = K^2` (u^2/s) and S the model's continuous two-sided PSD
    (:meth:`NoiseModel.psd`; the ramp has no PSD and is left out). Each row is divided by :math:`S(f_i)` and each
    column by its largest entry, so HiGHS's feasibility tolerance `tol` is a relative tolerance in PSD.

    Rows: a log-uniform grid of ``per_decade`` points a decade with the band's ends and the model's corner
    frequencies (:func:`imupipe.inband.corner_frequencies`); then, repeatedly, the ratio's local minima between grid
    points (bounded scalar minimisation in ln f) that fall below 1 - tol are added as rows and the LP solved again.
    Finally the pair is scaled (by at most 1 + tol in power) so that every row holds exactly; between rows every
    local minimum of the ratio is then at least 1 - tol (the cutting planes' stopping rule), so on any grid the pair's
    PSD is at least (1 - tol) times the model's. Any
    positive weight gives a Pareto-minimal pair: neither value can shrink alone.

    Parameters
    ----------
    model : NoiseModel or its to_dict()
        SI; its narrowband lines (sigma > 0) are refused.
    band_hz : (float, float)
        [lo, hi] Hz, 0 < lo < hi.

    Raises
    ------
    ValueError
        A line in the model, an empty band, or an LP HiGHS does not solve.
    """
    from scipy.optimize import linprog, minimize_scalar

    m = _model(model, name)
    _check_lines(m, name)
    m = replace(m, ramp=0.0, narrowband=())
    lo, hi = float(band_hz[0]), float(band_hz[1])
    if not 0 < lo < hi:
        raise ValueError(f"{name}: band_hz = {band_hz!r}, expected 0 < lo < hi (Hz)")
    f_obj = band_grid((lo, hi), per_decade)
    rows = band_grid((lo, hi), per_decade, extra=corner_frequencies(m))

    def psd(f):
        return np.asarray(m.psd(np.asarray(f, dtype=np.float64)), dtype=np.float64)

    if not np.any(psd(rows) > 0):
        return KalibrPair(0.0, 0.0, (lo, hi), (), float("inf"), int(rows.size))
    # a frequency where the model has no power needs no cover and has no ratio (the quantization PSD, band-limited,
    # is 0 from the model's Nyquist frequency on, and its 1/S made the LP's input infinite); its largest value, just
    # below that frequency, is a row (imupipe.inband.corner_frequencies)
    rows = rows[psd(rows) > 0]
    f_obj = f_obj[psd(f_obj) > 0]
    w_obj = (2.0 * np.pi * f_obj) ** 2
    s_obj = psd(f_obj)
    c_raw = np.array([np.mean(1.0 / s_obj), np.mean(1.0 / (w_obj * s_obj))])

    def ratio(x, f):
        f = np.asarray(f, dtype=np.float64)
        return (x[0] + x[1] / (2.0 * np.pi * f) ** 2) / psd(f)

    x = None
    for _ in range(max_rounds):
        S = psd(rows)
        A = np.column_stack([1.0 / S, 1.0 / ((2.0 * np.pi * rows) ** 2 * S)])
        d = 1.0 / A.max(axis=0)  # column scales: every entry in (0, 1]
        res = linprog(c_raw * d, A_ub=-(A * d), b_ub=-np.ones(rows.size), bounds=[(0, None), (0, None)],
                      method="highs", options={"primal_feasibility_tolerance": tol,
                                               "dual_feasibility_tolerance": tol})
        if res.status != 0:
            raise ValueError(f"{name}: the Kalibr pair LP failed ({res.message})")
        x = np.maximum(res.x, 0.0) * d
        g = ratio(x, rows)
        lf = np.log(rows)
        new = []
        for i in range(rows.size):  # local minima of the ratio on the rows, refined between the neighbours
            left, right = g[i - 1] if i else np.inf, g[i + 1] if i + 1 < rows.size else np.inf
            if g[i] <= left and g[i] <= right:
                a_, b_ = lf[max(i - 1, 0)], lf[min(i + 1, rows.size - 1)]
                r = minimize_scalar(lambda t: float(ratio(x, [math.exp(t)])[0]), bounds=(a_, b_), method="bounded",
                                    options={"xatol": 1e-10})
                if r.fun < 1.0 - tol:
                    new.append(math.exp(float(r.x)))
        if not new:
            break
        rows = np.unique(np.concatenate([rows, new]))
    g = ratio(x, rows)
    scale = max(1.0, 1.0 / float(np.min(g)))  # LP met to tol: scale <= 1 + tol
    x = x * scale
    g = g * scale
    tight = g <= 1.0 + 1e-6
    active, i = [], 0
    while i < rows.size:  # one frequency per run of touching rows: the run's smallest ratio
        if tight[i]:
            j = i
            while j + 1 < rows.size and tight[j + 1]:
                j += 1
            active.append(float(rows[i + int(np.argmin(g[i:j + 1]))]))
            i = j + 1
        else:
            i += 1
    active = tuple(active)
    return KalibrPair(noise_density=math.sqrt(x[0]), random_walk=math.sqrt(x[1]), band_hz=(lo, hi),
                      active_hz=active, min_ratio=float(np.min(g)), n_rows=int(rows.size))


def _as_set(m, name: str) -> dict:
    """Label -> NoiseModel: a single model (label "global") or a mapping of labels (axes) to models."""
    if isinstance(m, NoiseModel):
        return {"global": m}
    if isinstance(m, Mapping) and m and all(isinstance(v, (NoiseModel, Mapping)) for v in m.values()) \
            and "white" not in m:
        return {str(k): _model(v, f"{name} {k}") for k, v in m.items()}
    return {"global": _model(m, name)}


def _largest(pairs: Mapping[str, KalibrPair]) -> tuple[float, str, float, str]:
    """(largest N, its label, largest K, its label) over the pairs."""
    n_lab = max(pairs, key=lambda k: pairs[k].noise_density)
    k_lab = max(pairs, key=lambda k: pairs[k].random_walk)
    return pairs[n_lab].noise_density, n_lab, pairs[k_lab].random_walk, k_lab


def _below_reason(im: NoiseModel, kind: str, band_hz) -> str:
    """Why a written value is below the identified model's pair (ratio < 1: no inflation): the bound and its
    verified reduction trade white noise against the drift terms, so one of the two may come out below; named with
    the identified model's components that act as that term in band (:func:`imupipe.inband.acts_as`)."""
    from imupipe.inband import acts_as

    want = "white noise" if kind == "noise_density" else "random walk"
    comps = [c for c in acts_as(im, band_hz) if c["acts_as"] == want]
    named = ", ".join(c["component"] + (f" (T {c['T']:.3g} s)" if "T" in c else "") for c in comps) or "none"
    return (f"the identified model's own pair on the band needs a larger {kind.replace('_', ' ')} (its terms acting "
            f"as {want} in band: {named}); the exported model's PSD is bounded as a whole, the other term carries it")


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


#: Relative tolerance of "the same sample rate" (:func:`imupipe.kalibr.imu_rate`).
RATE_RTOL = 1e-9


def imu_rate(rates: Mapping[str, float] | float, rtol: float = RATE_RTOL,
             named: float | None = None) -> float:
    """The one IMU sample rate of a run's datasets, Hz.

    Parameters
    ----------
    rates : mapping of str to float, or float
        Dataset name -> sample rate (Hz) from the dataset sheet, or one rate.
    rtol : float, optional
        Relative tolerance for "the same rate" (default 1e-9).
    named : float, optional
        The rate the config names (``kalibr.update_rate_hz``, Hz): the update_rate where the datasets differ in rate
        (the densities are continuous-time; the rate sets the band [1/horizon, rate / 2] the pair must bound, which
        the records at that rate cover). It must be one of the datasets' rates: above every record's, no record
        shows the noise up to its Nyquist frequency.

    Raises
    ------
    ValueError
        When the datasets differ in rate and no rate is named (Kalibr's ``update_rate`` is one number), `named` is
        not one of the datasets' rates, or a rate is not a positive number.
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
    listing = ", ".join(f"{k}: {v:g} Hz" for k, v in vals.items())
    if named is not None:
        if not any(abs(v - float(named)) <= rtol * v for v in vals.values()):
            raise ValueError(f"kalibr.update_rate_hz {float(named):g}: not the rate of any dataset ({listing}); "
                             "name the rate of the records taken at the rate Kalibr's IMU runs at")
        return float(named)
    if any(abs(v - first) > rtol * first for v in vals.values()):
        raise ValueError(f"update_rate: the datasets differ in sample rate ({listing}); Kalibr's update_rate is "
                         "the IMU's one sample rate: set kalibr.update_rate_hz to the one Kalibr's IMU runs at")
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


def kalibr_imu(gyro, accel, *, update_rate_hz: float, band_hz, rostopic: str = "/imu0", identified_gyro=None,
               identified_accel=None) -> KalibrIMU:
    r"""Kalibr fields of a bounding gyro and accel model (:func:`kalibr_pair` of each).

    Parameters
    ----------
    gyro, accel : imupipe.models.NoiseModel or dict, or a mapping label -> model
        Bounding (exported) models, SI (rad/s, m/s^2): white N u/sqrt(Hz), GM sigma u and T s, random walk K
        u/sqrt(s). A mapping of axis labels to models gives one pair per axis; Kalibr's value is the largest of
        each (:attr:`KalibrIMU.set_by` names the label).
    update_rate_hz : float
        IMU sample rate, Hz (the recorded messages' rate; see :func:`imu_rate`).
    band_hz : (float, float)
        The band the pair bounds the model over, Hz: [1/horizon_s, update_rate_hz/2] (the workflow's; Kalibr runs
        its filter at the IMU's rate).
    rostopic : str, optional
        Topic of the IMU messages (the dataset sheet's ``topic``), default ``"/imu0"``.
    identified_gyro, identified_accel : NoiseModel or dict, optional
        Models identified from the Allan variance; their pair on the same band gives the comment's ratios.

    Returns
    -------
    KalibrIMU
    """
    rate = imu_rate(update_rate_hz)
    if not isinstance(rostopic, str) or not rostopic.strip():
        raise ValueError(f"rostopic: expected a topic name such as '/imu0', got {rostopic!r}")
    vals, set_by, pairs = {}, {}, {}
    for prefix, m, name in (("gyroscope", gyro, "gyro"), ("accelerometer", accel, "accel")):
        models = _as_set(m, name)
        pairs[prefix] = {k: kalibr_pair(v, band_hz, name=f"{name} {k}" if k != "global" else name)
                         for k, v in models.items()}
        n, n_lab, k, k_lab = _largest(pairs[prefix])
        vals[f"{prefix}_noise_density"], vals[f"{prefix}_random_walk"] = n, k
        set_by[f"{prefix}_noise_density"], set_by[f"{prefix}_random_walk"] = n_lab, k_lab
    for k, v in vals.items():
        if not v > 0:
            raise ValueError(f"{k}: the bound gives {v!r}; Kalibr needs a positive value")
    inflation, below = {}, {}
    for prefix, ident in (("gyroscope", identified_gyro), ("accelerometer", identified_accel)):
        im = _model(ident, prefix) if ident is not None else None
        ref = None
        if im is not None:
            ref = kalibr_pair(replace(im, narrowband=()), band_hz, name=f"identified {prefix}")
        for kind in ("noise_density", "random_walk"):
            key = f"{prefix}_{kind}"
            r = getattr(ref, kind) if ref is not None else None
            inflation[key] = (vals[key] / r) if r else None
            if inflation[key] is not None and inflation[key] < 1.0:
                below[key] = _below_reason(im, kind, band_hz)
    return KalibrIMU(update_rate=rate, rostopic=rostopic.strip(), inflation=inflation, below=below, set_by=set_by,
                     band_hz=tuple(float(b) for b in band_hz),
                     pairs={p: {k: (v.noise_density, v.random_walk) for k, v in d.items()} for p, d in pairs.items()},
                     **vals)


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
    ]
    if imu.band_hz:
        lo, hi = imu.band_hz
        lines += [
            "# Rule: (N, K) is the pair whose two-sided PSD N^2 + K^2/(2 pi f)^2 bounds the exported model's PSD at every",
            f"# frequency of the band [{lo:.4g}, {hi:.4g}] Hz (1/horizon to update_rate / 2: Kalibr's filter runs at the",
            "# IMU's rate, not at the application's filter rate), minimising the band's log-frequency mean of",
            "# (N^2 + K^2/(2 pi f)^2) / S_model(f) (an LP, HiGHS; GM, flicker and quantization terms are carried by N and",
            "# K wherever they lie in band).",
        ]
        for prefix, per in imu.pairs.items():
            if len(per) > 1:  # one value per sensor: the largest of each over the per-axis exported models
                listing = ", ".join(f"{k}: N {v[0]:.4g}, K {v[1]:.4g}" for k, v in per.items())
                which = "; ".join(f"{prefix}_{kind} set by axis {imu.set_by.get(f'{prefix}_{kind}', '-')}"
                                  for kind in ("noise_density", "random_walk"))
                lines.append(f"# {prefix}: the largest of each over the per-axis exported models (SI; {listing}): "
                             f"{which}")
    if source:
        lines.append(f"# Source: {source}")
    lines += [f"# {n}" for n in notes]
    known = {k: v for k, v in imu.inflation.items() if v is not None}
    if known:
        lines.append("# Each value written divided by the one the model identified from the Allan variance gives under the"
                     " same rule and band (above 1: the bound's inflation):")
        for k, v in known.items():
            if v < 1.0:
                why = imu.below.get(k) or "see the identify file"
                lines.append(f"#   {k}: {v:.3g} times the identified value (the written value is the smaller one, "
                             f"still the bounding value to use): {why}")
            else:
                lines.append(f"#   {k}: {v:.3g} times the identified value")
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

    Kalibr's model has two terms, white noise and a bias random walk, and needs both positive (:func:`kalibr_imu`).
    When the verified reduction dropped every GM and random-walk state (a white-noise-only export for the configured
    horizon), the exported model has no drift; the random walk and GM terms are then those of the bound before the reduction (white
    noise stays the exported one). More process noise than the verified export: a conservative drift for
    Kalibr, which propagates over whole calibration sequences, not one horizon.

    Returns
    -------
    (NoiseModel, str or None)
        The model to write and a sentence saying what was taken from the bound (None when nothing was).
    """
    if _drift_variance(exported) > 0 or not _drift_variance(bound) > 0:
        return exported, None
    note = (f"{sensor}: the exported KF model has no bias drift (the verified reduction dropped every GM and "
            "random-walk state for the configured horizon); Kalibr needs a positive random walk: taken from the "
            "bound before the reduction (random walk and GM terms), more than the export carries")
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
