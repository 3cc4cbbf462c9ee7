r"""Mutation audit of :mod:`dryfric_jax.combine` (pooling runs' sums) and :mod:`dryfric_jax.limits` (validity
ranges, predicted work, work bounds, float32 policy): what tests/test_combine.py, test_estimators_mutants.py,
test_internals_audit.py, test_bad_input.py, test_sweep.py, test_plan_audit.py and test_stress.py left open.

Expected values come from independent oracles, never from the code under test:

* combine: the field ranges its module writes out (``_FIELDS``: ``[0, 1]``, ``(0, 1)``, ``> 0``, ``>= 0``,
  seeds in ``[0, 2^62]``, n a whole number in ``[1, 2^62]``); the ratio estimators' invariance under scaling
  every sum by one power of two (M0 = sum U / sum t and D = (U2 - 2 M0 Ut + M0^2 t2) / t are homogeneous of
  degree 0, and a power of two scales exactly); a pool whose excursions all have U = 2t exactly (D = 0, M0 = 2
  by hand); the pooling rules of ``combine_estimates``'s docstring (rate = sum rate_i wall_i / sum wall_i,
  utilisation = useful / slots) worked by hand;
* limits: the closed form :math:`T(1 \to -1) = \tau\pi\,\mathrm{erfi}(\sqrt{\tau/2})` of the symmetric OU
  passage (the erfcx integral over a symmetric range is :math:`\int_0^s 2e^{u^2}du = \sqrt\pi\,\mathrm{erfi}(s)`),
  the module's docstrings (``_exp10``'s examples, ``max_steps = ceil(1e4 x tail x steps)``, at least 64, at
  most ``cap``; the tail scale at least 1; the accepted prediction at most ``max_work``) and hand arithmetic.

Mutant ids: K.. edit combine.py, L.. edit limits.py; each test's docstring names those it kills.
116 mutants were tried (60 of combine.py, 56 of limits.py).  The targeted existing tests (those above; the 2-process
test of test_combine.py left out) killed 64 (30 and 34); 11 are equivalent; of the 41 other survivors these tests
kill 40.  The equivalent ones:

* K50 (gather_hosts pads the seed rows with -1 for -2), K51 (a one-seed host's combined_from kept): the padding is
  never read (each row's own length is sent), and combine takes a run's seeds from combined_from or [seed] alike;
* L06 (quad limit 50 for 200): erfcx is smooth, quad needs at most 26 subintervals on lo in [-6, 50], widths to 1e6;
* L07 (b >= a for b > a): at a = b the reflected pair is again equal, T = 0 either way;
* L11 (thresholds 1 + g, -1 + g): X -> -X maps T(1 - g -> -1 - g) to T(-1 + g -> 1 + g), the same sum, bit for bit;
* L15 (tau_L' = inf let into the bias term): the planner refuses tau_L' = inf with |gamma_bar'| >= 1 before
  (check_recurrent), before any call of log_duration_scale;
* L23 (drift tau_L' for |gamma_bar'| >= 1): the bias term, tau_L' e^{z^2/2} / max(z, 1) >= tau_L', is in the max;
* L24 (tau' dropped from the tail's max): for tau' >= 1 the predicted duration exceeds tau' (by > 3x, scanned
  over tau' in [1, 1e3], |gamma_bar'| <= 3), below it the 1 binds;
* L29 (want <= 2^62), L32 (2^62 dropped from the last min): 2^62 either way;
* L41 (e < 15): no float log_x gives e = log_x / ln 10 = 15 exactly (14.999999999999998, then 15.000000000000002).

The one left, L36 (``min(exp(log_w), max_work)`` for ``min(exp(min(log_w, 700)), max_work)`` in check_work), was
more right than the module: an accepted prediction between e^700 = 1.0e304 and max_work was returned as 1.0e304
(plan_estimate(Params.from_nondim(1390, 1, 0), n_excursions=2, max_work=1e308).predicted_work = 1.01e304, the
prediction 2.56e306).  check_work now caps the exponent at log(max_work) instead (no overflow: an accepted log_w
is at most that), and test_a_prediction_beyond_e_to_the_700_is_returned_whole pins it.
"""
import dataclasses
import math
import sys
import warnings

