r"""Closed-form covariance analysis of a mismatched linear filter (fix phase + outage), no per-step loop.

Pure linear algebra on the discrete matrices of :func:`imupipe.verify.state_space`: truth
:math:`(\Phi_t, Q_{d,t}, P_{0,t}, H_t)`, filter :math:`(\Phi_f, Q_{d,f}, P_{0,f}, H_f)`, fix variance
:math:`R`. The step recursion it reproduces is the one of :func:`imupipe.verify.covariance_analysis_steps`
(module docstring of :mod:`imupipe.verify`): at every step propagate, and at a fix step apply the gain.

Fix schedule: a fix every ``m`` filter steps (``m`` = filter rate / fix rate, an integer), at the steps
:math:`k` with :math:`(k+1) \bmod m = 0` and :math:`k <` ``n_fix`` (so at t = 1/f_fix, 2/f_fix, ...); ``m`` = 1
is a fix at every step.

Quadratic-form series (:func:`quad_series`). For rows :math:`r_s` (a matrix ``R0``), a transition :math:`M`,
start :math:`C_0` and driving :math:`W`, with :math:`C_j = M^j C_0 M^{jT} + \sum_{i<j} M^i W M^{iT}`:

.. math::  r_s C_j r_s^T = g_{j,s} C_0 g_{j,s}^T + \sum_{i<j} g_{i,s} W g_{i,s}^T, \qquad g_{j,s} = r_s M^j .

The row powers :math:`g_j` are built by doubling (:math:`g_{[l, 2l)} = g_{[0, l)} M^l`, :math:`M^{2l} = (M^l)^2`)
inside a block of ``block`` powers, then block after block (:math:`g_{[b+L, b+2L)} = g_{[b, b+L)} M^L`).
No eigen-decomposition is used, so defective (Jordan) transitions such as the kinematic integrator
:math:`x, v` are exact; every :math:`g_j` is the product of at most :math:`\log_2 L + j/L` matrix
products, so its rounding error is about that many ulps of :math:`\|r\|\,\|M\|^j` (A's spectral radius is
<= 1 here, the integrator growing only polynomially). The MSE is a sum of non-negative terms
(:math:`W, C_0 \succeq 0`), so its cumulative sum has relative error of order n ulps (no cancellation).

Outage: :math:`M = A = \operatorname{diag}(\Phi_t, \Phi_f)`, :math:`W = \operatorname{diag}(Q_{d,t}, 0)`,
rows :math:`c = [-e_{pos}; e_{pos}]`: the MSE at every outage step from one call; the filter's own
:math:`P_k[0,0]` the same way with :math:`(\Phi_f, Q_{d,f}, e_0)`.

Fix phase: one cycle of m steps maps the state after a fix to the state after the next fix:
:math:`C \mapsto B_j (A^m C A^{mT} + S_m) B_j^T + [0; K_j] R [0; K_j]^T` with
:math:`S_m = \sum_{i<m} A^i Q_a A^{iT}` (built by doubling, :func:`power_and_sum`). The steps inside
a cycle are pure propagation: MSE at step jm-1+s = :math:`r_s C_j r_s^T + q_s`, with
:math:`r_s = c^T A^s` and :math:`q_s = c^T S_s c`, vectorised over s. The Riccati recursion runs
fix by fix (one Python iteration per fix, not per step) until the filter's a-posteriori :math:`P` has
converged: with :math:`\delta_j = \max_{ab} |P_j - P_{j-1}|_{ab} / \sqrt{P_{j,aa} P_{j,bb}}` (the change in
correlation units, so that a small state such as a velocity, to which the gain is nearly blind but which the
outage integrates, counts as much as the position) and :math:`\rho = (\delta_j/\delta_{j-16})^{1/16}` (checked
every 16 fixes), converged when
:math:`\delta_j = 0` (a fixed point in floating point: the map is deterministic) or when :math:`\rho < 1` and both
:math:`\delta_j` and the geometric-tail bound :math:`\delta_j \rho/(1-\rho)` on the remaining distance are
<= ``p_rtol`` = 1e-13. From there the gain is the steady-state one, the cycle map is time-invariant
(:math:`M = B A^m`, :math:`W = B S_m B^T + [0;K] R [0;K]^T`) and the rest of the fix phase is one
:func:`quad_series` call over (cycles x sub-steps).

Why on :math:`P` and why 1e-13: a first criterion on the gain alone (:math:`\|K_j - K_{j-1}\|` relative) stopped
while the velocity variance still moved (the gain sees it through :math:`dt^2 P_{vv}` only), and the outage,
which integrates the velocity error, then put the filter's P off by 3e-6 relative (test_covariance.py,
``test_steady_gain_branch_equals_step_loop``). Freezing at a relative distance :math:`\epsilon` from the exact
sequence changes the filter's :math:`P` by :math:`O(\epsilon^2)` for the gain (the Joseph form is stationary in
:math:`K` at the optimal gain) plus the carried :math:`\epsilon` of the state, and the mismatched MSE by
:math:`O(\epsilon)`, times an amplification (the outage integrates a bias error twice). Measured on a white + GM +
random-walk + flicker accel filter at 100 Hz with a fix every step against a mismatched truth (freezing at fix
10 000 and 30 000, at relative gain distances 1.8e-3 and 4.6e-4), the MSE moved by 1.7e-2 and 4.0e-3: an
amplification of about 10. At 1e-13 the result then moves by about 1e-12, three decades inside the 1e-9 that the
tests hold the closed form to against the step loop; 1e-13 is also about 1000 ulps, above the rounding floor of
:math:`\delta_j`, so the test can be met. The converse holds too: a filter with flicker-bank or GM states of time
constants 1e3-1e5 s, fixed at every 100 Hz step, does not converge to any useful tolerance within 600 s of fixes
(its gain still moves by 1e-3 relative after 10 000 fixes), so no looser tolerance would stop early with a 1e-9
result; such a fix phase runs to its end, one iteration per fix. Each iteration is two n x n
products (:math:`A^m C A^{mT}`) and O(n^2) work: a scalar fix makes :math:`B = I + [0; K] u^T` a rank-1
correction, :math:`B X B^T + R\,\tilde k \tilde k^T = X + \tilde k z^T + z \tilde k^T`,
:math:`z = X u + \tfrac12 (u^T X u + R) \tilde k`, :math:`\tilde k = [0; K]`; likewise the filter's
:math:`P \leftarrow P^- - u u^T/s`. The filter's recursion runs once per filter and schedule
(:func:`imupipe.verify.covariance_analysis` keeps it for the truths that follow). The truths of one filter share
its gains, so :func:`mismatched_mse_many` runs their fix-by-fix phases in one loop (one Python iteration per fix
for all of them, the covariances stacked in one 3-D array, zero-padded to the largest dimension): with state
dimensions of 3-10 the per-fix cost is the interpreter's overhead per array operation, not the arithmetic, so a
stack of four truths costs about what one does.

Compiled per-fix loops. The three loops that take one iteration per fix (the filter's Riccati recursion with its
convergence test, the truths' stacked recursion, and :func:`imupipe.verify._replay_errors`' fix phase) run in C
(``imupipe._kernels``: ``riccati_fixes``, ``mismatched_fixes``, ``replay_fixes``) when the optional module is built,
and in NumPy otherwise (``backend`` argument, or :func:`compiled_kernels` None). The C loops are the same
recursions in the same order of operations per fix, with two differences that change only the rounding: the
products :math:`A C A^T` skip the exact zeros of :math:`A`'s rows (the transitions are sparse: diagonal noise
states, the integrator, the augmented coupling block; adding :math:`0 \cdot x` is exact), so a product costs
:math:`O(\mathrm{nnz}(A)\, n)`, and each truth is carried at its own dimension (not zero-padded to the largest).
The two paths agree to 1e-12 relative at every step (tests/test_covariance.py, tests/test_verify.py), and both are
held to the step loop at 1e-9. A steady-gain freeze does not apply where it would matter most: the default bound's
filters (white + GM + random walk), fixed at every 1000 Hz step, still move their gain by 3 % (accel) and 21 %
(gyro) between 300 s and 600 s of fixes, so the fix phase is not a time-invariant map and cannot be doubled.

The worst MSE/P is then taken over every step (all steps are computed; nothing is sampled).

Reference: A. Gelb (ed.), "Applied Optimal Estimation", MIT Press 1974, section 7.2 (covariance analysis of
suboptimal filters); the doubling of :math:`\sum A^i Q A^{iT}` is the standard one for the discrete
Lyapunov sum (e.g. B. D. O. Anderson, J. B. Moore, "Optimal Filtering", Prentice-Hall 1979, ch. 4).
"""

