"""Mutation audit of dryfric_jax/plan.py (settings checks, the step h, the predicted work, the method-choice
plumbing) and dryfric_jax/regeneration.py (the split sets C+ / C- of the long-excursion estimator), targeting what
the older audits did not: check_count, check_layout, check_settings, check_method, choose (float32 fallbacks, the
default-delta caveat, auto), plan_estimate's layout and bounds, and split_set's dtype.

111 one-line mutants were tried.
* plan.py, 85 tried: 58 killed by the older tests (one of them, MAX_COUNT = 1 << 63, only by a hang: test_bad_input's
  2^62 + 1-excursion estimate then runs instead of being refused), 6 equivalent, 21 killed only here, 0 alive.
  Equivalent: check_h without ``math.isfinite(v) and`` (inf fails v <= h_max, NaN every comparison); auto passing
  ``h`` instead of ``h_c`` to the DI branch (check_h there again, and check_h is idempotent); the PDMP branch's
  ``if defaulted`` written ``if delta is None`` (auto has set delta to default_delta itself); ``delta`` for
  ``grid["delta"]`` (= float(delta), and delta is already a float there); plan_estimate's first check_layout with
  block 2 for 1 when block is None (lanes <= 2^22, and that block is not used); max_steps' cap floor 32 for 64
  (limits.max_steps_per_excursion floors at 64 itself).
  Killed only here: a bool count where lo = 1; ">" for ">=" in check_count's message; 2^62 (MAX_COUNT 1 << 63,
  check_settings' n_excursions and plan_estimate's max_steps without their upper bound); check_layout's numpy ints
  returned as numpy (lanes or block); a 0-d string array taken for a method; the PDMP float32 fallback decided on
  tau' instead of tau_L'; the default-delta caveat on a user's delta; a float32 note on a float64 run; the default
  block not fitted to the lanes; gamma_bar' made |gamma_bar'| and the PDMP's unit "events" lost in the work
  refusal; check_recurrent not called; chunk_lanes = 0 or max_steps = 0 taken for the default; check_settings
  returning numpy values, an unchecked dtype, rtol or max_work (and a string h a TypeError); the requested method
  missing from Plan.reason.
* regeneration.py, 26 tried: 24 killed by the older tests, 1 equivalent (``c = x_threshold`` for
  ``jnp.asarray(x_threshold, dt)``: c -+ w takes w's dtype, the step's, from a Python float threshold, the only
  kind di.py passes), 1 killed only here (``dt = jnp.float64``: a float64 set around a float32 step), 0 alive.

No defect was found.

Oracles, all independent of the code under test: the documented ranges and messages (plan's and limits'
docstrings: counts in [lo, 2^62], lanes * K <= 2^28, tau_L' < 1e-25 and h/tau < 1e-4 for the float32 fallbacks,
the 4.2 SD caveat of cost.default_delta_note), hand arithmetic (K = 2^28 / 2^22 = 64, depth (1 + 0) sqrt(25) = 5 SD,
default delta' = min(0.05, (1/16)/5, delta_max'/2) = 0.0125, gamma_bar' = -0.342/3.84 = -0.0891), and for the split
set a = L^-1 m by a numpy solve with w = min(1/|a|, 4/sqrt(tau)) (regeneration docstring).

Older tests run against every mutant: test_plan_audit, test_bad_input, test_api_rest_mutants, test_params,
test_api_audit, test_plumbing_audit, test_combine_limits_mutants, test_helpers_mutants (plan.py; DTYPES also
test_regeneration and test_di_step); test_internals_audit, test_regeneration, test_helpers_mutants
(regeneration.py).  test_stopping_rule (65 s, statistical) was not run: the two regeneration survivors do not
touch the float64 sets the engine uses.
"""
import math
import re

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.plan import MAX_COUNT, check_count, check_layout, check_method, check_settings, plan_estimate

FIG3 = dj.Params(**dj.FIG3)  # gamma_bar' = 0.342/3.84 = 0.0890625


