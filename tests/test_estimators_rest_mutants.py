r"""Second mutation audit of :mod:`dryfric_jax.estimators`: what the first (test_estimators_mutants.py) left.

Targets (the first audit's 39 mutants covered the Psi_D terms, the quantile, sqrt(N), the covariance's
divisor and products, the CI levels and replicate_coverage's M0 judge, units and min_size): delta_method's
check of n, the compiled-function cache, the constants, grad_psi_D_by_hand, phi_bf and psi_D_paper,
z_quantile's form, moments_from_sums, ci_rounding's rho (gradient, |C|, |E[X X^T]|, |S S^T|, eps, the
sigma^2 <= 0 case), rounding_note's threshold, percent and digits, sums_from_samples' cast and t_half,
long_excursion_estimates' N bound and the duration CI's clamp, bruteforce_estimates' cast, centring,
clamp and divisors, replicate_coverage's grouping, averages and boundaries.

72 one-line mutants were tried: 35 were killed by the older tests (34 by the five files run against every
mutant, MIN_RELIABLE_PATHS = 499 by test_stopping_rule.py), 13 are equivalent (below), 24 are killed only here
(n = 1 and numpy or string sample sizes in delta_method, the compiled-function cache of one, phi_bf's sign and
y_1^2 term, ci_rounding's |C| in the variance, |S S^T| dropped, |C| for |E[X X^T]|, half the size, a
ZeroDivisionError at sigma^2 = 0, rounding_note's ``<`` threshold, rho > 1 read as inf, 100 rho % and one
digit, integer samples summed in int64, t in place of a missing t_half, N = 2 refused, a NaN duration CI,
float32 brute-force U worked in float32, a partial last replicate, median for mean in two averages), and
0 are alive.

Equivalent (13): z_quantile as -inv_cdf(0.5 - level / 2) (the normal is symmetric; same to rounding);
``np.outer(S, S).T`` (the same matrix, products commute exactly); sums' n from t.size (equal to U.size
whenever U * t is formed) or as an int (every reader rounds or divides it); ``int(T["n"])`` for
``int(round(T["n"]))`` (every producer's n is an integer, exact below 2^53); abs(C_tt) for max(C_tt, 0) in the
duration CI (they differ only when rounding makes the variance of t negative: 1.5e-9 for 0, see
test_equal_durations_give_a_zero_duration_ci_not_nan); brute force's y_1 = Uc / t for Uc / sqrt(t) (after
centring y_1 = 0 up to rounding and Phi's gradient in y_1, -2 y_1, vanishes); abs(D_t) for max(D_t, 0) (they
differ only on a D_t below 0 by rounding); the horizon echoed as float(t) (the same value); Uc.std() for
U.std() (numpy centres; the same to rounding); ``<`` for ``<=`` in replicate_coverage's two hit tests (a
boundary hit has probability 0, and appendix D's interval is open, so neither is the wrong one);
D_ci / D_true for D_ci / abs(D_true) (D_true is a diffusivity, > 0).

Oracles: hand arithmetic; fractions.Fraction on dyadic samples (test_estimators_mutants' exact delta method
and analytic gradient of Psi_D, and ci_rounding's documented rho in exact arithmetic); scipy.stats.norm for
the quantiles; the docstrings (ci_rounding, rounding_note, delta_method, replicate_coverage) and appendix D.
Older tests run against every mutant: test_estimators_mutants.py, test_estimators.py, test_api_audit.py,
test_combine_limits_mutants.py, test_internals_audit.py (about 30 s together); test_combine.py (37 s) and
test_stopping_rule.py (51 s) were run against the survivors only (the other tests reaching estimators.py
run full simulations: test_engine, test_calibration, test_stress, test_pdmp, ...).

Two defects, fixed (the last three tests fail on the old code): no check of ``level`` (0 gave
CIs of 0, NaN NaN ones, -0.5 negative ones, >= 1 a statistics.StatisticsError about ``p``, and the largest
float below 1 that error too, because 0.5 + level / 2 rounded to 1), and none of brute force's horizon
``t`` (0, < 0 or NaN gave NaN estimates).  z_quantile now refuses a level outside (0, 1) with a ValueError
naming it and takes the lower tail; bruteforce_estimates refuses a t that is not > 0 and finite.
"""
import math
from fractions import Fraction as F

