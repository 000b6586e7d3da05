"""Figures (imupipe.plot): structure, labels with units, legends, log axes, and plotted data read back."""

import math
import subprocess
import sys

import numpy as np
import pytest

from imupipe.bound import paper_inflation
from imupipe.models import NoiseModel
from imupipe.plot import (
    plot_allan_components,
    plot_inflation_effect,
    plot_inflation_steps,
    plot_psd_bound,
    save_figure,
    table3_model,
)

DT = 1.0
N_FREQ_SAMPLES = 1024  # window length (samples) of the synthetic periodograms
N_CURVES = 6
SPEC = NoiseModel(white=2e-4, gauss_markov=((3e-5, 300.0),), random_walk=2e-6)
TRUE = NoiseModel(white=3e-4, gauss_markov=((6e-5, 150.0),), random_walk=4e-6)
BOUND = NoiseModel(white=4e-4, gauss_markov=((1e-4, 120.0),), random_walk=8e-6)


@pytest.fixture(scope="module")
def psd_case():
    """Frequency grid (with DC), chi2(2)/2-scattered sample PSDs of TRUE (two-sided, u^2/Hz)."""
    rng = np.random.default_rng(20211101)
    f = np.fft.rfftfreq(N_FREQ_SAMPLES, DT)
    s = np.zeros(f.size)
    s[1:] = TRUE.psd_sampled(f[1:], DT)
    curves = s * rng.chisquare(2, size=(N_CURVES, f.size)) / 2.0
    curves[:, 0] = 0.0
    return f, curves


@pytest.fixture(scope="module")
def allan_case():
    rng = np.random.default_rng(7)
    tau = 2.0 ** np.arange(0, 13)
    identified = NoiseModel(white=3e-4, gauss_markov=((6e-5, 150.0),), random_walk=4e-6, flicker=1e-5)
    edf = np.maximum(36000.0 / tau / 2.0, 2.0)
    avar = identified.avar(tau) * rng.chisquare(edf, size=(N_CURVES, tau.size)) / edf
    return tau, avar, identified


def _by_gid(ax, gid):
    lines = [ln for ln in ax.get_lines() if ln.get_gid() == gid]
    assert len(lines) == 1, f"expected one line with gid {gid!r}, got {len(lines)}"
    return lines[0]


def _legend(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()]


def _assert_loglog(ax):
    assert ax.get_xscale() == "log"
    assert ax.get_yscale() == "log"


# ---------------------------------------------------------------------------------------------
# Figure 5
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("dt", [DT, None])
def test_psd_bound_structure_and_bound_line(psd_case, dt):
    from matplotlib.figure import Figure

    f, curves = psd_case
    fig = plot_psd_bound(f, curves, SPEC, BOUND, sensor="gyro", dt=dt)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    _assert_loglog(ax)
    assert "[Hz]" in ax.get_xlabel()
    assert "two-sided PSD" in ax.get_ylabel() and "(rad/s)^2/Hz" in ax.get_ylabel()
    assert "gyro" in fig.get_suptitle()
    assert _legend(ax) == [
        f"sample PSDs ({N_CURVES} curves)", "spec sheet", "bound",
        "bound: white noise", "bound: Gauss-Markov", "bound: random walk",
    ]
    bound_line = _by_gid(ax, "bound")
    x = np.asarray(bound_line.get_xdata())
    np.testing.assert_array_equal(x, f[1:])  # DC skipped
    expect = BOUND.psd(x) if dt is None else BOUND.psd_sampled(x, dt)
    np.testing.assert_allclose(bound_line.get_ydata(), expect, rtol=1e-12, atol=0)
    spec_line = _by_gid(ax, "spec")
    np.testing.assert_allclose(spec_line.get_ydata(), SPEC.psd(x) if dt is None else SPEC.psd_sampled(x, dt),
                               rtol=1e-12, atol=0)
    # each component dashed, and the components add up to the bound
    comps = [_by_gid(ax, f"bound:{n}") for n in ("white", "gauss_markov", "random_walk")]
    assert all(c.get_linestyle() == "--" for c in comps)
    np.testing.assert_allclose(sum(np.asarray(c.get_ydata()) for c in comps), bound_line.get_ydata(), rtol=1e-12)
    samples = [ln for ln in ax.get_lines() if str(ln.get_gid()).startswith("sample:")]
    assert len(samples) == N_CURVES
    np.testing.assert_array_equal(samples[2].get_ydata(), curves[2, 1:])


