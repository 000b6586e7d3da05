"""The GM time-constant search starts at a stated number of sample intervals (identify.fit_tau_min_samples)."""
import numpy as np
import pytest

from imupipe.identify import fit_allan
from imupipe.identify.basis import _default_T_grid


def test_grid_floor_is_min_samples_times_dt():
    tau = np.logspace(-2, 3, 30)  # s; shortest tau = one sample at 100 Hz
    base = _default_T_grid(tau)
    floored = _default_T_grid(tau, T_min_s=5 * 0.01)
    assert base.min() == pytest.approx(0.01)
    # the floor is exactly the stated value (log grid starts at its lower end), the upper end is unchanged
    assert floored.min() == pytest.approx(0.05)
    assert floored.max() == pytest.approx(base.max())


def test_fit_allan_states_the_floored_range():
    tau = np.logspace(-2, 3, 30)
    avar = 1e-4 / tau + 1e-8 * tau / 3.0  # white + random walk, no GM
    fit = fit_allan(tau, avar, np.full_like(tau, 50.0), n_boot=0, dt=0.01, T_min_samples=5)
    lo, hi = fit.to_dict()["T_search_s"] if "T_search_s" in fit.to_dict() else (fit.T_grid.min(), fit.T_grid.max())
    assert lo == pytest.approx(0.05)
    assert hi == pytest.approx(500.0, rel=1e-6)


def test_min_samples_needs_dt():
    tau = np.logspace(-2, 3, 30)
    with pytest.raises(ValueError, match="needs dt"):
        fit_allan(tau, 1e-4 / tau, np.full_like(tau, 50.0), n_boot=0, T_min_samples=5)