import numpy as np
import pytest
from scipy.stats import norm

from dryfric_jax import estimators
from dryfric_jax.estimators import (ROUNDING_NOTE, ROUNDING_TOL, _value_and_variance, bruteforce_estimates,
                                    ci_rounding, delta_method, long_excursion_estimates, phi_bf, psi_D_paper,
                                    replicate_coverage, rounding_note, sums_from_samples)
from dryfric_jax.excursions import STAT_NAMES
from test_estimators_mutants import A_H, A_T, A_U, B_H, B_T, B_U, _grad_psi_D, _oracle, _sums

EPS64 = 2.0**-52  # float64's machine epsilon, written out (ci_rounding's docstring: 2.2e-16)
Z95 = float(norm.ppf(0.975))  # two-sided 95% quantile, from scipy (not the code's NormalDist)


def _first(m):
    """Psi(m) = m_1: its delta-method variance is C_11."""
    return m[0]


def test_delta_method_takes_any_real_sample_size_of_at_least_one():
    """'n must be a sample size >= 1': n = 1 is taken (half-width z sigma), and so are numpy integers and
    numpy floats of any width; a string is refused with the ValueError, not a TypeError from ``"4" >= 1``.
    Psi(m) = m_1 at mean 3, variance 4: sigma = 2, half-width z 2 / sqrt(n).  Kills V02 (n > 1), V03
    (np.integer dropped from the accepted types), V04 (np.floating dropped: np.float32 refused), V05 (the
    type check dropped)."""
    for n in (1, 4, 4.0, np.int64(4), np.int32(16), np.float32(4.0), np.float64(1.0)):
        D, half, sigma = delta_method(_first, [3.0], [[4.0]], n, 0.95)
        assert (D, sigma) == (3.0, 2.0), n
        assert half == pytest.approx(Z95 * 2 / math.sqrt(float(n)), rel=1e-14), n
    for bad in ("4", None, [4], 0.5):
        with pytest.raises(ValueError, match="^n must be a sample size >= 1"):
            delta_method(_first, [3.0], [[4.0]], bad, 0.95)


def test_the_compiled_delta_method_is_kept_for_both_ratios():
    """'compiled once per psi': each estimate runs psi_D then psi_M, and alternating between them must not
    evict either compiled function (a cache of one missed twice per estimate, tracing each again).
    Kills W03 (lru_cache maxsize=1)."""
    T = _sums(A_U, A_T, A_H)
    long_excursion_estimates(T)
    before = _value_and_variance.cache_info()
    for _ in range(3):
        long_excursion_estimates(T)
    after = _value_and_variance.cache_info()
    assert after.misses == before.misses and after.hits == before.hits + 6


def _rho_oracle(U, t):
    """ci_rounding's documented rho = eps |g|^T (|E[X X^T]| + |S S^T|) |g| / (g^T C g), in exact arithmetic,
    with g the analytic gradient of Psi_D (test_estimators_mutants._grad_psi_D)."""
    n = len(U)
    X = [(u, u * u, s, u * s, s * s) for u, s in zip(U, t)]
    S = [sum(x[i] for x in X) / n for i in range(5)]
    E2 = [[sum(x[i] * x[j] for x in X) / n for j in range(5)] for i in range(5)]
    g = _grad_psi_D(S)
    var = sum(g[i] * (E2[i][j] - S[i] * S[j]) * g[j] for i in range(5) for j in range(5))
    size = sum(abs(g[i]) * (abs(E2[i][j]) + abs(S[i] * S[j])) * abs(g[j]) for i in range(5) for j in range(5))
    return F(EPS64) * size / var


@pytest.mark.parametrize("run", ["a", "b", "ab"])
def test_ci_rounding_is_its_documented_formula(run):
    """rho on three dyadic samples (every sum exact in float64) against the formula of its docstring in
    exact arithmetic (rel 1e-9: the code's jax gradient and g^T C g round at 1e-16 times a cancellation of
    at most 1e3 here).  The covariance has entries of both signs, the gradient too.  Kills R01 (the
    gradient of psi_M), R02 (of the paper's Psi), C01 (|C| in the variance), C02 (|S S^T| dropped), C03
    (|C| for |E[X X^T]|), C04 (g for |g| on the left), C07 (half the size)."""
    U, t = {"a": (A_U, A_T), "b": (B_U, B_T), "ab": (A_U + B_U, A_T + B_T)}[run]
    want = _rho_oracle(U, t)
    assert 0 < want < ROUNDING_TOL  # these samples are not flagged
    assert ci_rounding(_sums(U, t, [F(0)] * len(U))) == pytest.approx(float(want), rel=1e-9, abs=0)


