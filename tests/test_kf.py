"""Tests of imupipe.kf: state-space structure (paper eqs. 17, 19), Van Loan against closed forms."""

import math

import numpy as np
import pytest

from imupipe.kf import continuous_model, discretize, export_kf, initial_covariance
from imupipe.models import NoiseModel

# STIM-300-like accelerometer (paper Table 2, inflated column, in SI): N from 0.0425 m/s/sqrt(h)
N_ACC = 0.0425 / 60.0
SIGMA_ACC = 0.165e-3 * 9.80665
T_ACC = 120.0
K_ACC = 3.625e-6 * 9.80665  # (g)/sqrt(s) read as the paper's units discussion (docs/method.md, section "Slip: units of K")


@pytest.fixture
def accel():
    return NoiseModel(white=N_ACC, gauss_markov=((SIGMA_ACC, T_ACC),), random_walk=K_ACC)


class TestContinuousModel:
    def test_eq17_structure(self, accel):
        cm = continuous_model(accel, q_m=9.81)
        assert cm.states == ["x", "v", "b", "p", "s_f"]
        expected_F = np.array(
            [
                [0, 1, 0, 0, 0],
                [0, 0, -1, -1, -9.81],
                [0, 0, -1 / T_ACC, 0, 0],
                [0, 0, 0, 0, 0],
                [0, 0, 0, 0, 0],
            ]
        )
        np.testing.assert_array_equal(cm.F, expected_F)
        assert cm.noises == ["nu_s", "nu_b", "nu_p"]
        np.testing.assert_array_equal(cm.G[:, 0], [0, -1, 0, 0, 0])
        np.testing.assert_array_equal(cm.G[:, 1], [0, 0, 1, 0, 0])
        np.testing.assert_array_equal(cm.G[:, 2], [0, 0, 0, 1, 0])
        np.testing.assert_allclose(np.diag(cm.Qc), [N_ACC**2, 2 * SIGMA_ACC**2 / T_ACC, K_ACC**2], rtol=1e-15)
        # the scale factor has no noise
        assert not np.any(cm.G[cm.states.index("s_f")])

    def test_eq19_reduced(self):
        m = NoiseModel(white=N_ACC, gauss_markov=((SIGMA_ACC, T_ACC),))
        cm = continuous_model(m)  # no random walk: reduced by default
        assert cm.states == ["x", "v", "b", "s_f"]
        assert cm.noises == ["nu_s", "nu_b"]

    def test_reduced_with_random_walk_warns(self, accel):
        with pytest.warns(UserWarning, match="random walk"):
            cm = continuous_model(accel, reduced=True)
        assert "p" not in cm.states

    def test_gyro_and_two_gm(self):
        m = NoiseModel(white=1e-4, gauss_markov=((1e-5, 1000.0), (2e-5, 10.0)), random_walk=1e-7)
        cm = continuous_model(m, sensor="gyro", scale_factor=False)
        assert cm.states == ["theta", "b_1", "b_2", "p"]
        # GM states sorted by increasing T
        assert cm.F[1, 1] == -1 / 10.0 and cm.F[2, 2] == -1 / 1000.0