def test_a_count_is_an_integer_not_a_bool_and_the_message_says_at_least():
    """check_count docstring: an integer >= lo.  Kills: ``isinstance(n, bool) or`` dropped (True taken as
    1 where lo = 1: chunk_lanes, max_steps), and the message's ``>= {lo}`` written ``> {lo}`` (and, by the
    range in the max_steps message, max_steps without ``hi=MAX_STEPS``)."""
    for bad in (True, np.True_):
        with pytest.raises(ValueError, match=r"^chunk_lanes must be an integer >= 1 \(got "):
            check_count("chunk_lanes", bad, 1)
        with pytest.raises(ValueError, match=r"^max_steps must be an integer in \[1, 2\^62\]"):
            plan_estimate(FIG3, n_excursions=2, max_steps=bad)
    with pytest.raises(ValueError, match=r"^n must be an integer >= 2 \(got 1\)$"):
        check_count("n", 1)
    assert check_count("chunk_lanes", 1, 1) == 1


def test_counts_end_at_2_62_in_the_settings_and_the_excursion_bound():
    """plan: the engine's counters are int64, counts at most 2^62 (both ends included).  Kills:
    MAX_COUNT = 1 << 63; check_settings' n_excursions without ``hi=MAX_COUNT`` (a sweep's settings took
    2^62 + 1); plan_estimate's max_steps without ``hi=MAX_STEPS``."""
    assert MAX_COUNT == 2**62
    assert check_settings(n_excursions=2**62)["n_excursions"] == 2**62
    with pytest.raises(ValueError, match=r"^n_excursions must be an integer in \[2, 2\^62\] \(got 4611686018427387905"):
        check_settings(n_excursions=2**62 + 1)
    assert plan_estimate(FIG3, n_excursions=2, max_steps=2**62).max_steps == 2**62
    with pytest.raises(ValueError, match=r"^max_steps must be an integer in \[1, 2\^62\]"):
        plan_estimate(FIG3, n_excursions=2, max_steps=2**62 + 1)


def test_layout_comes_back_as_python_ints():
    """check_layout docstring: 'Returns them as ints' (numpy integers in, Python ints out).  Kills
    ``return ..., block`` and ``return ... else lanes, ...`` (a numpy block or lanes returned as it came)."""
    lanes, block = check_layout(np.int64(4), np.int32(16))
    assert (lanes, block) == (4, 16) and type(lanes) is int and type(block) is int
    lanes, block = check_layout(None, np.array(8))
    assert lanes is None and type(block) is int and block == 8


@pytest.mark.parametrize("bad", [np.array("di"), np.array("auto")])
def test_method_must_be_a_string(bad):
    """check_method: method is one of the strings "di", "pdmp", "auto".  A 0-d string array compares
    equal to "di" (``in METHODS`` is true); kills ``not isinstance(method, str) or`` dropped."""
    with pytest.raises(ValueError, match=r"^method must be one of \['di', 'pdmp', 'auto'\]"):
        check_method(bad)
    with pytest.raises(ValueError, match=r"^method must be one of"):
        plan_estimate(FIG3, method=bad, n_excursions=2)


def test_pdmp_float32_fallback_is_decided_by_tau_L():
    """plan docstring step 3 and limits.pdmp_float32_unsafe_reason: the PDMP falls back to float64 for
    tau_L' < 1e-25 (here tau_L' = 1e-30, tau' = 1.47 far above any bound).  Kills the check made on
    ``params.tau_nd`` instead of ``params.tau_L_nd``."""
    p = dj.Params.from_nondim(1.47, 1e-30, 0.089)
    plan = plan_estimate(p, method="pdmp", dtype="float32", n_excursions=100, max_work=1e300)
    assert plan.dtype == "float64" and len(plan.notes) == 1
    assert plan.notes[0].startswith("float32 is not safe here (tau_L/tau0 = 1e-30 < 1e-25")
    assert plan_estimate(FIG3, method="pdmp", dtype="float32", n_excursions=100).dtype == "float32"