from __future__ import annotations

import math

import numpy as np

from imupipe.backend import choose_backend

try:  # optional compiled per-fix loops; the NumPy path gives the same results to rounding
    from imupipe import _kernels
    if not hasattr(_kernels, "mismatched_fixes"):  # pragma: no cover - a module built before these loops
        _kernels = None
except ImportError:  # pragma: no cover - exercised by forcing backend="numpy" in the tests
    _kernels = None

__all__ = ["compiled_kernels", "quad_series", "row_powers", "power_and_sum", "filter_variance", "mismatched_mse", "mismatched_mse_many",
           "augmented", "fix_gain_array"]

P_RTOL = 1e-13
_CHECK_EVERY = 16  # fixes between two convergence checks (a late stop costs at most 15 iterations)


def pick_backend(backend: str) -> str:
    """'c' or 'numpy' for `backend` ('auto': the compiled loops of ``imupipe._kernels`` when they are built;
    :func:`imupipe.backend.choose_backend`)."""
    return choose_backend(backend, _kernels)


class FixGains(list):
    """The filter's gain per fix, a list of (n, 1) arrays (:func:`filter_variance`): entries from `n_iter` on are
    the same steady-gain object. `array` (n_iter, n), when set, holds the first `n_iter` gains as rows."""

    n_iter: int
    array: np.ndarray | None = None


