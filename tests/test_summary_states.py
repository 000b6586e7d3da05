"""What the summary says the exported model carries, and the FLAGs of a re-assigned GM and of a parameter on its
boundary (imupipe.summary). An outside evaluation with a simulated truth of white noise + GM (0.1 mg, T 300 s) +
random walk, 3 h at 50 Hz, read "states kept: white, random_walk, flicker" (a flicker the truth lacks, the GM
"dropped") while the KF file exported a GM of T 44.9 s, and a FLAG saying the GM was "bounded as the random walk
it acts as". The numbers below are that run's (identify file and contract)."""

from imupipe.summary import flags_of, summary_sections

G = 9.80665

#: the contract of that run: the exported model (SI) and its spec-sheet units
CONTRACT = {
    "sensor": "accel", "bounded": True, "verified": True, "margin": 1.0,
    "model": {"white": 0.005672, "gauss_markov": [{"sigma": 0.0019875, "T": 44.91}], "random_walk": 1.0042e-4},
    "bound": {"white": 0.005672, "gauss_markov": [{"sigma": 0.0019875, "T": 44.91}], "random_walk": 1.0042e-4},
    "spec": {"white": 0.2 / 60.0, "gauss_markov": [], "random_walk": 0.0},
    "upper_envelope": {"white": 0.0034088, "random_walk": 5.346e-5,
                       "gauss_markov": [{"sigma": 5.93e-4, "T": 198.6}, {"sigma": 7.61e-4, "T": 415.9}]},
    "spec_spec_units": {"white": {"value": 0.2, "unit": "m/s/sqrt(h)"}, "gauss_markov": []},
    "bound_spec_units": {"white": {"value": 0.3403, "unit": "m/s/sqrt(h)"},
                         "gauss_markov": [{"sigma": {"value": 0.2027, "unit": "mg"}, "T": {"value": 44.91, "unit": "s"}}]},
}
MOVED = {"term": 1, "sigma": 0.0010778, "T_s": 387.8, "acts_as": "random_walk", "value": 7.739e-5,
         "why": "its T interval reaches the longest T the records resolve", "T_open_above": True}
IDENTIFY = {"selection": {"kept": ["white", "random_walk", "flicker"], "dropped": ["quantization", "ramp", "gauss_markov"],
                          "reasons": {"white": "kept: white", "random_walk": "kept: a re-assigned GM term acts as it",
                                      "flicker": "kept: shown by the chi-squared test of the refit (not a Kalman-filter "
                                                 "state: represented by a GM in the bound)",
                                      "gauss_markov": "re-assigned: GM term 1 ...; was: kept: significant"}},
            "gm_reassigned": [MOVED]}


def test_the_details_separate_the_identified_components_from_the_exported_states():
    _, details = summary_sections({"accel": {"bound": CONTRACT, "identify": IDENTIFY}})
    assert "- states kept:" not in details
    (comp,) = [ln for ln in details.splitlines() if ln.startswith("- components the identification kept")]
    assert comp.endswith(": white, random_walk, flicker") and "not the filter's states" in comp
    (states,) = [ln for ln in details.splitlines() if ln.startswith("- states of the exported filter model (KF file)")]
    # 0.0019875 m/s^2 / 9.80665e-3 = 0.203 mg; the KF file's GM is there, and no flicker state
    assert "GM sigma 0.203 mg (0.00199 m/s^2), T 44.9 s" in states and "flicker" not in states
    (gm,) = [ln for ln in details.splitlines() if ln.startswith("  - GM: ")]
    assert "the identified flicker" in gm and "the 2 GM term(s) of the identification's upper envelope" in gm
    assert "not the GM the identification re-assigned (T 388 s, reported as the random walk it acts as)" in gm
    (rw,) = [ln for ln in details.splitlines() if ln.startswith("  - random walk: ")]
    assert "a re-assigned GM acts as one" in rw


def test_a_reassigned_gm_flag_says_what_the_kf_file_exports():
    (f,) = [f for f in flags_of("accel", CONTRACT, IDENTIFY) if f.check == "GM re-assigned"]
    assert "bounded as the random walk" not in f.detail
    assert "the identification reports it as the random walk K 7.74e-05 m/s^2/sqrt(s) it acts as" in f.detail
    assert ("the exported filter model (KF file) has random walk K 0.0001 m/s^2/sqrt(s) and a GM of sigma 0.203 mg "
            "(0.00199 m/s^2), T 44.9 s: the bound's own GM term") in f.detail and f.detail.endswith("not this GM")
    # an exported model without a GM says so
    no_gm = {**CONTRACT, "model": {**CONTRACT["model"], "gauss_markov": []}}
    (f,) = [f for f in flags_of("accel", no_gm, IDENTIFY) if f.check == "GM re-assigned"]
    assert f.detail.endswith("and no GM state")


def test_a_parameter_on_its_boundary_names_its_value_unit_and_the_range_searched():
    ident = {"model": {"white": 1e-4, "flicker": 0.0, "gauss_markov": []},
             "fit": {"on_boundary": {"white": False, "flicker": True, "gm_T_1": True, "gm_sigma_1": True},
                     "params": {"gm_T_1": 0.0211, "gm_sigma_1": 0.0, "flicker": 0.0},
                     "T_search_s": [0.0211, 388.0], "intervals": {"gm_T_1": [0.0, 0.05]},
                     "interval_kind": {"gm_T_1": "one-sided (upper end only; T at the lower end of the search)"}}}
    flags = [f for f in flags_of("gyro", identify=ident) if f.check == "parameter on boundary"]
    # a GM sigma fitted as 0 is the GM absent, as a flicker at 0 is: not a fit pressed against its range
    assert [f.where for f in flags] == ["gm_T_1"]
    assert flags[0].detail == ("GM T 0.0211 s sits on the shortest time constant searched (range 0.0211-388 s, "
                               "identify file fit.T_search_s); interval [0 s, 0.05 s], one-sided (upper end only; T "
                               "at the lower end of the search)")
    # a random walk on its boundary: the value in the spec sheet's unit and SI, the range [0, inf)
    ident = {"model": {"random_walk": 2e-6}, "fit": {"on_boundary": {"random_walk": True},
                                                     "params": {"random_walk": 2e-6}}}
    (f,) = [f for f in flags_of("gyro", identify=ident) if f.check == "parameter on boundary"]
    # 2e-6 rad/s/sqrt(s) x 180/pi x 3600 = 0.413 (deg/h)/sqrt(s)
    assert f.detail == ("random walk K 0.413 (deg/h)/sqrt(s) (2e-06 rad/s/sqrt(s)) at a limit of its range [0, inf) "
                        "(a non-negative coefficient)")