def test_default_delta_caveat_only_on_the_default_delta():
    """cost.default_delta_note: the caveat is for a run on the *default* delta with a stick threshold
    deeper than 4.2 SD.  At tau' = 25, gamma_bar' = 0 the depth is (1 + 0) sqrt(25) = 5 SD; the default
    delta' = min(0.05, (1/16)/5, delta_max'/2) = 0.0125 (delta_max' = (-40 + sqrt(1600 + 400))/100 = 0.047,
    noise docstring, a = tau' max(8/sqrt(tau'), 1) = 40; Gamma = Delta = 1: physical = nondimensional).  The
    same delta given by the user carries no note.  Kills ``if defaulted and`` dropped."""
    p = dj.Params.from_nondim(25.0)
    a = 25.0 * max(8.0 / 5.0, 1.0)
    assert 0.5 * (-a + math.sqrt(a * a + 16 * 25.0)) / (4 * 25.0) > 0.0125
    default = plan_estimate(p, method="pdmp", n_excursions=100, max_work=1e300)
    assert default.delta == pytest.approx(0.0125, rel=1e-15)
    assert len(default.notes) == 1 and "here one lies 5 SD out" in default.notes[0]
    assert plan_estimate(p, method="pdmp", delta=0.0125, n_excursions=100, max_work=1e300).notes == []


def test_float64_run_gets_no_float32_note():
    """plan docstring step 3: the fallback note is for a float32 request only.  At tau = 1e3 s, h = 1e-8 s
    (h/tau = 1e-11 < 1e-4) a float64 run has no note, a float32 one falls back.  Kills
    ``if dtype == "float32" and unsafe`` written ``if unsafe``."""
    p = dj.Params(1.0, 1.0, 1e3, math.inf, 0.0)
    plan = plan_estimate(p, h=1e-8, n_excursions=100, max_work=1e300)
    assert (plan.dtype, plan.notes) == ("float64", [])
    plan = plan_estimate(p, h=1e-8, dtype="float32", n_excursions=100, max_work=1e300)
    assert plan.dtype == "float64" and "h/tau = 1e-11" in plan.notes[0]


def test_default_block_is_fitted_to_the_lanes():
    """excursions.default_block: K is halved while lanes * K > 2^28.  With 2^22 lanes (chunk_lanes) the
    default K is 2^28 / 2^22 = 64 on any backend (128 or 256 halved), and the plan is accepted.  Kills
    ``default_block(plan.method)`` without the lanes (K = 128 then refused as lanes * block > 2^28)."""
    for method in ("di", "pdmp"):
        plan = plan_estimate(FIG3, method=method, n_excursions=2**40, chunk_lanes=2**22, max_work=1e300)
        assert (plan.lanes, plan.block) == (2**22, 64)


def test_work_refusal_names_the_signed_bias_and_the_unit():
    """limits.check_work's message: gamma_bar' as given (-0.342/3.84 = -0.0890625 -> "-0.0891") and the
    unit, "steps" for the DI and "events" for the PDMP.  Kills ``abs(params.gamma_bar_nd)`` in plan's ``nd``
    (every other use of gamma_bar' in the work bound is symmetric) and ``check_work`` called without
    ``plan.unit`` (its default "steps")."""
    p = dj.Params(5.0, 3.84, 0.5, 0.067, -0.342)
    for method, unit in (("di", "steps"), ("pdmp", "events")):
        with pytest.raises(ValueError, match=r"^max_work must be >= \S+ " + unit + " for these parameters") as e:
            plan_estimate(p, method=method, n_excursions=10**9, max_work=1e3)
        assert "gamma_bar' = -0.0891)" in str(e.value)
        assert re.search(r"tau0 at \S+ " + unit + " per tau0", str(e.value))


def test_a_runaway_model_is_refused_by_gamma_bar():
    """plan docstring step 1, limits.check_recurrent: tau_L = inf with |gamma_bar| >= Delta has no
    stationary state and is refused by gamma_bar (the bound included), whatever max_work allows.  Kills
    the ``check_recurrent`` call dropped from ``choose``."""
    for g in (1.0, -1.5):
        with pytest.raises(ValueError, match=r"^gamma_bar must satisfy \|gamma_bar\| < Delta when tau_L = inf"):
            plan_estimate(dj.Params.from_nondim(1.0, math.inf, g), n_excursions=10, max_work=1e300)
    plan_estimate(dj.Params.from_nondim(1.0, math.inf, 0.5), n_excursions=10, max_work=1e300)


