"""Simulated components have the statistics of their definitions (tolerances from sampling spread)."""

import importlib
from pathlib import Path

import numpy as np
import pytest

from imupipe.models import NoiseModel
from imupipe.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
simulate_module = importlib.import_module("imupipe.simulate")  # the package exports the function of that name


def test_white_variance(rng):
    n, rate, N = 200_000, 100.0, 1e-3
    x = simulate(NoiseModel(white=N), n, rate, rng)
    # var estimate has relative std sqrt(2/n) = 0.0032: 5 sigma
    assert x.var() == pytest.approx(N**2 * rate, rel=5 * np.sqrt(2 / n))


def test_gauss_markov_lag1_and_variance(rng):
    n, rate, sigma, T = 400_000, 10.0, 2.0, 0.5
    x = simulate(NoiseModel(gauss_markov=((sigma, T),)), n, rate, rng)
    phi = np.exp(-1 / (rate * T))
    r1 = np.dot(x[1:], x[:-1]) / np.dot(x, x)
    # AR(1) lag-1 estimate std ~ sqrt((1-phi^2)/n) = 0.0007; variance with n_eff = n (1-phi)/(1+phi)
    assert r1 == pytest.approx(phi, abs=5 * np.sqrt((1 - phi**2) / n))
    n_eff = n * (1 - phi) / (1 + phi)
    assert x.var() == pytest.approx(sigma**2, rel=5 * np.sqrt(2 / n_eff))


def test_random_walk_increments(rng):
    n, rate, K = 200_000, 50.0, 1e-4
    x = simulate(NoiseModel(random_walk=K), n, rate, rng)
    d = np.diff(x)
    assert d.var() == pytest.approx(K**2 / rate, rel=5 * np.sqrt(2 / n))


def test_flicker_allan_flat(rng):
    from imupipe.allan import overlapping_avar

    B, rate, n = 1e-3, 1.0, 2**18
    avs = np.mean([overlapping_avar(simulate(NoiseModel(flicker=B), n, rate, rng), rate, np.array([16, 64, 256]))
                   for _ in range(8)], axis=0)
    # flat at (2 ln2/pi) B^2 within 15 %: 8 records, edf of several hundred per tau, plus the missing
    # sub-1/(n dt) part of the spectrum
    np.testing.assert_allclose(avs, 0.4413 * B**2, rtol=0.15)


def test_bad_arguments():
    with pytest.raises(ValueError, match="n >= 2"):
        simulate(NoiseModel(white=1.0), 1, 1.0)
    with pytest.raises(ValueError, match="rate"):
        simulate(NoiseModel(white=1.0), 10, 0.0)


def test_batch_records_have_the_model_statistics_and_are_independent(rng):
    # n_records rows: each row a record of the model. Steady-state GM + white: the variance across
    # rows at a fixed sample (n_records draws: rel. std sqrt(2/n_records)) at the first and last sample
    # (GM started at steady state), and the lag-1 correlation between rows ~ 0 (std 1/sqrt(n))
    N, sigma, T, rate, n, rows = 1e-3, 2e-3, 5.0, 10.0, 400, 20_000
    x = simulate(NoiseModel(white=N, gauss_markov=((sigma, T),)), n, rate, rng, n_records=rows)
    assert x.shape == (rows, n)
    total = sigma**2 + N**2 * rate
    for k in (0, n - 1):
        assert x[:, k].var() == pytest.approx(total, rel=5 * np.sqrt(2 / rows))
    phi = np.exp(-1 / (rate * T))
    r1 = np.mean(x[:, 1:] * x[:, :-1]) / total  # within-row lag-1 correlation
    assert r1 == pytest.approx(phi * sigma**2 / total, abs=5 / np.sqrt(rows * n) * 2)
    across = np.corrcoef(x[0], x[1])[0, 1]  # two different records
    assert abs(across) < 5 * np.sqrt(1 + 2 * phi / (1 - phi)) / np.sqrt(n)


@pytest.mark.skipif(simulate_module._kernels is None, reason="imupipe._kernels not built")
def test_ar1_kernel_is_lfilter(rng):
    """The compiled Gauss-Markov recursion does lfilter's operations in lfilter's order: bit-identical."""
    from scipy.signal import lfilter

    e = rng.standard_normal((3, 5000))
    for phi in (0.0, 0.5, 1.0 - 1e-9):
        expected = lfilter([1.0], [1.0, -phi], e, axis=-1)
        got = simulate_module._ar1(e.copy(), phi)
        assert np.array_equal(got, expected)
    with pytest.raises(ValueError, match="whole number of rows"):
        simulate_module._kernels.ar1(np.zeros(10), 0.5, 3)


