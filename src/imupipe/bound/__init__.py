r"""PSD overbounding of IMU errors by a Kalman-filter-ready noise model (docs/method.md, section "The bound").

Goal (Gallon, Joerger, Pervan, ION GNSS+ 2021, section II.2.e): a model of white noise, first-order
Gauss-Markov (GM) terms and a random walk whose two-sided PSD

.. math::

    S_m(f) = N^2 + \sum_i \frac{2\sigma_i^2 T_i}{1 + (2\pi f T_i)^2} + \frac{K^2}{(2\pi f)^2}

lies above every sample PSD of one sensor type (15 curves: 5 datasets x 3 axes) at every
frequency and above the spec sheet's PSD. For a stationary error, :math:`S_m \ge S_{true}` at all
:math:`f` makes every covariance of the model dominate the true one, so a linear estimator built on
the model reports a variance that bounds its true error variance (Langel, Garcia-Crespillo,
Joerger, PLANS 2020).

For fixed time constants :math:`T_i` the model PSD is linear in
:math:`x = (N^2, \sigma_i^2, K^2) \ge 0`, so the tightest bound is a linear program
(HiGHS through its own Python interface ``highspy``, the solver behind :func:`scipy.optimize.linprog`):

.. math::

    \min_{x \ge 0}\; \sum_k w_k \frac{S_m(f_k; x)}{E(f_k)} \quad \text{s.t.} \quad
    S_m(f_k; x) \ge \hat S_c(f_k)\ \forall c, k, \qquad S_m(f_j; x) \ge S_{spec}(f_j)\ \forall j,

with :math:`E` the envelope of the targets and :math:`w_k` log-frequency weights (each decade
counts equally). Rows are divided by their target (PSDs span 20 decades in SI) and columns by
their largest entry; the constraints are generated lazily (cutting planes: only a few hundred of
the 10^4 rows are ever binding). :math:`T` is profiled on a log grid and refined.

When the sample PSDs are of block-averaged data (the paper's 1 Hz averages), pass `dt`: the model
is then compared through ``NoiseModel.psd_sampled(f, dt)`` (averaging and aliasing included).

Bound over all frequencies (the paper's "for all f"). The sampled bins end at :math:`f_1 = 1/T_{win}`;
below it a record says nothing, yet a random walk (:math:`1/f^2`) or a long-T GM dominates a filter's
error over a long outage there. So the LP also holds, with continuous PSDs,

* :math:`S_m(f) \ge \max(S_{spec}(f), S_{up}(f))` on a log grid (10 per decade) from the floor
  :math:`f_{floor}` up to :math:`f_1`, :math:`S_m \ge S_{up}` on up to the Nyquist frequency of the sampled
  band, and :math:`S_m \ge \max(S_{spec}, S_{up})` above it, up to three decades above the larger of that
  frequency and the highest GM corner :math:`1/(2\pi T)` of both (``upper_band="all"``, the default;
  ``"below"`` only below :math:`f_1`): the exported model is continuous-time and a filter integrates its
  PSD at every frequency, where the decimated bins say nothing. :math:`S_{up}` is the identified model's
  upper confidence envelope (:func:`upper_envelope`: kept components at their upper limits, a GM over its
  whole T interval, an interval the data leave open included (:func:`gm_box_envelope`), the random walk
  at its upper limit even when model selection dropped it);
* :math:`f \to 0`: :math:`K_m \ge \max(K_{spec}, K_{up})` (a random walk the spec gives or the data
  cannot exclude is never dropped: the component is added, ``decisions`` says so);
* :math:`f \to \infty`: :math:`N_m \ge \max(N_{spec}, N_{up})` (only white noise remains there; :math:`N_{up}`
  with ``upper_band="all"``).

The floor is :math:`f_{floor} = 0.01/H` for the span :math:`H` (``span_s``: fix period plus
outage; without it :math:`f_1/100`, and never above :math:`f_1/10`). Why it is enough: over a window of
length :math:`H`, a component at :math:`f \ll 1/H` changes by a fraction :math:`\sim 2\pi f H` of its
amplitude, so a PSD shortfall below :math:`0.01/H` reaches the error variance over the span weighted by
:math:`(2\pi f H)^2 < 4\cdot 10^{-3}` (for white-, GM- and flicker-like shapes; the :math:`1/f^2`
random walk, which is not integrable there, is covered exactly by its asymptote). A spec (or identified)
flicker :math:`B^2/(2\pi f)` is therefore bounded down to the floor by whatever the LP chooses (GM,
random walk); it does not by itself force :math:`K_m > 0`. ``BoundResult.allf_margin`` is the smallest
ratio over these conditions (frequency 0 stands for the :math:`K` asymptote, inf for the :math:`N` one),
and ``bounded`` needs it >= 1.

``exclude=((f_lo_hz, f_hi_hz, reason), ...)`` leaves the sample-curve rows inside those closed intervals
out (never the spec or all-frequency rows); in band modes the bands are split at the intervals' edges first, so
that exactly the bins inside an interval are excluded, in raw and band modes alike. The excluded bins are listed
in ``details["excluded"]``. ``narrowband=((f0_hz, zeta), ...)`` adds fixed-shape damped-oscillator columns whose
variance is an LP variable; the column is :meth:`imupipe.models.NoiseModel.psd_sampled` of a unit-variance
narrowband term (one formula for the LP and the reported model), and the result's model carries the terms
(``model.narrowband``, with their fitted sigma).

Modes (how the sample PSDs enter the constraints):

``raw``
    the periodograms as they are (paper-faithful). The bound then follows the periodogram maxima:
    for white noise the largest of :math:`n` single-window ordinates is about :math:`\ln n + 0.577`
    times the true PSD (12.7x power, 3.6x amplitude for 15 curves x 12600 bins).
``smoothed``
    log-frequency band averages (:func:`imupipe.spectra.smooth_log_bands` bands, optionally
    merged at the low end to at least `min_edf` degrees of freedom); the model is band-averaged
    the same way.
``confidence``
    the upper chi-squared limit of each band average (or ordinate, with ``bands_per_decade=None``)
    at family-wise level `confidence`, Bonferroni-corrected over all curves x bands
    (:func:`imupipe.spectra.chi2_upper`): with that probability every curve's true band-averaged
    PSD lies below the bound.

References
----------
.. [1] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS
       Integration", ION GNSS+ 2021, eqs. 7, 9, 12, 13, Table 2, Appendix A.
.. [2] S. Langel, O. Garcia-Crespillo, M. Joerger, "A New Approach for Modeling Correlated Gaussian
       Errors Using Frequency Domain Overbounding", IEEE/ION PLANS 2020.
.. [3] IEEE Std 952-1997, Annex C (Allan-variance forms of the components).
.. [4] Q. Huangfu, J. A. J. Hall, "Parallelizing the dual revised simplex method", Math. Prog.
       Comp. 10, 119-142, 2018 (HiGHS).

Package layout (issue 18): :mod:`~imupipe.bound.engine` (the LP), :mod:`~imupipe.bound.paper` (the hand
inflation), :mod:`~imupipe.bound.allan_check` (Allan-domain checks, upper envelope), :mod:`~imupipe.bound.report`
(:class:`BoundResult`). Every public name stays importable from ``imupipe.bound``; private names stay
in their home submodule.
"""