def test_split_set_of_a_float32_step_is_float32():
    """regeneration.split_set builds C in the dtype of the step (``dt = ou.m1.dtype``): for a float32 OU step every
    field is float32, and c1, c2 are the float32 values of x_threshold -+ w, w = min(1/|a|, 4/sqrt(tau)) with
    a = L^-1 m (numpy solve in float64 of the step's own constants; w |a| = 1 here, so float32 rounding of a few
    ulps is all that separates them).  Kills ``dt = jnp.float64`` (a float64 set around a float32 step)."""
    import jax.numpy as jnp

    from dryfric_jax.ou import ou_step
    from dryfric_jax.regeneration import split_set

    ou = ou_step(1e-2, 1.0, "float32")
    s = split_set(ou, 0.3, 1.0)
    for f in ("c1", "c2", "a1", "a2", "a_sq", "half_d"):
        assert getattr(s, f).dtype == jnp.float32, f
    assert s.epsilon.dtype == jnp.float32
    m = np.array([float(ou.m1), float(ou.m2)])
    L = np.array([[float(ou.L11), 0.0], [float(ou.L21), float(ou.L22)]])
    w = min(1 / np.linalg.norm(np.linalg.solve(L, m)), 4.0)
    assert float(s.c1) == pytest.approx(0.3 - w, rel=1e-6) and float(s.c2) == pytest.approx(0.3 + w, rel=1e-6)


def test_zero_chunk_lanes_and_zero_max_steps_are_refused_not_defaulted():
    """plan_estimate: chunk_lanes and max_steps are integers >= 1 (None: the default); 0 and False are refused
    by name, not taken for None.  Kills ``if chunk_lanes:`` and ``if not max_steps:`` for the ``is None``
    tests (0 fell through to lanes_for's and max_steps_per_excursion's defaults)."""
    for bad in (0, False, np.int64(0)):
        with pytest.raises(ValueError, match=r"^chunk_lanes must be an integer >= 1 \(got "):
            plan_estimate(FIG3, n_excursions=100, chunk_lanes=bad)
        with pytest.raises(ValueError, match=r"^max_steps must be an integer in \[1, 2\^62\] \(got "):
            plan_estimate(FIG3, n_excursions=100, max_steps=bad)


def test_check_settings_checks_every_setting_and_returns_plain_values():
    """check_settings docstring: the settings 'as plain values', ``ValueError`` naming the first one that is
    wrong.  Kills, in check_settings: ``x = v`` for ``real(v)`` (a numpy h kept as numpy, a string h a
    TypeError from math.isfinite), ``dtype=dtype`` for ``dtype_name(dtype)``, ``rtol=rtol`` and
    ``max_work=max_work`` unchecked."""
    s = check_settings(method="auto", h=np.float32(0.5), delta=np.array(0.25), dtype=np.float32, rtol=np.float64(0.1),
                       max_work=np.int64(5000))
    assert (s["h"], s["delta"], s["dtype"], s["rtol"], s["max_work"]) == (0.5, 0.25, "float32", 0.1, 5000.0)
    for k in ("h", "delta", "rtol", "max_work"):
        assert type(s[k]) is float, k
    for kw, name in ((dict(h="1e-3"), "h must be in"), (dict(delta="0.05", method="pdmp"), "delta must be in"),
                     (dict(dtype="float16"), "dtype must be one of"), (dict(dtype=np.float16), "dtype must be one of"),
                     (dict(rtol=2.0), r"rtol must be in \(0, 1\)"), (dict(rtol=0.0), r"rtol must be in \(0, 1\)"),
                     (dict(max_work=999.0), "max_work must be a finite number >= 1e3"),
                     (dict(max_work=math.inf), "max_work must be a finite number >= 1e3")):
        with pytest.raises(ValueError, match="^" + name):
            check_settings(**kw)


def test_the_reason_for_a_requested_method_names_it():
    """Plan.reason is 'why this method' (reported as ``method_reason``, README): for an explicit method it was
    requested, and the reason says which; for ``auto`` it is the cost comparison, which ends with the pick.
    Kills the reason written without the method (``reason = "requested"``)."""
    for method in ("di", "pdmp"):
        why = plan_estimate(FIG3, method=method, n_excursions=100).reason
        assert f"'{method}'" in why and "requested" in why
    assert plan_estimate(FIG3, method="auto", n_excursions=100).reason.endswith("chose pdmp")