@pytest.mark.skipif(simulate_module._kernels is None, reason="imupipe._kernels not built")
def test_complex_ar1_kernel_is_lfilter(rng):
    """The compiled recursion of a narrowband line's modal coordinate does lfilter's complex operations in
    lfilter's order: bit-identical, over the poles a line takes (slow and fast, lightly and strongly damped)."""
    from scipy.signal import lfilter

    z = rng.standard_normal((3, 5000)) + 1j * rng.standard_normal((3, 5000))
    for mu in (0.5 - 0.2j, 0.99 * np.exp(0.3j), (1.0 - 1e-9) * np.exp(2.9j)):
        expected = lfilter([1.0], [1.0, -mu], z, axis=-1)
        got = simulate_module._complex_ar1(z.copy(), mu)
        assert np.array_equal(got, expected)
    with pytest.raises(ValueError, match="whole number of rows"):
        simulate_module._kernels.car1(np.zeros(10), 0.5, 0.1, 3)


def _bank_terms(w, p, weights, direct, state):
    """The terms of the flicker bank's sum, |direct w| and each branch's |u_i| (the NumPy passes with one branch
    and no direct term: y = 0 w + u_i = u_i exactly), shape (J + 1,) + w.shape."""
    terms = [np.abs(direct * w)]
    for i in range(p.size):
        st = state[:, i:i + 1].copy()
        terms.append(np.abs(simulate_module._flicker_passes(w, p[i:i + 1], weights[i:i + 1], 0.0, st)))
    return np.array(terms)


@pytest.mark.skipif(not hasattr(simulate_module._kernels, "flicker_bank"), reason="imupipe._kernels not built")
def test_flicker_bank_kernel_is_the_branch_passes(rng):
    """The compiled flicker bank (one pass, all branches) against the NumPy passes (branch by branch) on the bank of a
    10 h record at 125 Hz (11 branches), records in rows and one record in pieces whose branch states are carried:
    both compute each branch u_i[k] = p_i u_i[k-1] + weight_i w[k] by the same two products and one sum, and add the
    J + 1 terms direct w[k], u_0[k], ..., u_{J-1}[k]; two orders of summing J + 1 terms differ by at most
    2 gamma_J sum |terms| ~ J eps sum |terms| (Higham, Accuracy and Stability of Numerical Algorithms, 2002, eq. 4.4),
    so that is the bound (the kernel keeps the order, and the two agree to the bit on x86-64; the bound is what
    holds whatever the compiler does with the sum). The states after the last sample: the same, each branch exactly
    one recursion, to eps times the largest state."""
    eps = np.finfo(float).eps
    p, weights, direct, state = simulate_module._flicker_start(rng, (3,), 4_500_000, 2e-5, 1 / 125)
    J = p.size
    assert J == 11
    w = rng.standard_normal((3, 5000))
    bound = J * eps * _bank_terms(w, p, weights, direct, state).sum(axis=0)
    st_np, st_c = state.copy(), state.copy()
    y_np = simulate_module._flicker_passes(w, p, weights, direct, st_np)
    y_c = simulate_module._flicker_run(w, p, weights, direct, st_c)
    assert np.all(np.abs(y_c - y_np) <= bound)
    assert np.all(np.abs(st_c - st_np) <= eps * np.abs(st_np).max())
    # one record in pieces of 1, 999 and 4000 samples, states carried: as the whole record through the NumPy passes
    st_c = state[:1].copy()
    pieces = [simulate_module._flicker_run(np.ascontiguousarray(w[:1, a:b]), p, weights, direct, st_c)
              for a, b in ((0, 1), (1, 1000), (1000, 5000))]
    assert np.all(np.abs(np.concatenate(pieces, axis=1) - y_np[:1]) <= bound[:1])
    assert np.all(np.abs(st_c - st_np[:1]) <= eps * np.abs(st_np).max())
    # in place (y written over w) gives the same values
    w2, st2 = w.copy(), state.copy()
    assert np.array_equal(simulate_module._flicker_run(w2, p, weights, direct, st2, out=w2), y_c)
    with pytest.raises(ValueError, match="rows x J"):
        simulate_module._kernels.flicker_bank(w, p, weights, direct, np.zeros(J), np.empty_like(w), w.shape[-1])
    with pytest.raises(ValueError, match="same number of branches"):
        simulate_module._kernels.flicker_bank(w, p, weights[:-1], direct, state.copy(), np.empty_like(w), w.shape[-1])