def _n_iter(gains) -> int:
    """Fixes before the steady gain: `gains.n_iter`, or the first j > 0 whose gain is the object of fix j - 1."""
    n = getattr(gains, "n_iter", None)
    if n is not None:
        return int(n)
    return next((j for j in range(1, len(gains)) if gains[j] is gains[j - 1]), len(gains))


def _iterated_array(gains, n_iter) -> np.ndarray:
    arr = getattr(gains, "array", None)
    if arr is None or arr.shape[0] < n_iter:
        arr = np.array([np.asarray(g, dtype=float).reshape(-1) for g in gains[:n_iter]]).reshape(n_iter, -1)
    return np.ascontiguousarray(arr[:n_iter], dtype=float)


def fix_gain_array(gains) -> np.ndarray:
    """The gains of :func:`filter_variance` as one (fixes, n) array (row j: the gain of fix j)."""
    J = len(gains)
    if J == 0:
        return np.zeros((0, 0))
    n_iter = _n_iter(gains)
    head = _iterated_array(gains, n_iter)
    if n_iter == J:
        return head
    steady = np.asarray(gains[n_iter], dtype=float).reshape(1, -1)
    return np.concatenate([head.reshape(n_iter, -1), np.repeat(steady, J - n_iter, axis=0)])


def row_powers(R0, M, count, block):
    """Yield (start, G) with G[j] = R0 @ M^(start + j), shape (L, p, n), block after block.

    The rows of a block are stored as one (L p, n) array, so that each step is one 2-D matrix product (a
    stacked (L, p, n) @ (n, n) product is L small products). The blocks share two buffers: a block is valid
    until the next one is requested."""
    R0 = np.atleast_2d(np.asarray(R0, dtype=float))
    L = max(1, min(block, count))
    p, nn = R0.shape
    G = np.empty((L * p, nn))  # the rows of G[j] at j p .. j p + p - 1: every product below is one 2-D GEMM
    G[:p] = R0
    Ml = np.asarray(M, dtype=float)
    filled = 1
    while filled < L:
        take = min(filled, L - filled)
        np.matmul(G[:take * p], Ml, out=G[filled * p:(filled + take) * p])
        filled += take
        Ml = Ml @ Ml  # M^filled (filled doubles until the block is full)
    # M^L for the block-to-block step
    ML = np.linalg.matrix_power(np.asarray(M, dtype=float), L)
    G2 = np.empty_like(G)
    start = 0
    while start < count:
        n = min(L, count - start)
        yield start, G[:n * p].reshape(n, p, nn)
        start += L
        if start < count:
            np.matmul(G, ML, out=G2)
            G, G2 = G2, G