import numpy as np
import pytest
from scipy import special

import dryfric_jax as dj
from dryfric_jax import limits
from dryfric_jax.combine import combine_estimates, gather_hosts
from dryfric_jax.excursions import STAT_NAMES

# Gamma = 2, Delta = 3: v0 = Gamma/Delta = 2/3 m/s (MODEL_NOTES section 1; as in test_estimators_mutants)
V0 = 2 / 3
PARAMS = dict(Gamma=2.0, Delta=3.0, tau=0.1, tau_L=0.5, gamma_bar=0.25)


def _sums(U, t, th=None):
    """The sums of STAT_NAMES of the excursions (U, t) (t_half: th), by hand."""
    U, t = np.asarray(U, float), np.asarray(t, float)
    th = 0.5 * t if th is None else np.asarray(th, float)
    pw = dict(n=(0, 0), U=(1, 0), U2=(2, 0), U3=(3, 0), U4=(4, 0), t=(0, 1), t2=(0, 2), t3=(0, 3), t4=(0, 4),
              Ut=(1, 1), U2t=(2, 1), U3t=(3, 1), Ut2=(1, 2), U2t2=(2, 2), Ut3=(1, 3))
    out = {k: float(np.sum(U ** a * t ** b)) for k, (a, b) in pw.items()}
    out["t_half"] = float(th.sum())
    assert set(out) == set(STAT_NAMES)
    return out


def _samples(seed, n=400):
    g = np.random.default_rng(seed)
    t = g.exponential(1.0, n) + 0.25
    return 0.3 * t + np.sqrt(t) * g.standard_normal(n), t


def _run(seed, U=None, t=None, **kw):
    """An EstimateResult of the DI at PARAMS with the excursions (U, t) (default: 400 drawn with ``seed``);
    D, M0 are placeholders (combine recomputes them from the sums)."""
    if U is None:
        U, t = _samples(seed)
    base = dict(D=1.0, D_ci=0.1, M0=0.0, M0_ci=0.1, mean_duration=1.0, n_excursions=len(U), n_truncated=0,
                method="di", h=1e-3, dtype="float64", seed=seed, wall_s=1.0, lane_steps_per_s=10.0,
                lane_utilization=0.5, params=PARAMS, sums=_sums(U, t), version="test")
    return dj.EstimateResult(**{**base, **kw})