def test_psd_bound_spec_display_units_and_bound_result(psd_case):
    f, curves = psd_case
    res = paper_inflation(f, curves, SPEC, dt=DT, step=1.2)
    fig = plot_psd_bound(f, curves, SPEC, res, sensor="gyro", dt=DT, display_unit="spec")
    ax = fig.axes[0]
    assert "(deg/h)^2/Hz" in ax.get_ylabel()
    assert "paper" in fig.get_suptitle()  # the BoundResult's mode names itself
    c = (180.0 / math.pi * 3600.0) ** 2
    y = np.asarray(_by_gid(ax, "bound").get_ydata())
    np.testing.assert_allclose(y, c * res.model.psd_sampled(f[1:], DT), rtol=1e-12)
    fig_a = plot_psd_bound(f, curves, SPEC, BOUND, sensor="accel", display_unit="spec")
    assert "(mg)^2/Hz" in fig_a.axes[0].get_ylabel()
    fig_si = plot_psd_bound(f, curves, SPEC, BOUND, sensor="accel")
    assert "(m/s^2)^2/Hz" in fig_si.axes[0].get_ylabel()


def test_psd_bound_xarray_curves_and_labels(psd_case):
    xr = pytest.importorskip("xarray")
    f, curves = psd_case
    da = xr.DataArray(curves.reshape(2, 3, f.size), dims=("dataset", "axis", "frequency"),
                      coords={"dataset": ["d1", "d2"], "axis": ["x", "y", "z"], "frequency": f})
    fig = plot_psd_bound(None, da, SPEC, BOUND, sensor="accel", dt=DT, labels=True, title="accel, spec demo")
    ax = fig.axes[0]
    assert fig.get_suptitle() == "accel, spec demo"
    legend = _legend(ax)
    assert legend[:N_CURVES] == [f"dataset={d}, axis={a}" for d in ("d1", "d2") for a in "xyz"]
    np.testing.assert_array_equal(_by_gid(ax, "sample:4").get_ydata(), curves[4, 1:])
    with pytest.raises(ValueError, match="shape"):
        plot_psd_bound(f[:-1], curves, SPEC, BOUND, sensor="gyro")
    with pytest.raises(ValueError, match="sensor"):
        plot_psd_bound(f, curves, SPEC, BOUND, sensor="mag")


# ---------------------------------------------------------------------------------------------
# Figure 6
# ---------------------------------------------------------------------------------------------
def test_allan_components(allan_case):
    tau, avar, identified = allan_case
    lo, hi = avar * 0.8, avar * 1.25
    fig = plot_allan_components(tau, avar, identified, BOUND, sensor="gyro", avar_lower=lo, avar_upper=hi)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    _assert_loglog(ax)
    assert "[s]" in ax.get_xlabel()
    assert "Allan deviation" in ax.get_ylabel() and "[rad/s]" in ax.get_ylabel()
    assert "gyro" in fig.get_suptitle()
    legend = _legend(ax)
    for entry in ("confidence interval", f"sample ADEVs ({N_CURVES} curves)", "identified: white noise",
                  "identified: Gauss-Markov", "identified: random walk", "identified: flicker", "identified: total",
                  "bound: white noise", "bound: Gauss-Markov", "bound: random walk", "bound: total"):
        assert entry in legend
    np.testing.assert_allclose(_by_gid(ax, "bound").get_ydata(), np.sqrt(BOUND.avar(tau)), rtol=1e-12)
    np.testing.assert_allclose(_by_gid(ax, "identified").get_ydata(), np.sqrt(identified.avar(tau)), rtol=1e-12)
    np.testing.assert_allclose(_by_gid(ax, "bound:random_walk").get_ydata(), 8e-6 * np.sqrt(tau / 3.0), rtol=1e-12)
    np.testing.assert_allclose(_by_gid(ax, "sample:3").get_ydata(), np.sqrt(avar[3]), rtol=1e-15)
    for name in ("white", "gauss_markov", "random_walk"):  # same colour, solid vs dashed
        a, b = _by_gid(ax, f"identified:{name}"), _by_gid(ax, f"bound:{name}")
        assert a.get_color() == b.get_color()
        assert a.get_linestyle() == "-" and b.get_linestyle() == "--"
    fig_a = plot_allan_components(tau, avar, identified, None, sensor="accel")
    assert "[m/s^2]" in fig_a.axes[0].get_ylabel()
    assert not any(t.startswith("bound") for t in _legend(fig_a.axes[0]))