class TestDiscretize:
    @pytest.mark.parametrize("dt", [0.01, 0.1, 1.0, 7.3])
    def test_gm_closed_form(self, dt):
        sigma, T = 2.5e-3, 300.0
        F = np.array([[-1 / T]])
        Phi, Qd = discretize(F, np.eye(1), np.array([[2 * sigma**2 / T]]), dt)
        assert Phi[0, 0] == pytest.approx(math.exp(-dt / T), rel=1e-12)
        assert Qd[0, 0] == pytest.approx(sigma**2 * (1 - math.exp(-2 * dt / T)), rel=1e-12)

    @pytest.mark.parametrize("dt", [0.01, 0.5, 2.0])
    def test_random_walk_is_K_sqrt_dt_not_K_dt(self, dt):
        K = 3.4e-6
        Phi, Qd = discretize(np.zeros((1, 1)), None, np.array([[K**2]]), dt)
        assert Phi[0, 0] == 1.0
        assert Qd[0, 0] == pytest.approx(K**2 * dt, rel=1e-12)
        # the paper's sigma_p = K*dt is a different number except at dt = 1 s
        assert math.sqrt(Qd[0, 0]) == pytest.approx(K * math.sqrt(dt), rel=1e-12)
        assert not math.isclose(math.sqrt(Qd[0, 0]), K * dt, rel_tol=1e-3)

    @pytest.mark.parametrize("dt", [0.004, 0.1, 1.0])
    def test_velocity_random_walk_block(self, dt):
        # x' = v, v' = -nu_s: Qd = N^2 [[dt^3/3, -dt^2/2 * (-1)...]] with the sign of G squared away
        N = 7e-4
        cm = continuous_model(NoiseModel(white=N), scale_factor=False)
        Phi, Qd = discretize(cm.F, cm.G, cm.Qc, dt)
        np.testing.assert_allclose(Phi, [[1, dt], [0, 1]], rtol=1e-12, atol=0)
        np.testing.assert_allclose(
            Qd, N**2 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]]), rtol=1e-12, atol=0
        )

    def test_white_measurement_noise_per_step(self):
        d = export_kf(NoiseModel(white=2e-3), dt=0.01)
        assert d["discrete_noise"]["white_std_per_step"] == pytest.approx(2e-3 / math.sqrt(0.01), rel=1e-15)
        assert d["discrete_noise"]["step_s"] == 0.01 and "not per IMU sample" in d["discrete_noise"]["note"]

    def test_full_model_blocks(self, accel):
        dt = 0.2
        cm = continuous_model(accel)
        Phi, Qd = discretize(cm.F, cm.G, cm.Qc, dt)
        ib, ip = cm.states.index("b"), cm.states.index("p")
        assert Phi[ib, ib] == pytest.approx(math.exp(-dt / T_ACC), rel=1e-12)
        assert Qd[ib, ib] == pytest.approx(SIGMA_ACC**2 * -math.expm1(-2 * dt / T_ACC), rel=1e-12)
        assert Qd[ip, ip] == pytest.approx(K_ACC**2 * dt, rel=1e-12)
        assert Qd[ib, ip] == 0.0
        np.testing.assert_allclose(Qd, Qd.T, rtol=0, atol=0)
        assert np.all(np.linalg.eigvalsh(Qd) > -1e-30)

    def test_bad_inputs(self):
        with pytest.raises(ValueError, match="dt"):
            discretize(np.zeros((1, 1)), None, np.eye(1), 0.0)
        with pytest.raises(ValueError, match="shapes"):
            discretize(np.zeros((2, 2)), np.ones((2, 1)), np.eye(2), 1.0)


class TestInitialCovariance:
    def test_gm_steady_state_and_explicit_rw(self, accel):
        cm = continuous_model(accel)
        with pytest.raises(ValueError, match="p0_random_walk"):
            initial_covariance(accel, cm.states)
        P0 = initial_covariance(accel, cm.states, p0_random_walk=1e-8, var_scale_factor=1e-8)
        np.testing.assert_allclose(np.diag(P0), [0, 0, SIGMA_ACC**2, 1e-8, 1e-8], rtol=1e-15)

    def test_gm_stays_stationary(self, accel):
        # P0 of the GM state is a fixed point of the discrete propagation: Phi P Phi' + Qd = P
        cm = continuous_model(NoiseModel(gauss_markov=((SIGMA_ACC, T_ACC),)), scale_factor=False)
        Phi, Qd = discretize(cm.F, cm.G, cm.Qc, 0.5)
        P0 = initial_covariance(NoiseModel(gauss_markov=((SIGMA_ACC, T_ACC),)), cm.states)
        ib = cm.states.index("b")
        P1 = Phi @ P0 @ Phi.T + Qd
        assert P1[ib, ib] == pytest.approx(SIGMA_ACC**2, rel=1e-12)