def quad_series(R0, M, C0, W, count, block=16384):
    r"""out[j, s] = r_s C_j r_s^T with C_j = M^j C0 M^jT + sum_{i<j} M^i W M^iT, j = 0..count-1.

    R0 : (p, n) rows r_s (or one row, (n,)); returns (count, p). Exact for defective M (module docstring).
    """
    R0 = np.atleast_2d(np.asarray(R0, dtype=float))
    out = np.empty((count, R0.shape[0]))
    acc = np.zeros(R0.shape[0])
    C0, W = np.asarray(C0, dtype=float), np.asarray(W, dtype=float)
    for start, G in row_powers(R0, M, count, block):
        G2 = G.reshape(-1, G.shape[-1])  # (L p, n): one matrix product per quadratic form
        c0 = np.einsum("ia,ia->i", G2 @ C0, G2).reshape(G.shape[:2])
        w = np.einsum("ia,ia->i", G2 @ W, G2).reshape(G.shape[:2])
        cs = np.cumsum(w, axis=0)
        excl = np.vstack([np.zeros((1, w.shape[1])), cs[:-1]]) + acc
        out[start:start + G.shape[0]] = c0 + excl
        acc = acc + cs[-1]
    return out


def power_and_sum(A, Q, m):
    r"""(A^m, S_m = sum_{i<m} A^i Q A^iT) by doubling: S_{2l} = S_l + A^l S_l A^lT, exact for Jordan blocks."""
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    P, S = np.eye(n), np.zeros((n, n))  # A^k, S_k for the bits taken so far
    Al, Sl = A.copy(), np.asarray(Q, dtype=float).copy()  # A^l, S_l, l = 2^b
    k = m
    while k:
        if k & 1:
            S = S + P @ Sl @ P.T  # S_{k+l} = S_k + A^k S_l A^kT
            P = P @ Al
        k >>= 1
        if k:
            Sl = Sl + Al @ Sl @ Al.T
            Al = Al @ Al
    return P, 0.5 * (S + S.T)


def _rows(r, M, m):
    """(m, n) rows r M^s, s = 0..m-1."""
    return np.concatenate([G[:, 0, :] for _, G in row_powers(r, M, m, max(1, m))])


def _cycles(m, n_fix):
    return n_fix // m if m > 0 else 0


def _record_substeps(out, k0: int, m: int, M, Rs, sub, *, c=None, e0: bool = False) -> None:
    """Write the variances of the m sub-steps after a fix (steps k0 .. k0 + m - 1, those >= 0) into `out`: with one
    sub-step the quadratic form of `M` itself (``c^T M c``, or ``M[0, 0]`` with `e0`), else the row-power forms
    ``(R_s M R_s^T)_{00} + sub_s`` of the covariance `M` propagated s steps (rows `Rs`, process part `sub`)."""
    if m == 1:
        if k0 >= 0:
            out[k0] = M[0, 0] if e0 else float(c @ M @ c)
        return
    vals = ((Rs @ M) * Rs).sum(axis=1) + sub
    lo = max(0, k0)
    out[lo:k0 + m] = vals[lo - k0:]


