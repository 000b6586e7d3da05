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
    # three short sentences (an outside evaluation: one of 120 words, no action): what, where it went, what to do
    assert f.detail.startswith("the identified GM (sigma 0.11 mg (0.00108 m/s^2), T 388 s) is not resolved by the "
                               "records (")
    assert "Reported as the random walk K 7.74e-05 m/s^2/sqrt(s) it acts as" in f.detail
    assert ("In the KF file: the exported filter model (KF file) has random walk K 0.0001 m/s^2/sqrt(s) and a GM of "
            "sigma 0.203 mg (0.00199 m/s^2), T 44.9 s: the bound's own GM term") in f.detail
    assert "not this GM. To resolve it: longer records" in f.detail
    # an exported model without a GM says so
    no_gm = {**CONTRACT, "model": {**CONTRACT["model"], "gauss_markov": []}}
    (f,) = [f for f in flags_of("accel", no_gm, IDENTIFY) if f.check == "GM re-assigned"]
    assert "and no GM state. To resolve it" in f.detail


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


def test_a_dropped_components_parameter_on_its_boundary_is_not_flagged():
    # the selection dropped the GM: its T on the search's end is no parameter of the model (outside evaluation:
    # a FLAG on gm_T_1 beside "gauss_markov (dropped)")
    ident = {"model": {"white": 1e-4}, "selection": {"kept": ["white", "random_walk"]},
             "fit": {"on_boundary": {"gm_T_1": True, "random_walk": True},
                     "params": {"gm_T_1": 388.0, "random_walk": 2e-6}, "T_search_s": [0.02, 388.0]}}
    flags = [f.where for f in flags_of("gyro", identify=ident) if f.check == "parameter on boundary"]
    assert flags == ["random_walk"]
    ident["selection"]["kept"].append("gauss_markov")
    flags = [f.where for f in flags_of("gyro", identify=ident) if f.check == "parameter on boundary"]
    assert sorted(flags) == ["gm_T_1", "random_walk"]


def test_a_reassigned_random_walk_says_it_holds_for_taus_below_T():
    from imupipe.summary import reassigned_text

    r = {"sigma": 1e-5, "T_s": 232.0, "why": "T interval open", "acts_as": "random_walk", "value": 9.3e-7}
    text = reassigned_text("gyro", r)
    # sigma sqrt(2/T) is the random walk a GM acts as only for tau << T (its Allan variance rises as K^2 tau / 3
    # there and falls as 2 sigma^2 T / tau beyond T)
    assert "at taus well below T" in text
    r = {**r, "acts_as": "white", "value": 2e-4}
    assert "at taus well below T" not in reassigned_text("gyro", r)


def test_a_gm_reassigned_as_white_noise_names_its_t_interval_not_the_filter_rate():
    # an outside evaluation: a GM of T 56 s in 20 Hz records, its T interval down to 0.027 s, read "to resolve it: a
    # higher sample rate (at the filter's rate it is white noise)" under a 1 Hz filter, for which a 56 s GM is not
    # white: what narrows the interval is more data
    from imupipe.summary import reassigned_text

    r = {"sigma": 2e-5, "T_s": 56.1, "T_interval_s": [0.027, 640.0], "T_resolved_s": [0.027, 9000.0],
         "acts_as": "white", "value": 2e-4,
         "why": "its T interval's lower end (0.027 s) below twice the shortest T the records resolve (0.027 s)"}
    text, short = reassigned_text("gyro", r), reassigned_text("gyro", r, short=True)
    assert "white noise)." not in text and "a higher sample rate" not in text
    assert "To resolve it: more or longer records, which narrow its T interval (now down to 0.027 s)" in text
    assert short.endswith("to resolve it: more or longer records (its T interval reaches down to 0.027 s)")
    # the real ADIS16405 gyro's GM, T 0.0106 s at the shortest T its 100 Hz records resolve: a higher sample rate
    adis = {**r, "T_s": 0.0106, "T_interval_s": [0.0, 345.0], "T_resolved_s": [0.0106, 345.0]}
    assert reassigned_text("gyro", adis, short=True).endswith("to resolve it: a higher sample rate")
    assert "To resolve it: a higher sample rate (its T lies near the shortest" in reassigned_text("gyro", adis)


def test_the_tolerance_pass_says_when_its_worst_ratio_is_in_the_fixes():
    from imupipe.verdict import within_tolerance

    check = {"passed": True, "worst_ratio": 1.6, "tolerance": 0.9, "method": "replay of the records",
             "worst_t_s": 421.0, "worst_outage_ratio": 0.78, "worst_outage_t_s": 2000.0}
    text = within_tolerance(check)
    assert "ratio 1.6 at 421 s, in the fixes; the outage's worst 0.78" in text
    # the worst in the outage: no phase note; a ratio just above 1 is printed with the digits that show it
    text = within_tolerance({**check, "worst_ratio": 1.0004, "worst_t_s": 2000.0, "worst_outage_ratio": 1.0004})
    assert "ratio 1.0004 at 2000 s," in text and "in the fixes" not in text


def test_the_unit_slip_flag_names_a_kept_burst_as_another_cause():
    from imupipe.summary import above_spec_flags

    bound = {"spec": {"white": 1e-4}, "bound": {"white": 8e-4}, "upper_envelope": {"white": 8e-4},
             "curves": ["ev/x"]}
    (f,) = above_spec_flags("accel", bound)
    assert "check the unit of accel" in f.detail and "a burst (a knock) kept in the data raises N" in f.detail