def test_identical_excursions_give_a_zero_interval_flagged_not_a_crash():
    """Three identical excursions (U, t) = (3/2, 1/2): every sum is exact, so the covariance is 0 exactly,
    and so are D = E[(U - 3t)^2] / E[t] and all half-widths.  ci_rounding's docstring: ``inf`` if
    sigma^2 <= 0, and the note says the half-width means nothing.  Kills C05 (``not var >= 0``: a
    ZeroDivisionError at sigma^2 = 0)."""
    T = _sums([F(3, 2)] * 3, [F(1, 2)] * 3, [F(1, 4)] * 3)
    e = long_excursion_estimates(T)
    assert (e["D"], e["D_ci"], e["M0"], e["M0_ci"], e["mean_duration"], e["mean_duration_ci"]) == (0, 0, 3, 0, 0.5, 0)
    assert ci_rounding(T) == math.inf
    note = rounding_note(T)
    assert note.startswith(ROUNDING_NOTE + ": ") and "the half-width is 0 and means nothing" in note


@pytest.mark.parametrize("rho, pct", [(0.0246, 1.23), (0.5, 25.0), (2.0, 100.0)])
def test_rounding_note_states_half_the_variance_error_in_percent(monkeypatch, rho, pct):
    """The note's bound is on the half-width, 'about half as much' as rho (ci_rounding's docstring): 50 rho
    percent, to the 2 digits it prints (rel 5%).  A finite rho > 1 is not the 'came out <= 0' case.
    Kills N02 (``rho > 1`` for ``rho == inf``), N03 (100 rho %), N04 (one digit: 1% for 1.23%)."""
    monkeypatch.setattr(estimators, "ci_rounding", lambda T: rho)
    note = rounding_note({})
    assert note.startswith(ROUNDING_NOTE + ": ") and "means nothing" not in note
    stated = float(note.split("half-width by up to ~")[1].split("%")[0])
    assert stated == pytest.approx(pct, rel=0.05)


def test_rounding_note_threshold_is_rounding_tol_inclusive(monkeypatch):
    """'moved by more than ~ROUNDING_TOL / 2' (rounding_note's docstring), ROUNDING_TOL = 1e-2: rho equal to
    it gives no note, the next float up one.  Kills N01 (``rho < ROUNDING_TOL``)."""
    assert ROUNDING_TOL == 1e-2
    monkeypatch.setattr(estimators, "ci_rounding", lambda T: 1e-2)
    assert rounding_note({}) is None
    monkeypatch.setattr(estimators, "ci_rounding", lambda T: math.nextafter(1e-2, 1))
    assert rounding_note({}).startswith(ROUNDING_NOTE)


def test_two_excursions_are_enough_for_a_ci():
    """'need at least 2 complete excursions': N = 2 gives the exact delta method (test_estimators_mutants'
    Fraction oracle).  Kills L02 (``n < 3``)."""
    U, t, th = A_U[:2], A_T[:2], A_H[:2]
    want, _ = _oracle(U, t, th)
    got = long_excursion_estimates(_sums(U, t, th))
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-12), k


def test_equal_durations_give_a_zero_duration_ci_not_nan():
    """Three durations of 0.1 s: the sample variance of t is 0, but E[t^2] - E[t]^2 rounds to -1.7e-18
    (float64).  The mean duration's CI must be 0 up to that rounding, z sqrt(4 eps E[t^2] / n), not NaN.
    Kills L04 (the max(., 0) dropped).  abs(.) in its place gives 1.5e-9, inside the rounding: equivalent."""
    e = long_excursion_estimates(sums_from_samples([1.0, 2.0, -1.0], [0.1] * 3))
    assert 0 <= e["mean_duration_ci"] <= Z95 * math.sqrt(4 * EPS64 * 0.01 / 3)
    assert e["mean_duration"] == pytest.approx(0.1, rel=1e-15)