def filter_variance(Phi_f, Qd_f, P0_f, H_f, R, n_steps, n_fix, m=1, p_rtol=P_RTOL, backend="auto"):
    r"""The filter's a-posteriori P[0,0] at every step and its gains per fix: (pvar (n_steps,), gains list).

    gains[j] (n, 1) is the gain of fix j (step (j+1) m - 1); after convergence (module docstring) the list holds
    the steady gain for the remaining fixes (the same object). One Python iteration per fix until then, of
    O(n^2) work besides the propagation :math:`A^m P A^{mT} + S_m` (two n x n products): the update is
    :math:`P \leftarrow P^- - u u^T/s`, :math:`u = P^- h`, :math:`s = h^T u + R`, :math:`K = u/s` (the Joseph
    form with the optimal gain, to rounding). `backend`: 'c' runs the fix-by-fix part in
    ``imupipe._kernels.riccati_fixes`` (the same recursion and stopping rule, sparse products), 'numpy' here,
    'auto' the first available; they agree to rounding. The gains are a :class:`FixGains`."""
    be = pick_backend(backend)
    n = Phi_f.shape[0]
    e0 = np.zeros(n)
    e0[0] = 1.0
    J = _cycles(m, n_fix)
    Am, Sm = power_and_sum(Phi_f, Qd_f, m)
    AmT = np.ascontiguousarray(Am.T)
    h = np.asarray(H_f, dtype=float)[0]
    sub = quad_series(e0, Phi_f, np.zeros((n, n)), Qd_f, m)[:, 0]  # q_s = e0^T S_s e0, s < m
    Rs = _rows(e0, Phi_f, m)  # e0^T Phi^s, s < m
    pvar = np.empty(n_steps)
    P = np.array(P0_f, dtype=float, order="C")
    gains = FixGains()
    d_prev = None
    j = 0
    steady = None
    tmp = np.empty((n, n))
    if be == "c" and J > 0:
        G = np.empty((J, n))
        j, conv = _kernels.riccati_fixes(n, np.ascontiguousarray(Am), np.ascontiguousarray(Sm),
                                         np.ascontiguousarray(h), float(R), P, J, m, np.ascontiguousarray(Rs),
                                         np.ascontiguousarray(sub), pvar, G, _CHECK_EVERY, float(p_rtol))
        gains.extend(G[:j, :, None])
        gains.array = G[:j]
        if conv:
            steady = gains[-1]
    while be == "numpy" and j < J:
        # P at sub-steps s = 0..m-1 after state j (step jm-1+s); s = 0 is the step of fix j-1
        k0 = j * m - 1
        _record_substeps(pvar, k0, m, P, Rs, sub, e0=True)
        np.matmul(Am, P, out=tmp)
        Pm = tmp @ AmT
        Pm += Sm
        u = Pm @ h
        s = float(h @ u) + R
        K = u / s
        Pm -= np.multiply.outer(K, u)
        P_prev, P = P, 0.5 * (Pm + Pm.T)
        gains.append(K[:, None])
        j += 1
        if j % _CHECK_EVERY:
            continue
        # convergence of P itself (module docstring): its change over one fix in correlation units, checked
        # every _CHECK_EVERY fixes; rho per fix from the ratio of two checks
        sd = np.sqrt(np.maximum(np.diag(P), np.finfo(float).tiny))
        d = float(np.max(np.abs(P - P_prev) / np.multiply.outer(sd, sd)))
        if d == 0.0:
            steady = gains[-1]
            break
        if d_prev is not None and d <= p_rtol and d < d_prev:
            rho = (d / d_prev) ** (1.0 / _CHECK_EVERY)
            if d * rho / (1.0 - rho) <= p_rtol:
                steady = gains[-1]
                break
        d_prev = d
    gains.n_iter = j
    if steady is not None and j < J:
        # steady state: P after each fix is constant (to p_rtol); same sub-step pattern every cycle
        vals = ((Rs @ P) * Rs).sum(axis=1) + sub
        gains.extend([steady] * (J - j))
        k0 = j * m - 1
        pvar[k0:J * m - 1] = np.tile(vals, J - j)[: J * m - 1 - k0]
        j = J
    # outage (and the tail of the fix phase after the last fix): propagation from the state after fix J
    _fill_outage(pvar, J * m - 1, e0, Phi_f, P, Qd_f)
    return pvar, gains