class TestExport:
    def test_export_is_plain_and_consistent(self, accel):
        import yaml

        d = export_kf(accel, dt=0.01, q_m=9.81, p0_random_walk=(1e-3) ** 2)
        text = yaml.safe_dump(d)  # plain Python types only
        back = yaml.safe_load(text)
        assert back["states"] == ["x", "v", "b", "p", "s_f"]
        assert back["equation"].endswith("eq. 17")
        assert back["discrete_noise"]["random_walk_driving_std"] == pytest.approx(K_ACC * 0.1, rel=1e-12)
        assert back["discrete_noise"]["gauss_markov"][0]["phi"] == pytest.approx(math.exp(-0.01 / T_ACC))
        assert back["state_units"] == ["m", "m/s", "m/s^2", "m/s^2", "1"]



def test_discretize_stiff_gm_matches_the_closed_form():
    # a GM with T = 0.01 s at dt = 1 s: Phi = e^-100, Qd = sigma^2 (1 - e^-200) = sigma^2; the plain Van Loan
    # block holds e^(+100) and loses Qd to cancellation
    import math

    from imupipe.kf import discretize

    sigma, T = 3e-3, 0.01
    Phi, Qd = discretize(np.array([[-1 / T]]), None, np.array([[2 * sigma**2 / T]]), 1.0)
    assert Phi[0, 0] == pytest.approx(math.exp(-100.0), rel=1e-6, abs=1e-300)
    assert Qd[0, 0] == pytest.approx(sigma**2, rel=1e-9)


class TestNarrowband:
    """Two states per narrowband term (damped oscillator), exact Phi/Qd, steady-state P0."""

    LINE = (3e-3, 0.56, 0.02)  # sigma u, f0 Hz, zeta

    @pytest.mark.parametrize("dt", [0.01, 1.0])
    def test_blocks_match_the_simulators_exact_discretisation(self, dt):
        from imupipe.simulate import narrowband_discrete

        m = NoiseModel(white=1e-3, gauss_markov=((1e-4, 50.0),), narrowband=(self.LINE,))
        cm = continuous_model(m, sensor="accel", scale_factor=False)
        assert cm.states == ["x", "v", "b", "nb", "nb_dot"] and cm.noises == ["nu_s", "nu_b", "nu_nb"]
        i, j = cm.states.index("nb"), cm.states.index("nb_dot")
        w0 = 2 * math.pi * self.LINE[1]
        np.testing.assert_array_equal(cm.F[np.ix_([i, j], [i, j])], [[0, 1], [-w0**2, -2 * self.LINE[2] * w0]])
        assert cm.F[cm.states.index("v"), i] == -1.0  # the line is a rate error integrated into v
        assert cm.Qc[2, 2] == pytest.approx(4 * self.LINE[2] * w0**3 * self.LINE[0] ** 2, rel=1e-15)
        Phi, Qd = discretize(cm.F, cm.G, cm.Qc, dt)
        phi2, Qd2, P02 = narrowband_discrete(*self.LINE, dt)
        # the oscillator block is autonomous: its Phi and Qd blocks are the 2-state model's. Both are Van Loan
        # exponentials (one scaled and squared): agreement to rounding, 1e-9 relative of the block's largest entry
        np.testing.assert_allclose(Phi[np.ix_([i, j], [i, j])], phi2, rtol=0, atol=1e-9 * np.abs(phi2).max())
        np.testing.assert_allclose(Qd[np.ix_([i, j], [i, j])], Qd2, rtol=0, atol=1e-9 * np.abs(Qd2).max())
        P0 = initial_covariance(m, cm.states)
        np.testing.assert_array_equal(P0[np.ix_([i, j], [i, j])], P02)
        # steady state: one step of the exact recursion leaves P0 unchanged (F P + P F^T + G Qc G^T = 0)
        blk = np.ix_([i, j], [i, j])
        np.testing.assert_allclose(phi2 @ P0[blk] @ phi2.T + Qd2, P0[blk], rtol=0, atol=1e-9 * P0[blk].max())

    def test_export_units_and_parameters(self):
        m = NoiseModel(white=1e-3, narrowband=(self.LINE, (1e-3, 7.0, 0.05)))
        e = export_kf(m, 0.01, sensor="gyro")
        assert e["states"] == ["theta", "nb_1", "nb_1_dot", "nb_2", "nb_2_dot", "s_f"]
        assert e["state_units"][1:3] == ["rad/s", "rad/s/s"]  # nb in the rate unit, nb_dot per second
        assert e["noise_units"][1] == "(rad/s)^2/s^3"
        assert e["parameters"]["narrowband"][0] == {"sigma": 3e-3, "f0_hz": 0.56, "zeta": 0.02}
        assert np.allclose(np.diag(e["P0"])[3:5], [1e-6, (2 * math.pi * 7.0) ** 2 * 1e-6])


