r"""Identification of IMU noise components from Allan variances.

The Allan variance (AV) of a sum of independent processes is the sum of their AVs, and for a fixed Gauss-Markov
(GM) time constant every component's AV is linear in its squared coefficient (:mod:`imupipe.identify.basis`).
:func:`fit_allan` therefore solves a weighted non-negative least-squares problem for the squared coefficients at
each trial time constant and profiles it, with bootstrap and profile-likelihood intervals
(:mod:`imupipe.identify.fit`); :func:`select_components` keeps only what the data show and the application needs
and :func:`refit_selected` refits that (:mod:`imupipe.identify.select`); :func:`pooling_test` says whether
several curves may share one model (:mod:`imupipe.identify.pooling`); :func:`slope_line` is the classic
graphical reading (IEEE Std 952, Kalibr, MATLAB ``allanvar`` examples) kept for comparison
(:mod:`imupipe.identify.slope`).

Modules: ``basis`` (the AV basis, pooling of curves, the re-weighted NNLS and the T profile), ``bootstrap``
(replicates with the AVs' correlation, the goodness of fit), ``intervals`` (profile intervals by test
inversion), ``fit``, ``select``, ``pooling``, ``slope``, ``resolve`` (the GM time constants the records resolve,
:func:`~imupipe.identify.resolve.gm_T_range`, and a GM outside them re-assigned to the white noise or random walk
it acts as, :func:`~imupipe.identify.resolve.reassign_unresolved_gm`).

All values are SI: rate unit u (rad/s or m/s^2), N in u/sqrt(Hz), K in u/sqrt(s), sigma and B in u, T and tau
in s, Q in u s, R in u/s.
"""

from imupipe.identify.basis import COMPONENTS, av_basis
from imupipe.identify.fit import AllanFit, fit_allan
from imupipe.identify.pooling import pooling_test
from imupipe.identify.select import refit_selected, select_components
from imupipe.identify.slope import slope_line

__all__ = [
    "COMPONENTS",
    "AllanFit",
    "fit_allan",
    "slope_line",
    "select_components",
    "refit_selected",
    "pooling_test",
    "av_basis",
]