from imupipe.bound.report import (  # noqa: F401
    BoundResult,
)
from imupipe.bound.engine import (  # noqa: F401
    BOUND_COMPONENTS,
    DEFAULT_MIN_EDF,
    MODES,
    bound_psd,
    looseness,
    margin,
)
from imupipe.bound.paper import (  # noqa: F401
    paper_inflation,
)
from imupipe.bound.axes import (  # noqa: F401
    axis_of,
    bound_by_axis,
    curves_by_axis,
)
from imupipe.bound.allan_check import (  # noqa: F401
    BOX_SPLIT_RATIO,
    SHORT_T_WHITE_FACTOR,
    check_allan,
    check_allan_components,
    gm_bounds_gm,
    gm_box_envelope,
    random_walk_cap,
    split_gm_box,
    upper_envelope,
    upper_envelope_from_identification,
)

__all__ = [
    "BOUND_COMPONENTS",
    "DEFAULT_MIN_EDF",
    "MODES",
    "BoundResult",
    "bound_psd",
    "paper_inflation",
    "margin",
    "looseness",
    "check_allan_components",
    "gm_bounds_gm",
    "gm_box_envelope",
    "split_gm_box",
    "BOX_SPLIT_RATIO",
    "SHORT_T_WHITE_FACTOR",
    "random_walk_cap",
    "upper_envelope",
    "check_allan",
    "upper_envelope_from_identification",
    "bound_by_axis",
    "curves_by_axis",
    "axis_of",
]