def test_allan_components_marks_what_selection_dropped(allan_case):
    tau, avar, identified = allan_case
    fig = plot_allan_components(tau, avar, identified, BOUND, sensor="gyro", dropped=["random_walk", "flicker"])
    ax = fig.axes[0]
    legend = _legend(ax)
    for name, disp in (("random_walk", "random walk"), ("flicker", "flicker")):
        line = _by_gid(ax, f"identified:{name}")
        assert line.get_linestyle() == ":" and f"identified: {disp} (dropped)" in legend
        np.testing.assert_allclose(line.get_ydata(), np.sqrt(identified.components()[name].avar(tau)), rtol=1e-12)
    assert _by_gid(ax, "identified:white").get_linestyle() == "-" and "identified: white noise" in legend
    assert _by_gid(ax, "bound:random_walk").get_linestyle() == "--"  # the bound's components are not selected
    # the total is the full fit's, dropped components included (it is what was fitted to the AVs)
    np.testing.assert_allclose(_by_gid(ax, "identified").get_ydata(), np.sqrt(identified.avar(tau)), rtol=1e-12)
    with pytest.raises(ValueError, match="unknown component"):
        plot_allan_components(tau, avar, identified, BOUND, sensor="gyro", dropped=["gm"])


def test_allan_components_xarray(allan_case):
    xr = pytest.importorskip("xarray")
    tau, avar, identified = allan_case
    da = xr.DataArray(avar.reshape(2, 3, tau.size), dims=("dataset", "axis", "tau"),
                      coords={"dataset": ["a", "b"], "axis": list("xyz"), "tau": tau})
    fig = plot_allan_components(None, da, identified, BOUND, sensor="gyro", avar_lower=da * 0.5,
                                avar_upper=da * 2.0)
    ax = fig.axes[0]
    assert len([ln for ln in ax.get_lines() if str(ln.get_gid()).startswith("sample:")]) == N_CURVES
    np.testing.assert_allclose(_by_gid(ax, "sample:5").get_ydata(), np.sqrt(avar[5]), rtol=1e-15)


# ---------------------------------------------------------------------------------------------
# Figure 7
# ---------------------------------------------------------------------------------------------
def test_table3_model_si():
    m = table3_model()
    assert m.white == pytest.approx(0.1 / 60.0, rel=1e-15)
    assert m.gauss_markov == ((9.80665e-2, 1e3),)
    assert m.random_walk == 1e-4 and m.dt == 1.0