def _pool(*rs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        return combine_estimates(list(rs))


# ------------------------------------------------------------------------------------------------ combine.py
@pytest.mark.parametrize("edit", [
    dict(seed=2**62), dict(lane_utilization=1.0 + 5e-10), dict(lane_utilization=0.0), dict(events_per_s=0.0),
    dict(max_work=0.0), dict(wall_s=0.0), dict(n_truncated=0), dict(combined_from=[3, 2**62]),
    dict(ci_level=0.5), dict(max_time=1e-300),
])
def test_each_field_at_the_edge_of_its_range_is_accepted(edit):
    """combine's ranges include their closed ends: seed 2^62, utilisation 1 (up to 1e-9 of rounding) and 0,
    events_per_s, max_work, wall_s and n_truncated 0.  Kills K05 (seed < 2^62), K07 (utilisation <= 1 exactly),
    K08 (utilisation > 0), K12 (events_per_s > 0), K14 (max_work > 0), K03 (counts > 0), K36 (0/0 for a
    run of utilisation 0)."""
    a = dataclasses.replace(_run(1), **edit)
    c = _pool(a, _run(2, ci_level=a.ci_level))
    assert c.n_excursions == 800


@pytest.mark.parametrize("edit,field", [
    (dict(wall_s=math.inf), "wall_s"), (dict(lane_steps_per_s=math.nan), "lane_steps_per_s"),
    (dict(wall_s=True), "wall_s"), (dict(n_truncated=True), "n_truncated"), (dict(lanes=2.0), "lanes"),
    (dict(seed=2**62 + 1), "seed"), (dict(seed=-1), "seed"), (dict(h=0.0), "h"), (dict(delta=0.0), "delta"),
    (dict(L_X=-0.0), "L_X"), (dict(ci_level=1.0), "ci_level"), (dict(ci_level=0.0), "ci_level"),
    (dict(combined_from=[1, 2**62 + 1]), "combined_from"), (dict(combined_from=[-5]), "combined_from"),
    (dict(method="euler"), "method"), (dict(events_per_s=-1e-300), "events_per_s"),
    (dict(lane_utilization=1.0 + 1e-8), "lane_utilization"), (dict(predicted_work=-1.0), "predicted_work"),
    (dict(warnings=["a", 1]), "warnings"),
])
def test_each_field_just_beyond_its_range_is_refused_by_name(edit, field):
    """The other side of each range, and the types (a bool is not a number, an infinite wall time not
    finite).  Kills K01 (isfinite dropped: inf and nan pass as real), K02 (True taken as the number 1),
    K04 (True taken as the count 1), K05 (dual of the accepted 2^62), K06 (step 0 accepted), K09 (ci_level 1
    accepted), K10 (combined_from's seeds unchecked), K11 (any method)."""
    with pytest.raises(ValueError, match=f"^b.json must have {field} "):
        combine_estimates([_run(1), dataclasses.replace(_run(2), **edit)], labels=["a.json", "b.json"])


@pytest.mark.parametrize("name", ["U2", "U4", "t2", "t3", "t4", "U2t", "U2t2", "t_half"])
def test_every_sum_of_squares_must_be_nonnegative_and_zero_is_accepted(name):
    """combine: the sums of squares (and of positive times) must be >= 0, each one: a negative one is refused
    naming it; 0 is in range (a run whose t_half was not recorded has 0 there).  Kills K19-K21 (U4, t2,
    t_half dropped from the list) and K22 (> 0 for >= 0)."""
    bad = _run(2)
    with pytest.raises(ValueError, match=rf"^results\[1\] must have finite excursion sums.*\(got {name} = -1"):
        combine_estimates([_run(1), dataclasses.replace(bad, sums={**bad.sums, name: -1.0})])
    if name == "t_half":
        assert _pool(_run(1), dataclasses.replace(bad, sums={**bad.sums, "t_half": 0.0})).n_excursions == 800


def test_a_run_without_excursions_is_refused_even_beside_a_good_one():
    """n must be a whole number in [1, 2^62] in each run: n = 0 (and sums of 0) beside a run of 400 was pooled
    as that run.  Kills K16 (0 <= n)."""
    empty = _run(2, sums=dict.fromkeys(STAT_NAMES, 0.0) | {"t": 1.0})
    with pytest.raises(ValueError, match=r"^results\[1\] must have finite excursion sums.*\(got n = 0"):
        combine_estimates([_run(1), empty])


def _scaled(r, c):
    return dataclasses.replace(r, sums={k: v * c for k, v in r.sums.items()})


def test_two_to_the_62_excursions_are_accepted_in_one_run_and_in_a_pool():
    """n = 2^62 is inside [1, 2^62], for one run and for the pool of two runs of 2^61.  Every sum scaled by
    one power of two c (exact in float64) leaves M0 and D unchanged (both are ratios homogeneous of degree 0
    in the sums) and divides the CIs by sqrt(c) (delta method, N -> cN): so the scaled pool is the unscaled
    pool with CIs / sqrt(c).  Kills K17 (n < 2^62 in a run) and K32 (pool n >= 2^62 refused)."""
    a, b = _run(1, *[x[:256] for x in _samples(1)]), _run(2, *[x[:256] for x in _samples(2)])
    one = _pool(_scaled(a, 2.0**54))
    ref = _pool(a)
    assert one.n_excursions == 2**62
    assert (one.D, one.M0) == pytest.approx((ref.D, ref.M0), rel=1e-12)
    assert (one.D_ci, one.M0_ci) == pytest.approx((ref.D_ci / 2.0**27, ref.M0_ci / 2.0**27), rel=1e-9)
    two = _pool(_scaled(a, 2.0**53), _scaled(b, 2.0**53))
    ref = _pool(a, b)
    assert two.n_excursions == 2**62
    assert (two.D, two.M0) == pytest.approx((ref.D, ref.M0), rel=1e-12)


def test_steps_equal_to_rounding_pool_and_steps_that_differ_do_not():
    """Two runs' h must agree, to rounding only (rel 1e-12: a step read back from text, or computed as
    h' tau0, differs in its last bits): h (1 + 4e-16) pools, h (1 + 1e-9) is another step.  Kills K25 (exact
    equality) and K26 (rel 1e-6)."""
    h = 1e-3
    assert _pool(_run(1, h=h), _run(2, h=h * (1 + 4e-16))).h == h
    with pytest.raises(ValueError, match="^results must share h"):
        combine_estimates([_run(1, h=h), _run(2, h=h * (1 + 1e-9))])


def test_a_pool_with_exactly_zero_diffusivity_is_accepted():
    """Excursions with U = 2t exactly (dyadic t: every sum exact) have M0 = sum U / sum t = 2 and
    D = sum (U - 2t)^2 / sum t = 0 exactly; the pool is refused only for D < 0.  Kills K33 (D <= 0 refused)."""
    t1, t2 = np.array([0.5, 1.0, 1.5, 2.0]), np.array([0.25, 0.75, 3.0])
    c = _pool(_run(1, 2 * t1, t1), _run(2, 2 * t2, t2))
    assert c.D == 0.0 and c.M0 == pytest.approx(2 * V0, rel=1e-15)


@pytest.mark.filterwarnings("ignore:overflow:RuntimeWarning", "ignore:invalid value:RuntimeWarning")
def test_sums_that_give_a_nan_ci_are_refused():
    """Finite, in-range sums can still be inconsistent: t2 = t4 = 1e300 beside t ~ 500 (a hand-edited file)
    make the covariance of t an overflow, inf - inf = nan, and D's CI nan with D finite and > 0.  The pool
    is refused, not returned with a nan CI.  Kills K58 (only D < 0 refused)."""
    r = _run(1)
    bad = dataclasses.replace(r, sums={**r.sums, "t2": 1e300, "t4": 1e300})
    with pytest.raises(ValueError, match=r"^results must hold consistent excursion sums: they give D = .* \+- nan"):
        combine_estimates([bad])


def test_the_pools_bookkeeping_where_the_runs_spent_no_time():
    """combine_estimates docstring: the pool's rate is its useful steps over its wall time (0 if no time was
    spent, not a ZeroDivisionError); its utilisation useful / slots, a run of utilisation 0 having no useful
    steps to add (not a ZeroDivisionError), and with no slots at all the first run's.  By hand: rates 0 and 40
    over 0 s and 2 s, utilisation 0 and 0.8: rate (0 + 80)/2 = 40, utilisation 80/(80/0.8) = 0.8.  Kills K35
    (wall >= 0), K36 (the utilisation-0 guard dropped), K37 (no slots: 0), K56 (the first run's wall time)."""
    c = _pool(_run(1, wall_s=0.0, lane_steps_per_s=0.0, lane_utilization=0.0),
              _run(2, wall_s=2.0, lane_steps_per_s=40.0, lane_utilization=0.8))
    assert (c.wall_s, c.lane_steps_per_s, c.lane_utilization) == (2.0, 40.0, 0.8)
    c = _pool(_run(1, wall_s=0.0, lane_utilization=0.3), _run(2, wall_s=0.0, lane_utilization=0.6))
    assert (c.wall_s, c.lane_steps_per_s, c.lane_utilization) == (0.0, 0.0, 0.3)


def test_the_pools_event_rate_notes_and_run_settings():
    """PDMP runs (events_per_s set): the pool's event rate is its rate, by hand (2 s at 30/s + 6 s at 10/s)/8 s
    = 15/s, not the first run's 30; a note both runs carry is said once; rtol and max_time, settings of one
    run's stopping, are None on the pool; lanes the runs differ in are 0.  Kills K38 (first run's event rate),
    K39 (notes repeated), K41 (first run's rtol), K42 (first run's max_time), K43 (first run's lanes),
    K52 (a setting the runs differ in kept)."""
    kw = dict(method="pdmp", h=None, delta=0.05, rtol=0.01, max_time=60.0, warnings=["note x"])
    c = _pool(_run(1, wall_s=2.0, lane_steps_per_s=30.0, events_per_s=30.0, lanes=64, **kw),
              _run(2, wall_s=6.0, lane_steps_per_s=10.0, events_per_s=10.0, lanes=128, **kw))
    assert (c.lane_steps_per_s, c.events_per_s) == (15.0, 15.0)
    assert c.warnings.count("note x") == 1 and (c.rtol, c.max_time, c.lanes) == (None, None, 0)


def test_one_result_dict_is_not_a_list_and_foreign_keys_are_ignored():
    """A single to_dict() is refused as not a list (it was iterated as its keys, each refused as 'of type
    str'); a to_dict() with a key EstimateResult does not have (a newer version's field) is read.  Kills K46
    (dict not refused up front) and K47 (unknown keys passed to EstimateResult: a TypeError)."""
    with pytest.raises(ValueError, match=r"^results must be a list of EstimateResult objects \(got dict\)"):
        combine_estimates(_run(1).to_dict())
    with pytest.raises(ValueError, match=r"^results must be a list of EstimateResult objects \(got ndarray\)"):
        combine_estimates(np.array(0.5))  # a 0-d array has __iter__: a TypeError from iter (an audit)
    assert _pool({**_run(1).to_dict(), "from_the_future": 1}, _run(2)).n_excursions == 800


def test_gather_hosts_keeps_a_key_made_run_seedless():
    """In one process gather_hosts pools the run alone: a run made from a key (seed None) stays seedless
    (combined_from [None], with the key warning), not seed 0.  Kills K49 (None sent as seed 0)."""
    with pytest.warns(dj.DryfricWarning, match="assumed independent"):
        g = gather_hosts(_run(None, *_samples(5)))
    assert g.combined_from == [None] and g.n_excursions == 400


# ------------------------------------------------------------------------------------------------ limits.py
@pytest.mark.parametrize("tau", [1.0, 20.0, 100.0, 300.0])
def test_the_symmetric_passage_time_is_tau_pi_erfi(tau):
    r"""At gamma_bar' = 0 the passage from x+ = 1 to x- = -1 has u from -s to s, s = sqrt(tau'/2), and
    erfcx(u) + erfcx(-u) = 2 e^{u^2}: T = tau sqrt(pi) int_0^s 2 e^{u^2} du = tau pi erfi(s) (closed form).
    tau' = 100 and 300 put u_b = -7.1 and -12.2 below the Dawson cut (-6) with u_a = -u_b above 0, where the
    e^{u^2} part ends at 0, not at u_a.  Kills L03 (m = hi: the log of twice the time there), L05, L09,
    L10 (the factor 2 of the Dawson form, sqrt(tau) for sqrt(tau/2), log tau for log(tau sqrt(pi)))."""
    s = math.sqrt(tau / 2.0)
    want = math.log(tau * math.pi) + math.log(special.erfi(s))
    assert limits.log_ou_passage_time(1.0, -1.0, tau) == pytest.approx(want, rel=1e-9, abs=1e-9)
    assert limits.log_ou_passage_time(-1.0, 1.0, tau) == pytest.approx(want, rel=1e-9, abs=1e-9)  # X -> -X


@pytest.mark.parametrize("log_x,text", [
    (math.log(1250.0), "1.25e+03"),  # e <= 15: exp(x) itself, 3 digits
    (math.log(59_749.0), "5.98e+04"),  # rounded up (a lower bound): "5.97e+04" was refused as max_work
    (1e10 * 0 + 10 * math.log(10.0), "1.01e+10"),  # log(1e10) < 10 log(10) by rounding: 1e10 is refused
    (1234 * math.log(10.0) + math.log(2.53), "2.6e1234"),  # two digits of the mantissa, rounded up
    (123456.7 * math.log(10.0), "5.1e123456"),  # 10^0.7 = 5.01, up
    (15.999 * math.log(10.0), "1e16"),  # 10^0.999 = 9.977 rounds to 10 at two digits: it printed "10e15"
    (1233.9999 * math.log(10.0), "1e1234"),
    (1e6 * math.log(10.0), "10^(1e+06)"),  # e = 1e6 exactly (checked below): the exponent's own form
    (1.9e300 * math.log(10.0), "10^(1.9e+300)"), (math.inf, "10^(1.79e+308)"),
])
def test_exp10_writes_the_docstrings_forms(log_x, text):
    """limits._exp10: exp(log_x) as text, its docstring's forms "2.5e1234", "10^(1.9e+300)", "10^(1.79e+308)" for an
    overflowed log (it said "inf"), and plain
    %.3g up to 1e15; the exponent form from e = 1e6 on (included).  Kills L42 (plain only to 1e6), L43
    (e > 1e6), L44 (exponent form from 1e5), L45 (three digits of mantissa), L46 (inf not said)."""
    assert 1e6 * math.log(10.0) / math.log(10.0) == 1e6
    assert limits._exp10(log_x) == text


def test_a_max_work_copied_from_the_refusal_is_accepted():
    """The work refusal states a lower bound ("max_work must be >= 5.98e+04"), rounded to nearest it was below the
    prediction in 54 of these 200 runs (a diff review): copied back as max_work, it was refused again."""
    for n in range(1000, 1200):
        with pytest.raises(ValueError) as e:
            limits.check_work(0.3, 10.0, 0.1, 50.0, n, max_work=1.0)
        least = float(str(e.value).split("max_work must be >= ")[1].split(" ")[0])
        assert limits.check_work(0.3, 10.0, 0.1, 50.0, n, max_work=least) <= least


def test_a_work_refusal_past_float_range_by_the_duration_alone_suggests_nothing_that_cannot_help():
    """One excursion predicted to last past 1.8e308 tau0 (tau_L' = 1e300, gamma_bar' = 1.5: the bias keeps it moving):
    no h, delta or N helps, so none is suggested; the white-noise theory only where tau' < 1.  Past float range by N
    and steps alone (a duration of ~1), coarsening and lowering N are still the advice."""
    for tau, hint in ((0.5, True), (2.0, False)):
        with pytest.raises(ValueError) as e:
            limits.check_work(tau, 1e300, 1.5, 10.0, 100)
        assert str(e.value).endswith(".  No h, delta or N makes this run feasible" + (
            "; the white-noise theory ('dryfric theory') gives D when tau << tau0" if hint else ""))
    with pytest.raises(ValueError, match=r"\.  Coarsen h or delta, lower N, or use the white-noise theory"):
        limits.check_work(1e-3, 0.5, 0.0, 1e200, 10**150)


def test_max_steps_is_the_ceiling_of_1e4_tail_time_scales():
    r"""max_steps_per_excursion = ceil(1e4 x tail x steps per tau0), at least 64, at most cap (docstring).
    gamma_bar' = -0.9, tau_L' = 12.3456 (< 1/(1 - 0.9)^2 = 100; the runaway floor 1/(0.1 + 0.5/sqrt(tau_L')) = 4.1 is
    below it): tail = tau_L', 123456 steps.
    Fast noise with tau_L' = 0.1: every part of the tail (tau', drift, duration floor min(1, tau_L')) is
    below 1, and the tail scale is 1: 1e4 x 1 x 100 = 1e6.  Kills L28 (int for ceil), L25 (the 1 dropped
    from the tail's max), L30 (at least 1, not 64); L21, L27, L54 too."""
    assert limits.max_steps_per_excursion(1e-3, 12.3456, -0.9, 1.0) == math.ceil(1e4 * 12.3456) == 123456
    assert limits.tail_time_scale(1e-3, 0.1, 0.3) == 1.0
    assert limits.max_steps_per_excursion(1e-3, 0.1, 0.3, 100.0) == 1_000_000
    assert limits.max_steps_per_excursion(1e-3, 0.1, 0.3, 1e-9) == 64


def test_max_steps_at_the_bias_equal_to_the_friction_and_beyond_float_range():
    r"""At |gamma_bar'| = 1 exactly there is no drift time (1/(1 - |gamma_bar'|)^2 has no value; the bias
    term, tau_L' e^0 / max(0, 1) = tau_L' = 10, is the tail): 1e4 x 10 x 1 = 1e5 steps (+1 for the
    ceiling of its rounding).  tau' = 1500 (duration ~ e^{750}: exp overflows a float) is bounded by the cap,
    not an OverflowError.  Kills L22 (g <= 1: a ZeroDivisionError at g = 1) and L26 (exp without
    min(., 700)); L14, L17, L18, L31, L55 too."""
    for g in (1.0, -1.0):
        assert limits.max_steps_per_excursion(1e-3, 10.0, g, 1.0) == pytest.approx(1e5, abs=1)  # ceil of e^{log 10}
    assert limits.log_duration_scale(1500.0, 1.0, 0.0) > 709.8  # beyond float range
    assert limits.max_steps_per_excursion(1500.0, 1.0, 0.0, 10.0) == limits.MAX_WORK
    assert limits.max_steps_per_excursion(1500.0, 1.0, 0.0, 10.0, cap=1e300) == 2**62


def test_an_accepted_prediction_never_exceeds_max_work():
    """check_work accepts log(N x duration x steps) <= log(max_work) and returns the prediction, at most
    max_work: at N = 3, 3 steps per tau0 and the floor duration 1 (fast noise, tau_L' = 1) log 3 + log 3 =
    log 9 exactly in floats, but exp of it is 9.000000000000002; the prediction returned is 9 (hand
    arithmetic), not above the bound it was accepted under.  Kills L35 (min with max_work dropped);
    L13, L33, L34 too."""
    assert math.log(3) + math.log(3.0) <= math.log(9.0) and math.exp(math.log(3) + math.log(3.0)) > 9.0
    assert limits.check_work(1e-6, 1.0, 0.0, 3.0, 3, max_work=9.0) == 9.0


def test_float32_reasons_state_their_numbers():
    """float32_unsafe_reason's messages: at h/tau = 1e-6 float32's rounding of 1 - m2 (up to 3e-8) is 3e-8 /
    1e-6 = 3.0% of it; at tau' = 1e-32 the noise's stationary SD 1/sqrt(tau') is 1e16.  Kills L52 (3e-8 x
    h/tau) and L56 (1/tau' for the SD)."""
    assert limits.float32_unsafe_reason(1e-6, 1.0, 1.0).endswith("by up to 3%")
    assert limits.float32_unsafe_reason(1e-10, 1.0, 1.0).endswith("by up to 30000%")  # not 3e+04%
    # near the bound h/tau = 1e-4 the share is 0.03%; with one decimal it read "0.0%" (a user audit)
    assert limits.float32_unsafe_reason(6.7e-5, 1.0, 1.0).endswith("by up to 0.045%")
    assert "stationary SD 1e+16 nears" in limits.float32_unsafe_reason(1.0, 1.0, 1e-32)


def test_a_prediction_at_exactly_the_largest_float_is_not_beyond_float_range():
    """check_work says 'beyond float range (no max_work allows them)' only where the prediction exceeds the
    largest float: N = 1, the floor duration 1 (log 0 exactly) and sys.float_info.max steps per tau0 predict
    exactly the largest float, which max_work = that float allows; max_work = 1e300 refuses it with the advice
    to raise max_work.  Kills L39 (>= for >)."""
    big = sys.float_info.max
    assert limits.log_duration_scale(1e-6, 1.0, 0.0) == 0.0
    with pytest.raises(ValueError, match=r"^max_work must be >= 1.8e308 steps for these parameters \(got 1e\+300\)"):
        limits.check_work(1e-6, 1.0, 0.0, big, 1, max_work=1e300)
    limits.check_work(1e-6, 1.0, 0.0, big, 1, max_work=big)  # accepted


def test_a_prediction_beyond_e_to_the_700_is_returned_whole():
    """check_work's docstring: predicted work = N x predicted duration x steps per tau0.  tau' = 1390 (a
    duration of ~e^700 tau0), N = 2 and 100 steps per tau0 predict 2.6e306 steps, which max_work = 1e308
    accepts: the plan reports that prediction, not e^700 = 1.0e304 (the old cap of the exponent).  Kills L36's
    twin, the exponent capped at 700."""
    p = dj.Params.from_nondim(1390.0, 1.0, 0.0)
    plan = dj.plan_estimate(p, h=p.tau0 / 100.0, n_excursions=2, max_work=1e308)
    want = 2 * math.exp(limits.log_duration_scale(1390.0, 1.0, 0.0)) * plan.per_tau0
    assert plan.per_tau0 == pytest.approx(100.0, rel=1e-12) and 1e306 < want < 1e308
    assert plan.predicted_work == pytest.approx(want, rel=1e-12)