def _fill_outage(out, k0, r, M, C, Q):
    """Steps k0 .. end of `out` after the last fix (state C at step k0; k0 = -1: no fix, C the prior):
    out[k0] = r C r^T and out[k0 + i] = r C_i r^T with C_i = M C_{i-1} M^T + Q (:func:`quad_series`)."""
    cnt = out.size - k0
    if cnt > 1:
        out[k0 + 1:] = quad_series(r, M, C, Q, cnt)[1:, 0]
    if k0 >= 0:
        rr = np.atleast_2d(r)
        out[k0] = float((rr @ C @ rr.T)[0, 0])


def augmented(Phi_t, Qd_t, P0_t, H_t, Phi_f, H_f, shared=((0, 0),)):
    r"""Augmented system in error coordinates: (A, Q_a, C_0, c, B(K), n_t).

    The vector :math:`[x_t; \hat x_f]` is mapped to :math:`[x_t; e]`, :math:`e = \hat x_f - E x_t`, with
    :math:`E` putting truth state i_t at filter state i_f for each pair of `shared` (the kinematic states,
    present in both). This similarity transform :math:`T = [[I, 0], [-E, I]]` is exact; it takes the
    large kinematic variances (the truth's position grows like t^2 var_vel) out of the quadratic form,
    which becomes :math:`c = [0; e_0]`, so no cancellation of two large numbers gives the small MSE.
    With no measurement :math:`A = T \operatorname{diag}(\Phi_t, \Phi_f) T^{-1}`; a fix is
    :math:`B = T [[I, 0], [K H_t, I - K H_f]] T^{-1}` plus :math:`[0; K] R [0; K]^T` (T leaves it).
    """
    nt, nf = Phi_t.shape[0], Phi_f.shape[0]
    n = nt + nf
    E = np.zeros((nf, nt))
    for it, jf in shared:
        E[jf, it] = 1.0
    # blocks of T A T^-1 and T B T^-1 formed directly (differences of equal entries are exact zeros)
    A = np.zeros((n, n))
    A[:nt, :nt], A[nt:, nt:] = Phi_t, Phi_f
    A[nt:, :nt] = Phi_f @ E - E @ Phi_t
    Qa = np.zeros((n, n))
    Qa[:nt, :nt] = Qd_t
    Qa[nt:, :nt] = -E @ Qd_t
    Qa[:nt, nt:] = Qa[nt:, :nt].T
    Qa[nt:, nt:] = E @ Qd_t @ E.T
    C = np.zeros((n, n))
    C[:nt, :nt] = P0_t
    C[nt:, :nt] = -E @ P0_t
    C[:nt, nt:] = C[nt:, :nt].T
    C[nt:, nt:] = E @ P0_t @ E.T
    c = np.zeros(n)
    c[nt] = 1.0
    c[:nt] = -np.asarray(H_t, dtype=float)[0] + np.asarray(H_f, dtype=float)[0] @ E  # 0 when x is shared
    dH = np.asarray(H_t, dtype=float) - np.asarray(H_f, dtype=float) @ E

    def B_of(K):
        B = np.eye(n)
        B[nt:, :nt] = K @ dH
        B[nt:, nt:] -= K @ H_f
        return B

    return A, Qa, C, c, B_of, nt


def mismatched_mse(Phi_t, Qd_t, P0_t, H_t, Phi_f, Qd_f, P0_f, H_f, R, n_steps, n_fix, m=1, gains=None,
                   p_rtol=P_RTOL, shared=((0, 0),), backend="auto"):
    """True MSE c^T C_k c of the filter's position (angle) estimate at every step, (n_steps,), and pvar.

    The estimate starts at 0, C_0 = diag(P0_t, 0); computed in error coordinates (:func:`augmented`, `shared`:
    (truth index, filter index) of the states both have, the kinematic ones); see the module docstring for the
    schedule and method. One truth of :func:`mismatched_mse_many`."""
    pvar, gains = (None, gains) if gains is not None else filter_variance(Phi_f, Qd_f, P0_f, H_f, R, n_steps,
                                                                          n_fix, m, p_rtol, backend)
    mse = mismatched_mse_many([(Phi_t, Qd_t, P0_t, H_t, shared)], Phi_f, H_f, R, n_steps, n_fix, m, gains,
                              backend)[0]
    return mse, pvar, gains