def test_inflation_effect():
    fig = plot_inflation_effect()
    assert len(fig.axes) == 4
    base = table3_model()
    for ax, key in zip(fig.axes, ("N", "K", "sigma", "T")):
        _assert_loglog(ax)
        assert "[Hz]" in ax.get_xlabel() and "(m/s^2)^2/Hz" in ax.get_ylabel()
        line = _by_gid(ax, "base")
        x = np.asarray(line.get_xdata())
        assert x[0] == pytest.approx(1.0 / 36000.0, rel=1e-12) and x[-1] == pytest.approx(0.5, rel=1e-12)
        np.testing.assert_allclose(line.get_ydata(), base.psd(x), rtol=1e-12)
        legend = _legend(ax)
        assert legend[0] == "Table 3 example"
        assert len(legend) == (7 if key == "T" else 4)
    assert "accel" in fig.get_suptitle()
    ax_n, ax_k, ax_s, ax_t = fig.axes
    assert "T / 10" in _legend(ax_t) and "T x 10" in _legend(ax_t)
    x = np.asarray(_by_gid(ax_n, "base").get_xdata())
    # white x2 adds 3 N^2 everywhere; K x5 adds 24 K^2/w^2; sigma x10 multiplies the GM term by 100
    diff = np.asarray(_by_gid(ax_n, "N:x2").get_ydata()) - base.psd(x)
    np.testing.assert_allclose(diff, 3.0 * base.white**2, rtol=1e-9)
    diff = np.asarray(_by_gid(ax_k, "K:x5").get_ydata()) - base.psd(x)
    np.testing.assert_allclose(diff, 24.0 * base.random_walk**2 / (2 * np.pi * x) ** 2, rtol=1e-9)
    gm = NoiseModel(gauss_markov=base.gauss_markov).psd(x)
    diff = np.asarray(_by_gid(ax_s, "sigma:x10").get_ydata()) - base.psd(x)
    np.testing.assert_allclose(diff, 99.0 * gm, rtol=1e-9)
    y_t = np.asarray(_by_gid(ax_t, "T:/5").get_ydata())
    np.testing.assert_allclose(y_t, NoiseModel(white=base.white, gauss_markov=((9.80665e-2, 200.0),),
                                               random_walk=1e-4).psd(x), rtol=1e-12)


def test_inflation_effect_paper_factors_and_gyro():
    fig = plot_inflation_effect(factors=(0.5, 1.5), duration_s=3600.0, dt=0.5)
    assert _legend(fig.axes[2]) == ["Table 3 example", "σ x 0.5", "σ x 1.5"]
    assert _by_gid(fig.axes[0], "base").get_xdata()[-1] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="gyro"):
        plot_inflation_effect(sensor="gyro")
    fig_g = plot_inflation_effect(SPEC, sensor="gyro", factors=(3,))
    assert "(rad/s)^2/Hz" in fig_g.axes[0].get_ylabel()
    assert _legend(fig_g.axes[0]) == ["base model", "N x 3"]


# ---------------------------------------------------------------------------------------------
# Figure 8
# ---------------------------------------------------------------------------------------------
def _phase_labels(history):
    """Expected legend labels of every phase end (run of one parameter) and the row index of each end."""
    params = [h[0] for h in history]
    ends = [i for i in range(1, len(params)) if i == len(params) - 1 or params[i + 1] != params[i]]
    seen, labels = {}, []
    for i in ends:
        seen[params[i]] = seen.get(params[i], 0) + 1
        labels.append(f"after {params[i]}" + (f" (round {seen[params[i]]})" if seen[params[i]] > 1 else ""))
    return labels, ends


@pytest.mark.parametrize("max_phases", [6, 1000])
def test_inflation_steps(psd_case, max_phases):
    f, curves = psd_case
    res = paper_inflation(f, curves, SPEC, dt=DT)
    assert res.bounded
    history = res.details["history"]
    fig = plot_inflation_steps(f, curves, SPEC, history, sensor="gyro", dt=DT, max_phases=max_phases)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    _assert_loglog(ax)
    assert "(rad/s)^2/Hz" in ax.get_ylabel() and "[Hz]" in ax.get_xlabel()
    assert "gyro" in fig.get_suptitle()
    legend = _legend(ax)
    assert legend[:2] == [f"sample PSDs ({N_CURVES} curves)", "spec sheet"]
    labels, ends = _phase_labels(history)
    assert len(labels) > 6  # this case alternates parameters: the truncation is exercised
    phases = legend[2:]
    labels[-1] = f"final, {labels[-1]}"
    if max_phases >= len(labels):
        assert phases == labels
    else:  # the first, the last and phases spread between, in order
        assert len(phases) == max_phases
        assert phases[0] == labels[0] and phases[-1] == labels[-1]
        idx = [labels.index(p) for p in phases]
        assert idx == sorted(set(idx))
        ends = [ends[i] for i in idx]
    # the last curve is the procedure's final model
    last = _by_gid(ax, f"phase:{len(phases) - 1}")
    np.testing.assert_allclose(last.get_ydata(), res.model.psd_sampled(f[1:], DT), rtol=1e-12)
    for j in (0, 2):  # each drawn phase is the model of the history row that ends it
        row = history[ends[j]]
        m = NoiseModel(white=row[1], gauss_markov=((row[2], row[3]),), random_walk=row[4])
        np.testing.assert_allclose(_by_gid(ax, f"phase:{j}").get_ydata(), m.psd_sampled(f[1:], DT), rtol=1e-12)
    np.testing.assert_allclose(_by_gid(ax, "spec").get_ydata(), SPEC.psd_sampled(f[1:], DT), rtol=1e-12)