def test_zero_narrowband_terms_have_no_state():
    m = NoiseModel(white=1e-3, narrowband=((0.0, 0.46, 0.01), (2e-3, 0.56, 0.01)))
    cm = continuous_model(m, scale_factor=False)
    assert cm.states == ["x", "v", "nb"] + ["nb_dot"] and cm.noises == ["nu_s", "nu_nb"]
    P0 = initial_covariance(m, cm.states)
    assert P0[2, 2] == 4e-6


@pytest.mark.parametrize("narrowband", [
    [{"sigma": 2e-3, "f0_hz": 0.5, "zeta": 0.01}, {"sigma": 0.0, "f0_hz": 3.0, "zeta": 0.02}],
    [[2e-3, 0.5, 0.01], [0.0, 3.0, 0.02]],  # the same terms as (sigma, f0_hz, zeta) lists
])
def test_export_scope_line_states_read_either_form(narrowband):
    """Line states: the narrowband terms of the exported model with sigma > 0, in either YAML form."""
    from imupipe.kf import export_scope

    exported = {"reduced": False, "model": {"white": 1e-4, "narrowband": narrowband},
                "verification": {"scenario": {"rate_hz": 1.0, "fix_s": 600.0, "horizon_s": 600.0}}}
    scope = export_scope(exported, None, 1.0)
    assert scope["line_states"] == [{"sigma": 2e-3, "f0_hz": 0.5, "zeta": 0.01}]
    assert scope["dropped_by_reduction"] == [] and scope["rate_mismatch"] is False


def test_the_kf_files_kinematic_p0_is_the_verified_one():
    # an outside evaluation took the KF file's P0 literally: its kinematic entries were 0 while the verification had
    # started the reference filter (and the truth) at the fix variance and 1 (m/s)^2; with a true initial error of
    # that size its filter under-stated the error 1.66x in the outage. The KF file now starts them where the
    # verification did (the verify file's scenario), and says so in its notes
    from imupipe.stages.kf import exported_kf
    from imupipe.verify import kinematic_start, reference_scenario

    model = NoiseModel(white=1e-3, gauss_markov=((1e-4, 100.0),), random_walk=1e-6)
    for sensor in ("accel", "gyro"):
        sc = reference_scenario(sensor)
        start = kinematic_start(sc)
        assert start["var_pos"] == pytest.approx(sc.sigma_fix**2)
        exported = {"model": model.to_dict(), "verification": {"scenario": {"sigma_fix": sc.sigma_fix, **start}},
                    "bias_initialisation": {"p0_random_walk": 1e-8}}
        kf = exported_kf(exported, 1.0, sensor)
        P0, states = np.asarray(kf["P0"]), kf["states"]
        kin = {"x": start["var_pos"], "v": start.get("var_vel"), "theta": start["var_pos"]}
        for i, s in enumerate(states):
            if s in kin:
                assert P0[i, i] == pytest.approx(kin[s])
        assert any("kinematic states" in n for n in kf["notes"])
    # a verify file written before the scenario carried them: the scenario's defaults from its fix sigma
    old = {"model": model.to_dict(), "verification": {"scenario": {"sigma_fix": 0.5}},
           "bias_initialisation": {"p0_random_walk": 1e-8}}
    P0 = np.asarray(exported_kf(old, 1.0, "accel")["P0"])
    assert P0[0, 0] == pytest.approx(0.25) and P0[1, 1] == pytest.approx(1.0)