@pytest.mark.skipif(not hasattr(simulate_module._kernels, "sim_piece"), reason="imupipe._kernels not built")
@pytest.mark.parametrize("white, gms, krw", [(0.3, [(0.99, 0.2), (0.5, 1.5)], 0.01), (None, [], 0.01),
                                             (0.3, [], None), (None, [(1.0 - 1e-7, 3e-4)], None)])
def test_linear_piece_kernel_is_the_numpy_passes(monkeypatch, white, gms, krw):
    """The compiled white + Gauss-Markov + random-walk piece (one pass) against the NumPy passes (term by term):
    the same normal draws (one draw of the piece's normals is the stream of one draw per term), the same products,
    recursions and sums in the same order, so the same bits (tolerance 0, as the AR(1) kernel against lfilter);
    the first piece (steady-state start) and a continued one, the GM states and the walk's running sum carried."""
    def pieces():
        gm_last, rw_sum, out = [0.7, -0.2][:len(gms)], 0.4, []
        rng = np.random.default_rng(17)
        for first, m in ((True, 1000), (False, 333), (False, 1)):
            x, rw_sum = simulate_module._linear_piece(rng, m, first, white, gms, gm_last, krw, rw_sum)
            out.append(x)
        return np.concatenate(out), gm_last, rw_sum, rng.standard_normal()

    x_c, last_c, sum_c, next_c = pieces()
    monkeypatch.setattr(simulate_module, "_kernels", None)
    x_np, last_np, sum_np, next_np = pieces()
    assert x_c.tobytes() == x_np.tobytes() and last_c == last_np and sum_c == sum_np and next_c == next_np


@pytest.mark.skipif(not hasattr(simulate_module._kernels, "flicker_bank"), reason="imupipe._kernels not built")
def test_chunks_without_the_kernel_give_the_same_record(rng, monkeypatch):
    """The demo's gyro model through simulate_chunks with the compiled kernels and without them (the NumPy/SciPy
    paths): the same seed gives the same record to the flicker bank's bound (J eps times the sum of the magnitudes
    of the bank's terms, test above; the other components do the same operations on both paths: lfilter and the
    AR(1) kernel are bit-identical), bounded here by J eps (|direct| + sum weights / (1 - p)) 6: each
    |u_i| <= max(|u_i[-1]|, weight_i max|w| / (1 - p_i)), max|w| < 6 over 3000 normal draws and the stationary start
    has std weight_i / sqrt(1 - p_i^2) <= weight_i / (1 - p_i)."""
    from imupipe.simulate import flicker_bank, simulate_chunks
    from imupipe.specsheet import load_spec

    model = load_spec(str(ROOT / "config" / "truth" / "stim300_like.yaml")).models["gyro"]
    n, rate = 3000, 125.0
    with_kernel = np.concatenate([v for _, v in simulate_chunks(model, n, rate, 5, chunk=700)])
    monkeypatch.setattr(simulate_module, "_kernels", None)
    without = np.concatenate([v for _, v in simulate_chunks(model, n, rate, 5, chunk=700)])
    p, res, c, gain = flicker_bank(n, 1 / rate)
    scale = model.flicker * gain
    J, eps = p.size, np.finfo(float).eps
    bound = J * eps * 6 * scale * (c + np.sum(res / (1 - p)))
    # plus the rounding of the record's last sum (the flicker added to the other components): eps |x|
    assert np.all(np.abs(with_kernel - without) <= bound + eps * np.abs(with_kernel))


def test_narrowband_steady_state_and_autocovariance(rng):
    # 20000 independent records: variance at the first and last sample (started at steady state) and the
    # lag-1 and lag-25 covariances against the closed form R(t) = Re[A e^{lambda t}]; each estimate has
    # relative std about sqrt(2/rows) = 0.01: 5 sigma
    from imupipe.models import _nb_lambda

    sigma, f0, zeta, rate, n, rows = 2.0, 0.56, 0.05, 100.0, 60, 20_000
    x = simulate(NoiseModel(narrowband=((sigma, f0, zeta),)), n, rate, rng, n_records=rows)
    tol = 5 * np.sqrt(2 / rows)
    for k in (0, n - 1):
        assert x[:, k].var() == pytest.approx(sigma**2, rel=tol)
    lam, c = _nb_lambda(f0, zeta)
    for lag in (1, 25):
        r = sigma**2 * np.real((1 - 1j * c) * np.exp(lam * lag / rate))
        est = np.mean(x[:, -1] * x[:, -1 - lag])
        assert est == pytest.approx(r, abs=tol * sigma**2)