def test_inflation_steps_paper_order():
    """Data above the spec in the GM band, little scatter: sigma is inflated first, then T deflated."""
    rng = np.random.default_rng(3)
    f = np.fft.rfftfreq(N_FREQ_SAMPLES, DT)
    true = NoiseModel(white=1e-4, gauss_markov=((2e-4, 100.0),), random_walk=1e-6)
    spec = NoiseModel(white=1.2e-4, gauss_markov=((5e-5, 200.0),), random_walk=1e-6)
    s = np.concatenate([[0.0], true.psd_sampled(f[1:], DT)])
    curves = s * rng.chisquare(100, size=(N_CURVES, f.size)) / 100.0
    res = paper_inflation(f, curves, spec, dt=DT, step=1.1)
    fig = plot_inflation_steps(f, curves, spec, res.details["history"], sensor="accel", dt=DT, title="t")
    phases = _legend(fig.axes[0])[2:]
    labels = _phase_labels(res.details["history"])[0]
    assert len(labels) <= 6
    assert phases == labels[:-1] + [f"final, {labels[-1]}"]
    assert phases[:2] == ["after sigma", "after T"]
    assert fig.get_suptitle() == "t"
    np.testing.assert_allclose(_by_gid(fig.axes[0], f"phase:{len(phases) - 1}").get_ydata(),
                               res.model.psd_sampled(f[1:], DT), rtol=1e-12)
    with pytest.raises(ValueError, match="max_phases"):
        plot_inflation_steps(f, curves, spec, res.details["history"], sensor="accel", max_phases=1)