def mismatched_mse_many(truths, Phi_f, H_f, R, n_steps, n_fix, m, gains, backend="auto"):
    r"""The true MSE of one filter against several truths at once: a list of (n_steps,) arrays.

    `truths`: sequence of (Phi_t, Qd_t, P0_t, H_t, shared) (:func:`mismatched_mse`); `gains` the filter's gains per
    fix (:func:`filter_variance`). The gain is the same for every truth, so the fix-by-fix part of the fix phase
    (until the steady gain) runs one Python iteration per fix for all truths together: the augmented covariances
    are stacked as one (T, n, n) array, n = the largest truth dimension + the filter's, each truth's states first,
    then zero padding, then the filter's states. The padding rows and columns of :math:`A^m, S_m, C_0` and
    :math:`u` are zero, so they stay exactly zero and add exact zeros to every sum: each truth's recursion is the
    one of its own unpadded matrices (to the rounding of a different summation order in the matrix products).
    `backend` (:func:`filter_variance`): 'c' runs that loop in ``imupipe._kernels.mismatched_fixes``.
    """
    be = pick_backend(backend)
    T = len(truths)
    nf = Phi_f.shape[0]
    J = _cycles(m, n_fix)
    systems = []
    for Phi_t, Qd_t, P0_t, H_t, shared in truths:
        A, Qa, C, c, B_of, nt = augmented(Phi_t, Qd_t, P0_t, H_t, Phi_f, H_f, shared)
        systems.append((A, Qa, C, c, B_of, nt))
    ntm = max(s[5] for s in systems)
    n = ntm + nf

    def pad_idx(nt):  # positions of an unpadded truth's augmented states in the padded layout
        return np.concatenate([np.arange(nt), np.arange(ntm, n)])

    Am_s = np.zeros((T, n, n))
    Sm_s = np.zeros((T, n, n))
    C_s = np.zeros((T, n, n))
    c_s = np.zeros((T, n))
    u_s = np.zeros((T, n))
    per = []
    for t, (A, Qa, C, c, B_of, nt) in enumerate(systems):
        na = A.shape[0]
        ix = pad_idx(nt)
        Am, Sm = power_and_sum(A, Qa, m)
        Am_s[t][np.ix_(ix, ix)] = Am
        Sm_s[t][np.ix_(ix, ix)] = Sm
        C_s[t][np.ix_(ix, ix)] = C
        c_s[t, ix] = c
        # B(K) = I + [0; K] u^T with u^T = [H_t - H_f E, -H_f] (a scalar fix): row nt of B(1) - I
        u = B_of(np.ones((na - nt, 1)))[nt] - np.eye(na)[nt]
        u_s[t, ix] = u
        sub = quad_series(c, A, np.zeros((na, na)), Qa, m)[:, 0]
        Rs = _rows(c, A, m)
        per.append((Am, Sm, sub, Rs, ix, u))
    mse = np.empty((T, n_steps))
    AmT_s = np.ascontiguousarray(np.swapaxes(Am_s, 1, 2))
    tmp = np.empty((T, n, n))
    X = np.empty((T, n, n))
    XT = np.swapaxes(X, 1, 2)
    u3, c3 = u_s[:, :, None], c_s[:, :, None]  # column vectors: batched products by matmul (numpy >= 1.26)
    u3T = np.swapaxes(u3, 1, 2)
    y = np.empty((T, n, 1))
    Cc = np.empty((T, n, 1))
    cT = np.swapaxes(c3, 1, 2)
    q = np.empty((T, 1, 1))
    Xf = X[:, ntm:, :]  # the filter's rows
    half_R = 0.5 * R
    unit_c = bool(np.all(c_s == np.eye(n)[ntm]))
    j = 0
    j_stop = min(J, _n_iter(gains))  # the steady gain from there on
    if be == "c" and j_stop > 0:
        # each truth unpadded (its own dimension), packed one after the other
        def pack(arrs):
            return np.ascontiguousarray(np.concatenate([np.asarray(a, dtype=float).ravel() for a in arrs]))

        dims = np.array([sy[0].shape[0] for sy in systems], dtype=np.int64)
        unit_idx = np.array([sy[5] if np.array_equal(sy[3], np.eye(sy[0].shape[0])[sy[5]]) else -1
                             for sy in systems], dtype=np.int64)
        C_p = pack([sy[2] for sy in systems])
        _kernels.mismatched_fixes(dims, nf, pack([q[0] for q in per]), pack([q[1] for q in per]),
                                  pack([q[5] for q in per]), pack([sy[3] for sy in systems]), unit_idx, C_p,
                                  _iterated_array(gains, j_stop), j_stop, float(R), m, pack([q[3] for q in per]),
                                  pack([q[2] for q in per]), mse, n_steps)
        lo = 0
        for t, q in enumerate(per):
            na = int(dims[t])
            C_s[t][np.ix_(q[4], q[4])] = C_p[lo:lo + na * na].reshape(na, na)
            lo += na * na
        j = j_stop
    while j < j_stop:
        K = gains[j]
        k0 = j * m - 1
        if m == 1:
            if k0 >= 0:
                if unit_c:  # c = e_ntm (the position is shared): c^T C c is that diagonal entry, exactly
                    mse[:, k0] = C_s[:, ntm, ntm]
                else:
                    np.matmul(cT, np.matmul(C_s, c3, out=Cc), out=q)  # c^T C c
                    mse[:, k0] = q[:, 0, 0]
        else:
            for t, (_, _, sub, Rs, ix, _) in enumerate(per):
                _record_substeps(mse[t], k0, m, C_s[t][np.ix_(ix, ix)], Rs, sub)
        # X = A^m C A^mT + S_m; B X B^T + R kt kt^T = X + kt z^T + z kt^T, z = X u + (u^T X u + R)/2 kt
        np.matmul(Am_s, C_s, out=tmp)
        np.matmul(tmp, AmT_s, out=X)
        X += Sm_s
        np.matmul(X, u3, out=y)
        w = np.matmul(u3T, y)[:, :, 0] * 0.5 + half_R  # (u^T X u + R)/2, (T, 1)
        z = y[:, :, 0]
        z[:, ntm:] += w * K[:, 0]
        # the symmetric part of X + 2 kt z^T is X + kt z^T + z kt^T (X symmetric); kt is 0 above row ntm
        z *= 2.0
        Xf += K[None, :, :] * z[:, None, :]
        np.add(X, XT, out=C_s)
        C_s *= 0.5
        j += 1
    out = []
    for t, (A, Qa, _, c, B_of, nt) in enumerate(systems):
        Am, Sm, sub, Rs, ix, _ = per[t]
        C = C_s[t][np.ix_(ix, ix)].copy()
        mse_t = mse[t]
        jj = j
        if jj < J:
            na = A.shape[0]
            K = gains[jj]
            B = B_of(K)
            M = B @ Am
            Kz = np.zeros((na, 1))
            Kz[nt:] = K
            W = B @ Sm @ B.T + R * (Kz @ Kz.T)
            vals = quad_series(Rs, M, C, W, J - jj)  # (cycles, m): r_s C_i r_s^T, i = j..J-1
            k0 = jj * m - 1  # >= 0: the steady gain is reached after a few fixes
            mse_t[k0:J * m - 1] = (vals + sub).reshape(-1)
            C = _lyap_power(M, C, W, J - jj)  # the state after fix J, for the outage
        _fill_outage(mse_t, J * m - 1, c, A, C, Qa)
        out.append(mse_t)
    return out


def _lyap_power(M, C0, W, j):
    """M^j C0 M^jT + sum_{i<j} M^i W M^iT by doubling (power_and_sum)."""
    Mj, Sj = power_and_sum(M, W, j)
    C = Mj @ C0 @ Mj.T + Sj
    return 0.5 * (C + C.T)


def compiled_kernels():
    """The compiled per-fix loops (the optional C module: ``riccati_fixes``, ``mismatched_fixes``,
    ``replay_fixes``), or None when it is not built (the NumPy path then runs)."""
    return _kernels