def test_narrowband_welch_psd(rng):
    # Welch (one-sided, hann, 64 segments) of a simulated line: the band power around the line against the
    # model's, and the total against sigma^2. The line's correlation time 1/(zeta w0) = 1.6 s in a 13 100 s
    # record gives ~4000 independent stretches: relative std of a power estimate ~ sqrt(2/4000) = 0.022;
    # 5 sigma = 0.11
    from scipy.signal import welch

    sigma, f0, zeta, rate = 1.0, 2.0, 0.05, 20.0
    m = NoiseModel(narrowband=((sigma, f0, zeta),))
    x = simulate(m, 64 * 4096, rate, rng)
    f, p = welch(x, fs=rate, nperseg=4096, noverlap=0)
    band = (f > 1.5) & (f < 2.5)
    df = f[1] - f[0]
    est = np.sum(p[band]) * df
    ff = np.linspace(1.5, 2.5, 20001)
    truth = 2 * np.trapezoid(m.psd(ff), ff)
    assert est == pytest.approx(truth, rel=0.11)
    # total variance is sigma^2 (one-sided integral of the Welch PSD)
    assert np.sum(p) * df == pytest.approx(sigma**2, rel=0.11)


def test_narrowband_discrete_matches_lyapunov():
    # Phi P0 Phi^T + Qd = P0 (steady state is invariant under the exact discretisation)
    from imupipe.simulate import narrowband_discrete

    phi, Qd, P0 = narrowband_discrete(0.3, 0.56, 0.02, 0.01)
    np.testing.assert_allclose(phi @ P0 @ phi.T + Qd, P0, rtol=1e-9, atol=1e-12 * P0.max())


def test_modal_drive_is_the_complex_product_bit_for_bit(rng):
    """The oscillator's modal drive in real arithmetic equals ``eta @ v`` (a real times a complex number has no
    cross terms, so each part is the same two products and one sum): the simulated records, and every verdict
    drawn from them, are unchanged by it."""
    from imupipe.simulate import _modal_drive

    eta = rng.standard_normal((3, 1001, 2)) * np.array([1e-3, 5.0])
    v = rng.standard_normal(2) + 1j * rng.standard_normal(2)
    out = np.empty((3, 1000), dtype=np.complex128)
    _modal_drive(eta[:, :-1, :], v, out)
    assert np.array_equal(out, eta[:, :-1, :] @ v)


# ---------------------------------------------------------------------------------------------
# flicker: the bank of first-order recursions (imupipe.simulate.flicker_bank)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n, dt", [(4_500_000, 1 / 125), (36_000, 1.0), (108_000, 0.05), (100, 1.0),
                                   *[(int(n), 1.0) for n in np.geomspace(64, 2e7, 40)]])
def test_flicker_bank_psd_within_its_documented_accuracy(n, dt):
    """The bank's exact PSD (closed form of the recursions) against B^2/(2 pi f), B = 1: the bounds of the
    flicker_bank docstring, on the demo's record shapes (10 h at 125 Hz, its 1 Hz decimation, the tiny run) and
    record lengths from 64 to 2e7 samples (the bank's shape depends on n alone)."""
    from imupipe.simulate import flicker_bank, flicker_bank_psd

    p, res, c, gain = flicker_bank(n, dt)
    assert np.all(res > 0) and c > 0  # a positive sum: no cancellation

    def db(f):
        return 10 * np.log10(gain**2 * flicker_bank_psd(f, dt, p, res, c) * 2 * np.pi * f)

    assert np.abs(db(np.geomspace(4 / (2 * n * dt), 1 / (8 * dt), 2000))).max() < 0.25
    low = db(np.geomspace(1 / (2 * n * dt), 4 / (2 * n * dt), 200))
    assert -0.25 < low.min() and low.max() < 0.25
    top = db(np.geomspace(1 / (8 * dt), 1 / (2 * dt), 200))
    assert top.min() > -0.25 and top.max() < 2.8