def test_inflation_steps_repeated_phases_and_dicts(psd_case):
    f, curves = psd_case
    cols = ["parameter", "N", "sigma", "T", "K", "margin"]
    rows = [["spec", 2e-4, 3e-5, 300.0, 2e-6, 0.2], ["sigma", 2e-4, 6e-5, 300.0, 2e-6, 0.5],
            ["N", 4e-4, 6e-5, 300.0, 2e-6, 0.8], ["sigma", 4e-4, 9e-5, 300.0, 2e-6, 1.0]]
    fig = plot_inflation_steps(f, curves, SPEC, [dict(zip(cols, r)) for r in rows], sensor="accel")
    assert _legend(fig.axes[0])[2:] == ["after sigma", "after N", "final, after sigma (round 2)"]
    assert "(m/s^2)^2/Hz" in fig.axes[0].get_ylabel()
    y = _by_gid(fig.axes[0], "phase:2").get_ydata()
    np.testing.assert_allclose(y, NoiseModel(white=4e-4, gauss_markov=((9e-5, 300.0),),
                                             random_walk=2e-6).psd(f[1:]), rtol=1e-12)
    # in spec units (mg^2/Hz, imupipe.plot.SPEC_RATE_UNITS): the same curve / (9.80665e-3 m/s^2 per mg)^2
    fig = plot_inflation_steps(f, curves, SPEC, [dict(zip(cols, r)) for r in rows], sensor="accel",
                               display_unit="spec")
    assert "(mg)^2/Hz" in fig.axes[0].get_ylabel()
    np.testing.assert_allclose(_by_gid(fig.axes[0], "phase:2").get_ydata(), y / 9.80665e-3 ** 2, rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# output and import cost
# ---------------------------------------------------------------------------------------------
def test_save_figure_atomic(tmp_path, psd_case):
    f, curves = psd_case
    fig = plot_psd_bound(f, curves, SPEC, BOUND, sensor="gyro", dt=DT)
    out = tmp_path / "figs" / "psd_bound_gyro.png"
    save_figure(fig, out)
    data = out.read_bytes()
    assert len(data) > 1000 and data[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in out.parent.iterdir()) == ["psd_bound_gyro.png"]
    svg = tmp_path / "figs" / "fig7.svg"
    save_figure(plot_inflation_effect(), svg)
    assert b"<svg" in svg.read_bytes()[:2000]
    bad = tmp_path / "figs" / "fig.notaformat"
    with pytest.raises(ValueError):
        save_figure(fig, bad)
    assert sorted(p.name for p in out.parent.iterdir()) == ["fig7.svg", "psd_bound_gyro.png"]


def test_import_does_not_load_matplotlib():
    code = "import sys, imupipe.plot; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_long_curves_are_drawn_through_their_envelope():
    # a 20000-point periodogram: every log-x column keeps its extremes, so the drawn curve has the data's
    # per-column min and max (the picture at pixel resolution), with far fewer points
    from imupipe.plot import _ENVELOPE_BINS, _envelope

    rng = np.random.default_rng(8)
    f = np.linspace(0, 0.5, 20_001)[1:]
    y = rng.chisquare(2, f.size) / 2
    keep = _envelope(f, y)
    assert keep.size < f.size / 2 and np.all(np.diff(keep) > 0)
    lx = np.log(f)
    col = np.minimum(((lx - lx[0]) / (lx[-1] - lx[0]) * _ENVELOPE_BINS).astype(int), _ENVELOPE_BINS - 1)
    for c in np.unique(col)[:: 97]:
        in_col = col == c
        assert y[in_col].max() == y[keep][col[keep] == c].max()
        assert y[in_col].min() == y[keep][col[keep] == c].min()
    # short curves are drawn whole
    assert np.array_equal(_envelope(f[:1000], y[:1000]), np.arange(1000))


def test_envelope_has_one_column_per_pixel_of_its_axes():
    # the 2x2 figure's panels are about half as wide as the single-axes figure's: half the columns, and a
    # drawn sample curve keeps at most 4 points per column (first, last, min, max)
    from imupipe.plot import _DPI, _new_figure, _pixel_columns

    ax1 = _new_figure()[1][0, 0]
    panel = _new_figure(2, 2, figsize=(11.0, 8.0))[1][0, 0]
    one, quarter = _pixel_columns(ax1), _pixel_columns(panel)
    assert one == pytest.approx(ax1.get_position().width * 7.5 * _DPI, abs=1)
    assert 0.3 * one < quarter < 0.7 * one
    f = np.linspace(0, 0.5, 20_001)[1:]
    from imupipe.plot import _draw_samples

    _draw_samples(panel, f, np.random.default_rng(1).chisquare(2, (1, f.size)), None, "PSDs")
    assert panel.get_lines()[0].get_xdata().size <= 4 * quarter


# ---------------------------------------------------------------------------------------------
# Allan deviation with slope lines and N / B / K read-offs; spec-sheet units; envelope; SVG / PDF
# ---------------------------------------------------------------------------------------------
N_WR, K_WR = 1.0e-4, 1.0e-7  # rad/s/sqrt(Hz), rad/s/sqrt(s)
TAU_WR = np.geomspace(1e-2, 1e6, 8 * 200 + 1)  # 200 taus per decade


def _white_rw_avar(tau):
    return N_WR**2 / tau + K_WR**2 * tau / 3.0


def test_allan_readoffs_equal_the_closed_forms():
    from imupipe.plot import allan_readoffs

    ro = allan_readoffs(TAU_WR, _white_rw_avar(TAU_WR))
    # N read on the -1/2 line at the smallest tau: N sqrt(1 + K^2 tau^2 / (3 N^2)), relative excess 2e-11
    assert ro["white"] == pytest.approx(N_WR, rel=1e-9)
    # K on the +1/2 line at the largest tau: K sqrt(1 + 3 N^2 / (K^2 tau^2)), relative excess 1.5e-6
    assert ro["random_walk"] == pytest.approx(K_WR, rel=1e-5)
    # minimum of N^2/tau + K^2 tau/3 at tau* = sqrt(3) N / K: ADEV_min = sqrt(2 N K / sqrt(3)); the grid's
    # nearest tau is within half a step (ln ratio 0.0058) -> relative error <= (0.0058)^2 / 4 ~ 1e-5
    adev_min = math.sqrt(2 * N_WR * K_WR / math.sqrt(3.0))
    assert ro["adev_min"] == pytest.approx(adev_min, rel=2e-5)
    assert ro["flicker"] == pytest.approx(adev_min / math.sqrt(2 * math.log(2) / math.pi), rel=2e-5)
    assert ro["tau_min"] == pytest.approx(math.sqrt(3.0) * N_WR / K_WR, rel=0.012)


@pytest.mark.parametrize("display, rate_unit, n_text, factor", [
    ("spec", "deg/h", "deg/sqrt(h)", math.degrees(1.0) * 3600.0),
    ("SI", "rad/s", "rad/s/sqrt(Hz)", 1.0),
])
def test_allan_deviation_figure_units_marks_and_legend(display, rate_unit, n_text, factor):
    from imupipe.plot import plot_allan_deviation

    avar = np.vstack([_white_rw_avar(TAU_WR) * s for s in np.linspace(0.9, 1.1, 15)])  # 15 curves
    fig = plot_allan_deviation(TAU_WR, avar, sensor="gyro", display_unit=display,
                               labels=[f"c{i}" for i in range(15)])
    ax = fig.axes[0]
    assert f"[{rate_unit}]" in ax.get_ylabel() and "[s]" in ax.get_xlabel()
    legend = _legend(ax)
    assert len(legend) <= 7  # 15 curves under one entry + 3 lines
    # markers at tau = 1 s (N), the minimum (0.664 B) and tau = 3 s (K), in the display unit
    ro = fig.readoffs["si"]
    np.testing.assert_allclose(_by_gid(ax, "readoff:N").get_xdata(), [1.0])
    np.testing.assert_allclose(_by_gid(ax, "readoff:N").get_ydata(), [ro["white"] * factor], rtol=1e-12)
    np.testing.assert_allclose(_by_gid(ax, "readoff:K").get_xdata(), [3.0])
    np.testing.assert_allclose(_by_gid(ax, "readoff:K").get_ydata(), [ro["random_walk"] * factor], rtol=1e-12)
    np.testing.assert_allclose(_by_gid(ax, "readoff:B").get_ydata(), [ro["adev_min"] * factor], rtol=1e-12)
    # the median of the 15 scaled curves is the unscaled one: N as in the closed form
    assert ro["white"] == pytest.approx(N_WR, rel=1e-9)
    # slope lines have the slopes -1/2, 0, +1/2 (log-log)
    for gid, slope in (("slope:-1/2", -0.5), ("slope:0", 0.0), ("slope:+1/2", 0.5)):
        ln = _by_gid(ax, gid)
        x, y = np.log(ln.get_xdata()), np.log(ln.get_ydata())
        assert (y[-1] - y[0]) / (x[-1] - x[0]) == pytest.approx(slope, abs=1e-12)
    n_entry = next(t for t in legend if t.startswith("−1/2 line"))
    assert n_text in n_entry
    if display == "spec":  # N = 1e-4 rad/s/sqrt(Hz) = 1e-4 * 180/pi * 60 deg/sqrt(h) = 0.344
        assert "N = 0.344 deg/sqrt(h)" in n_entry
    assert "the curve at" not in n_entry  # the -1/2 line holds at 1 s: the read-off is the curve's value


def test_a_slope_read_off_off_the_curve_names_the_curve_value():
    # white noise + a flicker plateau 3 N^2 high: the -1/2 line goes through the short taus and reads N at 1 s,
    # while the curve at 1 s is sqrt(N^2 + 3 N^2) = 2 N; the legend gives the curve's value beside the line's
    from imupipe.plot import READOFF_CURVE_RTOL, plot_allan_deviation

    tau = np.geomspace(1e-3, 1e4, 7 * 50 + 1)
    avar = N_WR**2 / tau + 3.0 * N_WR**2
    fig = plot_allan_deviation(tau, avar, sensor="gyro")
    ro = fig.readoffs["si"]
    assert ro["white"] == pytest.approx(N_WR, rel=2e-3)  # read at tau = 1e-3 s: excess sqrt(1 + 3e-3) - 1 = 1.5e-3
    n_entry = next(t for t in _legend(fig.axes[0]) if t.startswith("−1/2 line"))
    # N = 1e-4 rad/s/sqrt(Hz) = 0.344 deg/sqrt(h); the curve at 1 s is 2 N = 0.688 deg/sqrt(h) (sigma(1 s) sqrt(1 s))
    assert "N = 0.344 deg/sqrt(h) (read at τ = 1 s; the curve at τ = 1 s: 0.688 deg/sqrt(h))" in n_entry, n_entry
    assert 2.0 - 1.0 > READOFF_CURVE_RTOL


def test_allan_deviation_accel_in_ug():
    from imupipe.plot import plot_allan_deviation

    fig = plot_allan_deviation(TAU_WR, _white_rw_avar(TAU_WR), sensor="accel")
    ax = fig.axes[0]
    assert "[ug]" in ax.get_ylabel()
    # 1 m/s^2 = 1e6 / 9.80665 ug
    np.testing.assert_allclose(_by_gid(ax, "readoff:N").get_ydata(), [N_WR * 1e6 / 9.80665], rtol=1e-9)


def test_psd_envelope_covers_every_sample_with_two_legend_entries(psd_case):
    f, curves = psd_case
    fig = plot_psd_bound(f, curves, SPEC, BOUND, sensor="gyro", dt=DT, samples="envelope", display_unit="spec")
    ax = fig.axes[0]
    legend = _legend(ax)
    assert legend[:2] == [f"sample PSDs: min-max of {N_CURVES} curves", "sample PSDs: median (smoothed)"]
    assert len(legend) <= 7
    assert "(deg/h)^2/Hz" in ax.get_ylabel()
    (band,) = [c for c in ax.collections if c.get_gid() == "samples:envelope"]
    verts = np.vstack([p.vertices for p in band.get_paths()])
    scale = (math.degrees(1.0) * 3600.0) ** 2
    # the band reaches exactly the highest and lowest sample values (f > 0): no extreme hidden
    np.testing.assert_allclose(verts[:, 1].max(), curves[:, 1:].max() * scale, rtol=1e-12)
    np.testing.assert_allclose(verts[:, 1].min(), curves[:, 1:].min() * scale, rtol=1e-12)
    med = _by_gid(ax, "samples:median").get_ydata()
    assert med.size < f.size  # smoothed in log bins
    assert np.all(med <= verts[:, 1].max()) and np.all(med >= verts[:, 1].min())
    with pytest.raises(ValueError, match="samples"):
        plot_psd_bound(f, curves, SPEC, BOUND, sensor="gyro", samples="blob")


@pytest.mark.parametrize("suffix, magic", [(".svg", b"<svg"), (".pdf", b"%PDF")])
def test_svg_and_pdf_written_on_request(tmp_path, suffix, magic):
    from imupipe.plot import plot_allan_deviation

    path = tmp_path / f"adev{suffix}"
    save_figure(plot_allan_deviation(TAU_WR, _white_rw_avar(TAU_WR), sensor="gyro"), path)
    data = path.read_bytes()
    assert magic in data[:400]


@pytest.mark.parametrize("sensor, unit, factor", [("gyro", "deg/h", math.degrees(1.0) * 3600.0),
                                                  ("accel", "ug", 1e6 / 9.80665)])
def test_allan_components_in_user_units(allan_case, sensor, unit, factor):
    tau, avar, identified = allan_case
    display = "spec" if sensor == "gyro" else "ug"
    fig = plot_allan_components(tau, avar, identified, BOUND, sensor=sensor, display_unit=display)
    ax = fig.axes[0]
    assert ax.get_ylabel() == f"Allan deviation [{unit}]"
    np.testing.assert_allclose(_by_gid(ax, "identified").get_ydata(), np.sqrt(identified.avar(tau)) * factor,
                               rtol=1e-12)
    np.testing.assert_allclose(_by_gid(ax, "sample:2").get_ydata(), np.sqrt(avar[2]) * factor, rtol=1e-12)