def test_sums_from_samples_of_integers_and_without_half_durations():
    """Integer samples are summed in float64: U = 10^5 gives U^4 = 10^20 (past int64's 9.2e18, where int
    powers wrap); without t_half its sum is 0 (no half durations known), not the full durations'.
    Kills S03 (the float64 cast dropped), S02 (t in place of the missing t_half)."""
    T = sums_from_samples([100_000, -3], [1, 2])
    want = {k: float(sum(u**a * s**b for u, s in ((100_000, 1), (-3, 2)))) for k, (a, b) in
            dict(U=(1, 0), U2=(2, 0), U3=(3, 0), U4=(4, 0), U3t=(3, 1), U2t2=(2, 2), t4=(0, 4)).items()}
    for k, v in want.items():
        assert T[k] == pytest.approx(v, rel=1e-15), k
    assert T["n"] == 2 and T["t_half"] == 0
    assert long_excursion_estimates(sums_from_samples([1.0, 2.0], [1.0, 3.0]))["mean_half_duration"] == 0


def _bf_oracle(U, t, level=0.95):
    """Brute force's numbers in exact arithmetic (test_estimators' hand formulas): D_t = mean((U - Ubar)^2) / t,
    its influence values ((U - Ubar)^2 - v) / t, M0_t = Ubar / t, M0_t_ci = z sqrt(v / n) / t."""
    n = len(U)
    mean = sum(U) / n
    v = sum((u - mean) ** 2 for u in U) / n
    var_D = sum((((u - mean) ** 2 - v) / t) ** 2 for u in U) / n
    z = float(norm.ppf(0.5 + level / 2))
    return dict(D_t=float(v / t), D_t_ci=z * math.sqrt(var_D / n), M0_t=float(mean / t),
                M0_t_ci=z * math.sqrt(v / n) / float(t))


def test_bruteforce_of_float32_displacements_is_worked_in_float64():
    """A float32 run's U (100 + N(0, 1), 16 paths): each float32 is a dyadic rational, so the oracle is
    exact; worked in float64 the code agrees to 1e-12.  In float32, centring loses ~6e-6 of each U - Ubar
    (D_t off by ~1e-5).  Kills B01 (the float64 cast of U dropped)."""
    U32 = (100 + np.random.default_rng(7).standard_normal(16)).astype(np.float32)
    t = 2.5
    want = _bf_oracle([F(float(u)) for u in U32], F(t))
    got = bruteforce_estimates(U32, t)
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-12), k


def test_phi_bf_and_the_papers_psi_are_their_documented_formulas():
    """phi_bf(y) = y_2 - y_1^2 and psi_D_paper(x) = (x_2 - x_1^2) / x_3, on small integers (exact).
    bruteforce_estimates centres U first, so y_1 = 0 there and a wrong sign or a dropped y_1^2 in phi_bf
    changes nothing it returns: only phi_bf itself shows it.  Kills F01 (+ y_1^2), F02 (y_1^2 dropped)."""
    assert phi_bf(np.array([3.0, 11.0])) == 2.0 and phi_bf(np.array([-2.0, 5.0])) == 1.0
    assert psi_D_paper(np.array([3.0, 13.0, 2.0, 0.0, 0.0])) == 2.0


def test_replicate_coverage_groups_whole_replicates_and_averages():
    """Seven lanes, two per replicate: three replicates (sizes 2, 2, 6); the seventh lane, one excursion,
    is no replicate (it alone would have no CI).  The relative half-width is the mean over the three (not
    the median), and mean_size 10/3.  Oracle: test_estimators_mutants' exact delta method per replicate,
    hits judged with a margin.  Kills Q02 (a partial last replicate), Q04 and Q05 (median for mean)."""
    lanes = [(A_U[:1], A_T[:1], A_H[:1]), (A_U[1:2], A_T[1:2], A_H[1:2]), (A_U[2:3], A_T[2:3], A_H[2:3]),
             (A_U[3:], A_T[3:], A_H[3:]), (B_U[:3], B_T[:3], B_H[:3]), (B_U[3:], B_T[3:], B_H[3:]),
             (B_U[:1], B_T[:1], B_H[:1])]
    arr = np.array([[_sums(*x)[k] for k in STAT_NAMES] for x in lanes])
    reps = [_oracle(A_U[:2], A_T[:2], A_H[:2])[0], _oracle(A_U[2:], A_T[2:], A_H[2:])[0], _oracle(B_U, B_T, B_H)[0]]
    D_true, M_true = 2.0, 0.5
    hits_D = [abs(r["D"] - D_true) <= r["D_ci"] for r in reps]
    hits_M = [abs(r["M0"] - M_true) <= r["M0_ci"] for r in reps]
    for r in reps:  # no hit is near its boundary
        assert abs(abs(r["D"] - D_true) - r["D_ci"]) > 0.01 and abs(abs(r["M0"] - M_true) - r["M0_ci"]) > 0.01
    widths = [r["D_ci"] / D_true for r in reps]
    assert abs(np.median(widths) - np.mean(widths)) > 0.01 * np.mean(widths)
    c = replicate_coverage(arr, STAT_NAMES, 2, D_true, M_true)
    assert c["replicates"] == 3
    assert (c["coverage_D"], c["coverage_M0"]) == (sum(hits_D) / 3, sum(hits_M) / 3)
    assert c["rel_half_width"] == pytest.approx(sum(widths) / 3, rel=1e-12)
    assert (c["min_size"], c["mean_size"]) == (2, pytest.approx(10 / 3, rel=1e-15))