def test_flicker_bank_starts_at_steady_state_and_is_reproducible(rng):
    """Variance across records at the first and last sample = the bank's stationary variance
    (B gain)^2 (c^2 + 2 c sum res + sum_ij res_i res_j/(1 - p_i p_j)); rel. std sqrt(2/rows): 5 sigma. The same
    seed gives the same bytes."""
    from imupipe.simulate import flicker_bank

    B, rate, n, rows = 2e-3, 1.0, 3000, 4000
    x = simulate(NoiseModel(flicker=B), n, rate, rng, n_records=rows)
    p, res, c, gain = flicker_bank(n, 1 / rate)
    var = (B * gain) ** 2 * (c**2 + 2 * c * res.sum() + res @ (1 / (1 - np.outer(p, p))) @ res)
    for k in (0, n // 2, n - 1):
        assert x[:, k].var() == pytest.approx(var, rel=5 * np.sqrt(2 / rows))
    a = simulate(NoiseModel(white=1e-3, flicker=B), 70_000, 20.0, 11)
    assert a.tobytes() == simulate(NoiseModel(white=1e-3, flicker=B), 70_000, 20.0, 11).tobytes()


def _flicker_circulant(rng, n, rate, B, rows):
    """The former draw (reference): white noise shaped by sqrt(B^2/(2 pi f)) on the rfft grid of 2n points (DC 0),
    the first n samples."""
    m, dt = 2 * n, 1 / rate
    f = np.fft.rfftfreq(m, dt)
    spec = np.zeros(f.size)
    spec[1:] = np.sqrt(B**2 / (2 * np.pi * f[1:]))
    z = rng.standard_normal((rows, f.size)) + 1j * rng.standard_normal((rows, f.size))
    return np.fft.irfft(z * spec * np.sqrt(m / dt / 2), n=m, axis=-1)[:, :n]


def test_flicker_allan_variance_as_the_former_circulant_draw(rng):
    """The flicker's Allan variance is that of the former FFT draw: the mean AV of the bank's records and of the
    former draw's records agree at every octave tau from 4 samples to n/2, within 4 standard errors of the difference
    (from the spread over the records) plus 6 % (the bank's documented 0.25 dB PSD accuracy; an AV is a
    weighted mean of the PSD). At 1-2 samples the AV weighs the band above rate/8, where the bank's PSD lies up to
    2.8 dB (x 1.9) above B^2/(2 pi f): bounded by that."""
    from imupipe.allan import overlapping_avar

    B, rate, n, rows = 1e-3, 1.0, 2**13, 96
    m = 2 ** np.arange(0, 13)
    new = np.array([overlapping_avar(r, rate, m) for r in simulate(NoiseModel(flicker=B), n, rate, rng,
                                                                    n_records=rows)])
    old = np.array([overlapping_avar(r, rate, m) for r in _flicker_circulant(rng, n, rate, B, rows)])
    se = np.sqrt(new.var(axis=0, ddof=1) / rows + old.var(axis=0, ddof=1) / rows)
    diff = np.abs(new.mean(axis=0) - old.mean(axis=0))
    band = m >= 4
    assert np.all(diff[band] < 4 * se[band] + 0.06 * old.mean(axis=0)[band]), diff / old.mean(axis=0)
    assert np.all(new.mean(axis=0)[~band] < 1.9 * old.mean(axis=0)[~band] + 4 * se[~band])
    # and the flat level (2 ln 2/pi) B^2 at taus well inside the band (4 standard errors + 6 %)
    inside = (m >= 4) & (m <= n // 64)
    level = 2 * np.log(2) / np.pi * B**2
    assert np.all(np.abs(new.mean(axis=0)[inside] - level) < 4 * new.std(axis=0, ddof=1)[inside] / np.sqrt(rows)
                  + 0.06 * level)


def test_demo_records_statistically_as_before(rng):
    """The demo's channels (config/truth/stim300_like.yaml: white + GM + flicker + random walk, 125 Hz) with the bank
    against the same model with the former flicker draw: mean Allan variances agree at every octave tau within 4
    standard errors of the difference (+1.2 %: the flicker bank's 6 % accuracy times its share of the AV, < 20 %)."""
    from imupipe.allan import overlapping_avar
    from imupipe.specsheet import load_spec

    truth = load_spec(str(ROOT / "config" / "truth" / "stim300_like.yaml"))
    rate, n, rows = 125.0, 2**15, 24
    m = 2 ** np.arange(0, 14)
    for sensor in ("gyro", "accel"):
        model = truth.models[sensor]
        rest = NoiseModel(white=model.white, gauss_markov=model.gauss_markov, random_walk=model.random_walk)
        new = np.array([overlapping_avar(r, rate, m) for r in simulate(model, n, rate, rng, n_records=rows)])
        former = simulate(rest, n, rate, rng, n_records=rows) + _flicker_circulant(rng, n, rate, model.flicker, rows)
        old = np.array([overlapping_avar(r, rate, m) for r in former])
        se = np.sqrt(new.var(axis=0, ddof=1) / rows + old.var(axis=0, ddof=1) / rows)
        diff = np.abs(new.mean(axis=0) - old.mean(axis=0))
        assert np.all(diff < 4 * se + 0.012 * old.mean(axis=0)), (sensor, diff / se)


# ---------------------------------------------------------------------------------------------
# simulate_chunks: one record in pieces (the simulate rule writes the demo's records this way)
# ---------------------------------------------------------------------------------------------
def test_chunks_continue_each_component_across_pieces():
    """Over 3000 seeds, records of 48 samples in pieces of 16: the variance of every sample and the lag-1
    covariance inside a piece and across the piece boundaries equal the model's (GM: sigma^2, phi sigma^2; flicker:
    the bank's closed forms; random walk: K^2 dt (k + 1) and K^2 dt (k + 1) for the lag-1 covariance);
    rel. std of a variance estimate sqrt(2/seeds), of a covariance at most sqrt((1 + rho^2)/seeds)/rho: 5 sigma."""
    from imupipe.simulate import flicker_bank, simulate_chunks

    seeds, n, piece, rate = 3000, 48, 16, 1.0
    sigma, T, B, K = 1.0, 5.0, 0.7, 0.3
    cases = {
        "gm": NoiseModel(gauss_markov=((sigma, T),)),
        "flicker": NoiseModel(flicker=B),
        "rw": NoiseModel(random_walk=K),
    }
    phi = np.exp(-1 / (rate * T))
    p, res, c, gain = flicker_bank(n, 1 / rate)
    C = 1 / (1 - np.outer(p, p))
    f_var = (B * gain) ** 2 * (c**2 + 2 * c * res.sum() + res @ C @ res)
    f_cov1 = (B * gain) ** 2 * np.sum(res * p * (c + C @ res))  # cov(y_k, y_{k+1}) of the bank
    for name, model in cases.items():
        x = np.array([np.concatenate([v for _, v in simulate_chunks(model, n, rate, s, chunk=piece)])
                      for s in range(seeds)])
        assert x.shape == (seeds, n)
        k = np.arange(n)
        if name == "gm":
            var, cov1 = np.full(n, sigma**2), np.full(n - 1, phi * sigma**2)
        elif name == "flicker":
            var, cov1 = np.full(n, f_var), np.full(n - 1, f_cov1)
        else:
            var, cov1 = K**2 * (k + 1) / rate, K**2 * (k[:-1] + 1) / rate
        np.testing.assert_allclose(x.var(axis=0), var, rtol=5 * np.sqrt(2 / seeds))
        got = np.mean(x[:, 1:] * x[:, :-1], axis=0) - x[:, 1:].mean(axis=0) * x[:, :-1].mean(axis=0)
        rho = cov1 / np.sqrt(var[1:] * var[:-1])
        for j in (piece - 2, piece - 1, 2 * piece - 1):  # inside a piece, across the first and second boundary
            assert got[j] == pytest.approx(cov1[j], rel=5 * np.sqrt((1 + rho[j] ** 2) / seeds) / rho[j]), (name, j)


def test_chunks_reproducible_and_as_simulate_in_distribution(rng):
    """The same seed and piece size give the same bytes; the demo's gyro model in pieces and whole: mean Allan
    variances agree at every octave tau within 4 standard errors of the difference (24 records each)."""
    from imupipe.allan import overlapping_avar
    from imupipe.simulate import simulate_chunks
    from imupipe.specsheet import load_spec

    model = load_spec(str(ROOT / "config" / "truth" / "stim300_like.yaml")).models["gyro"]
    rate, n, rows = 125.0, 2**15, 24

    def pieces(seed):
        return np.concatenate([v for _, v in simulate_chunks(model, n, rate, seed, chunk=5000)])

    assert pieces(3).tobytes() == pieces(3).tobytes()
    m = 2 ** np.arange(0, 14)
    new = np.array([overlapping_avar(pieces(s), rate, m) for s in range(100, 100 + rows)])
    old = np.array([overlapping_avar(r, rate, m) for r in simulate(model, n, rate, rng, n_records=rows)])
    se = np.sqrt(new.var(axis=0, ddof=1) / rows + old.var(axis=0, ddof=1) / rows)
    assert np.all(np.abs(new.mean(axis=0) - old.mean(axis=0)) < 4 * se)