def test_min_reliable_paths_is_the_measured_threshold():
    """MIN_RELIABLE_PATHS = 500, the N' at which the measured coverage reached 0.947 (its comment); the
    warning tests use the constant itself, so a changed value passed them.  Kills K03."""
    assert estimators.MIN_RELIABLE_PATHS == 500 and estimators.MIN_PATHS == 3


@pytest.mark.parametrize("bad", [0, 0.0, 1, 1.0, 1.5, -0.5, math.nan, True, "0.95", None])
def test_a_confidence_level_outside_0_1_is_refused_naming_level(bad):
    """DEFECT, fixed in z_quantile: a level of 0 gave half-widths of 0, NaN NaN ones, -0.5
    negative ones, 1 and 1.5 a statistics.StatisticsError about its ``p``, a string a TypeError.  Every
    estimator takes ``level`` (long excursions, brute force, the delta method, replicate_coverage)."""
    T = _sums(A_U, A_T, A_H)
    lanes = np.array([[T[k] for k in STAT_NAMES]])
    msg = r"^level must be a confidence level in \(0, 1\)"
    for call in (lambda: estimators.z_quantile(bad), lambda: long_excursion_estimates(T, bad),
                 lambda: bruteforce_estimates([1.0, 2.0, 4.0], 1.0, bad),
                 lambda: delta_method(_first, [3.0], [[4.0]], 4, bad),
                 lambda: replicate_coverage(lanes, STAT_NAMES, 1, 1.0, 1.0, bad)):
        with pytest.raises(ValueError, match=msg):
            call()


def test_z_quantile_is_scipys_up_to_the_largest_level_below_one():
    """The two-sided quantile against scipy's norm.isf((1 - level) / 2): at 0.5, 0.9, 0.95, 0.999 and at the
    largest float below 1, where 0.5 + level / 2 rounds to 1 (old code: StatisticsError; fixed to the lower
    tail, (1 - level) / 2 = 2^-54 exactly).  rel 1e-13: both are accurate to a few ulp."""
    for level in (0.5, 0.9, 0.95, 0.999, 1e-9, math.nextafter(1, 0)):
        want = float(norm.isf((1 - level) / 2))
        assert estimators.z_quantile(level) == pytest.approx(want, rel=1e-13), level


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf, True, "1", None])
def test_bruteforce_refuses_a_horizon_that_is_not_positive_and_finite(bad):
    """DEFECT, fixed in bruteforce_estimates: t = 0 gave D_t = NaN and M0_t = inf, t < 0 NaN and a
    negative M0_t CI, t = NaN all NaN, with numpy warnings only.  Positive numbers of any numeric type are
    taken (exact oracle)."""
    with pytest.raises(ValueError, match=r"^t must be (finite and > 0|a real number) \(got "):
        bruteforce_estimates([1.0, 2.0, 4.0], bad)
    for t in (2, np.int64(2), np.float32(2.0), 2.0):
        want = _bf_oracle([F(1), F(2), F(4)], F(2))
        got = bruteforce_estimates([1.0, 2.0, 4.0], t)
        for k in want:
            assert got[k] == pytest.approx(want[k], rel=1e-13), (t, k)
