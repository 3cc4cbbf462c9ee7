r"""Mutation audit of :mod:`dryfric_jax.estimators` and :mod:`dryfric_jax.combine`: exact oracles.

The oracle here is written from the formulas, not from the code: the regenerative ratio estimators
(estimators' module docstring, MODEL_NOTES section 1)

.. math::
    M_0 = \frac{E[U]}{E[t]}, \qquad D = \frac{E[(U - M_0 t)^2]}{E[t]},

with the delta-method half-width :math:`z\sqrt{\nabla\Psi^T C \nabla\Psi / N}` (covariance with divisor N,
appendix D), the gradient of :math:`\Psi_D(x) = x_2/x_3 - 2x_1x_4/x_3^2 + x_1^2x_5/x_3^3` coded by hand
and checked against an exact central difference.  The inputs are small hand-made samples of dyadic
rationals: every sum is exact in float64 and the oracle runs in :class:`fractions.Fraction`, so the
code must agree to rounding (rel 1e-12).  Units: Gamma = 2, Delta = 3, so that tau0 = 2/9 s,
v0 = 2/3 m/s and D0 = Gamma^3/Delta^4 = 8/81 m^2/s all differ (with Gamma = Delta = 1, as in
test_combine's runs, a CI in the wrong unit passed).

Mutant ids: E for estimators, C for combine, R for replicate_coverage; each test's docstring says what
the edits it kills change.  39 were tried; 29 were killed by the other tests, one is equivalent.
"""
import math
from fractions import Fraction as F

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.api import small_n_note
from dryfric_jax.combine import combine_estimates
from dryfric_jax.estimators import delta_method, long_excursion_estimates, psi_D, psi_M, replicate_coverage
from dryfric_jax.excursions import STAT_NAMES

# two-sided normal quantiles, written out (not taken from the code under test)
Z = {0.95: 1.959963984540054, 0.9: 1.6448536269514722}
# physical units at Gamma = 2, Delta = 3 (MODEL_NOTES section 1), written out
TAU0, V0, D0 = 2 / 9, 2 / 3, 8 / 81
PARAMS = dict(Gamma=2.0, Delta=3.0, tau=0.1, tau_L=0.5, gamma_bar=0.25)

# run a: drift > 0; run b: drift < 0 and other sizes, so every way of pooling but the right one differs
A_U, A_T, A_H = [F(3, 2), F(-1), F(4), F(1, 2)], [F(1), F(2), F(5, 2), F(1, 2)], [F(1, 4), F(3, 2), F(1), F(1, 4)]
B_U = [F(-2), F(5, 2), F(-3, 2), F(-7, 4), F(0), F(-3)]
B_T = [F(1, 2), F(3), F(1), F(3, 2), F(2), F(5, 4)]
B_H = [F(1, 4), F(1), F(1, 2), F(1, 2), F(3, 2), F(1, 2)]

# what each sum of STAT_NAMES is: sum over the excursions of U^a t^b
_POWERS = dict(n=(0, 0), U=(1, 0), U2=(2, 0), U3=(3, 0), U4=(4, 0), t=(0, 1), t2=(0, 2), t3=(0, 3), t4=(0, 4),
               Ut=(1, 1), U2t=(2, 1), U3t=(3, 1), Ut2=(1, 2), U2t2=(2, 2), Ut3=(1, 3))


def _sums(U, t, th):
    """The sufficient statistics of the excursions, written out (not ``sums_from_samples``)."""
    out = {k: float(sum(u**a * s**b for u, s in zip(U, t))) for k, (a, b) in _POWERS.items()}
    return {**out, "t_half": float(sum(th))}


def _psi_D(x):
    x1, x2, x3, x4, x5 = x
    return x2 / x3 - 2 * x1 * x4 / x3**2 + x1**2 * x5 / x3**3


def _grad_psi_D(x):
    """The analytic gradient of :func:`_psi_D`, by hand."""
    x1, x2, x3, x4, x5 = x
    return [-2 * x4 / x3**2 + 2 * x1 * x5 / x3**3, 1 / x3,
            -x2 / x3**2 + 4 * x1 * x4 / x3**3 - 3 * x1**2 * x5 / x3**4, -2 * x1 / x3**2, x1**2 / x3**3]


def _oracle(U, t, th, level=0.95):
    """Every number of ``long_excursion_estimates`` in exact arithmetic (nondimensional), and sigma_D."""
    n = len(U)
    X = [(u, u * u, s, u * s, s * s) for u, s in zip(U, t)]
    S = [sum(x[i] for x in X) / n for i in range(5)]
    C = [[sum(x[i] * x[j] for x in X) / n - S[i] * S[j] for j in range(5)] for i in range(5)]
    m = S[0] / S[2]
    D = sum((u - m * s) ** 2 for u, s in zip(U, t)) / sum(t)
    assert D == _psi_D(S)  # the two forms of D agree exactly
    g_D, g_M = _grad_psi_D(S), [1 / S[2], 0, -S[0] / S[2] ** 2, 0, 0]
    var = [sum(g[i] * C[i][j] * g[j] for i in range(5) for j in range(5)) for g in (g_D, g_M)]
    z = Z[level]
    return dict(D=float(D), D_ci=z * math.sqrt(var[0] / n), M0=float(m), M0_ci=z * math.sqrt(var[1] / n),
                mean_duration=float(S[2]), mean_duration_ci=z * math.sqrt(C[2][2] / n),
                mean_half_duration=float(sum(th) / n), n_excursions=n), math.sqrt(var[0])


def test_the_hand_gradient_of_psi_d_is_an_exact_central_difference():
    """The oracle's own gradient against (Psi(x + h e_i) - Psi(x - h e_i)) / 2h in exact arithmetic
    (error O(h^2) = 1e-12 here): the oracle below is right before it judges the code."""
    x = [F(7, 4), F(9, 2), F(3, 2), F(5, 2), F(13, 4)]
    h = F(1, 10**6)
    for i, g in enumerate(_grad_psi_D(x)):
        up = [v + (h if j == i else 0) for j, v in enumerate(x)]
        dn = [v - (h if j == i else 0) for j, v in enumerate(x)]
        assert float((_psi_D(up) - _psi_D(dn)) / (2 * h)) == pytest.approx(float(g), rel=1e-9, abs=1e-12), i


@pytest.mark.parametrize("level", [0.95, 0.9])
@pytest.mark.parametrize("run", ["a", "ab"])
def test_long_excursion_estimates_are_the_exact_delta_method(level, run):
    """Every number of ``long_excursion_estimates`` (and sigma of ``delta_method``) against the exact
    delta method with the analytic gradient, at N = 4 (a divisor N - 1 moves a half-width by 15%) and
    N = 10.  Kills E01-E16, E18 and E23 (Psi_D terms, the paper's Psi, the quantile, sqrt(N), the
    covariance's cross terms, divisor and products, the mean-duration CI, the mean half duration, sigma,
    the gradient's point, the M0 CI's level); the existing tests killed them too, by other oracles."""
    U, t, th = (A_U, A_T, A_H) if run == "a" else (A_U + B_U, A_T + B_T, A_H + B_H)
    want, sigma_D = _oracle(U, t, th, level)
    got = long_excursion_estimates(_sums(U, t, th), level)
    assert got.keys() == want.keys()
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-12), k
    assert isinstance(got["n_excursions"], int)
    # delta_method itself, on numpy's mean and covariance (divisor N) of X = (U, U^2, t, Ut, t^2)
    X = np.array([[float(u), float(u * u), float(s), float(u * s), float(s * s)] for u, s in zip(U, t)]).T
    S, C = X.mean(axis=1), np.cov(X, bias=True)
    D, half, sigma = delta_method(psi_D, S, C, len(U), level)
    assert (D, half, sigma) == pytest.approx((want["D"], want["D_ci"], sigma_D), rel=1e-12)
    assert delta_method(psi_M, S, C, len(U), level)[1] == pytest.approx(want["M0_ci"], rel=1e-12)


def _result(U, t, th, seed, level=0.95, **kw):
    """An EstimateResult of a run with the excursions (U, t): its own numbers (physical units), as a real
    run's (a pooling that averages the runs' D or CIs gives another number than the pooled excursions')."""
    e, _ = _oracle(U, t, th, level)
    base = dict(D=e["D"] * D0, D_ci=e["D_ci"] * D0, M0=e["M0"] * V0, M0_ci=e["M0_ci"] * V0,
                mean_duration=e["mean_duration"] * TAU0, mean_duration_ci=e["mean_duration_ci"] * TAU0,
                n_excursions=len(U), n_truncated=0, method="di", h=1e-3, dtype="float64", seed=seed, wall_s=1.0,
                lane_steps_per_s=1.0, params=PARAMS, sums=_sums(U, t, th), ci_level=level, version="test")
    return dj.EstimateResult(**{**base, **kw})


@pytest.mark.parametrize("level", [0.95, 0.9])
def test_combine_is_the_exact_estimate_of_the_pooled_excursions_in_physical_units(level):
    """Two runs (N = 4 and 6, drifts of opposite signs), Gamma = 2, Delta = 3: the pool's D, M0, mean
    duration and all three CIs are the exact delta method on the 10 excursions, times D0 = 8/81,
    v0 = 2/3, tau0 = 2/9 (written out); at the runs' ci_level 0.9 the pool's CIs are 90% ones.  Its sums
    are the runs' (t_half too) and its truncated count theirs.  Kills C01 (D_ci in v0), C02 (M0_ci in u0),
    C03 (mean_duration_ci not in s), C04 (D in u0^2), C05 (mean duration in u0), C06 (D as the N-weighted
    mean of the runs' D), C07 (D_ci pooled by inverse variance), C08 (truncated counts of the later runs
    dropped), C09 (ci_level ignored), C10 (t_half not pooled), C11 (M0_ci as the N-weighted runs' CIs)."""
    a = _result(A_U, A_T, A_H, 1, level, n_truncated=2)
    b = _result(B_U, B_T, B_H, 2, level, n_truncated=3)
    c = combine_estimates([a, b])
    want, _ = _oracle(A_U + B_U, A_T + B_T, A_H + B_H, level)
    got = (c.D, c.D_ci, c.M0, c.M0_ci, c.mean_duration, c.mean_duration_ci)
    assert got == pytest.approx((want["D"] * D0, want["D_ci"] * D0, want["M0"] * V0, want["M0_ci"] * V0,
                                 want["mean_duration"] * TAU0, want["mean_duration_ci"] * TAU0), rel=1e-12)
    assert (c.n_excursions, c.n_truncated, c.ci_level) == (10, 5, level)
    assert c.sums == pytest.approx(_sums(A_U + B_U, A_T + B_T, A_H + B_H), rel=1e-15)
    # one run pools to itself: its own numbers, unit for unit
    one = combine_estimates([a])
    assert (one.D, one.D_ci, one.M0, one.M0_ci, one.mean_duration, one.mean_duration_ci) == pytest.approx(
        (a.D, a.D_ci, a.M0, a.M0_ci, a.mean_duration, a.mean_duration_ci), rel=1e-12)


def _big_run(rng, n, seed):
    t = rng.exponential(1.0, n) + 0.25
    U = 0.2 * t + np.sqrt(t) * rng.standard_normal(n)
    return _result([F(0)] * 3, [F(1)] * 3, [F(0)] * 3, seed, n_excursions=n, sums=_sums(U, t, 0.5 * t))


def test_the_pools_small_n_note_is_at_its_threshold():
    """The pool warns below MIN_RELIABLE_N = 10^4 excursions and not at it: 5000 + 5000 gives no note,
    5000 + 4999 the note for 9999.  Kills C12 (<= for <)."""
    rng = np.random.default_rng(12)
    a, b, c = _big_run(rng, 5000, 1), _big_run(rng, 5000, 2), _big_run(rng, 4999, 3)
    notes = lambda r: [w for w in r.warnings if w.startswith("n_excursions = ")]  # noqa: E731
    assert dj.estimators.MIN_RELIABLE_N == 10_000
    assert notes(combine_estimates([a, b])) == []
    assert notes(combine_estimates([a, c])) == [small_n_note(9999)]


def test_replicate_coverage_on_two_hand_made_replicates():
    """Two replicates of two lanes each (the first of run b's 6 excursions, the second of run a's 4) at
    level 0.9, D_true = 4, M_true = -2: replicate b covers D (|3.23 - 4| < 1.94) and misses M0 (|-0.62 + 2| =
    1.38 > 0.97, but < D's CI 1.94); replicate a misses both.  So coverage_D = 0.5, coverage_M0 = 0, the
    mean relative half-width is that of the exact 90% CIs over D_true, and the smallest replicate has 4.
    Kills R01 (M0 judged by D's CI), R02 (half-width relative to the estimate), R03 (level ignored), R04
    (min_size the first replicate's).  The calibration test that uses this function is slow and checks
    only loose coverage bands."""
    lanes = [(B_U[:3], B_T[:3], B_H[:3]), (B_U[3:], B_T[3:], B_H[3:]), (A_U[:2], A_T[:2], A_H[:2]),
             (A_U[2:], A_T[2:], A_H[2:])]
    arr = np.array([[_sums(*x)[k] for k in STAT_NAMES] for x in lanes])
    rep_b, _ = _oracle(B_U, B_T, B_H, 0.9)
    rep_a, _ = _oracle(A_U, A_T, A_H, 0.9)
    D_true, M_true = 4.0, -2.0
    # the margins the docstring states (hits and misses far from the CI boundary)
    assert abs(rep_b["D"] - D_true) < 0.5 * rep_b["D_ci"] and abs(rep_a["D"] - D_true) > 1.5 * rep_a["D_ci"]
    assert rep_b["M0_ci"] < abs(rep_b["M0"] - M_true) - 0.3 < rep_b["D_ci"] - 0.6
    assert abs(rep_a["M0"] - M_true) > 2 * rep_a["D_ci"]
    c = replicate_coverage(arr, STAT_NAMES, 2, D_true, M_true, level=0.9)
    assert (c["replicates"], c["coverage_D"], c["coverage_M0"]) == (2, 0.5, 0.0)
    assert c["rel_half_width"] == pytest.approx((rep_b["D_ci"] + rep_a["D_ci"]) / 2 / D_true, rel=1e-12)
    assert (c["min_size"], c["mean_size"]) == (4, 5.0)


def test_a_pool_of_pools_keeps_the_units():
    """A pooled result pools further with a third run: the same numbers as pooling the three at once,
    in physical units (a second conversion of a pool's D, or none, would show here).  Kills C01-C05."""
    third_U, third_T, third_H = [F(1, 2), F(5, 2)], [F(3, 4), F(2)], [F(1, 4), F(1)]
    a, b = _result(A_U, A_T, A_H, 1), _result(B_U, B_T, B_H, 2)
    c = _result(third_U, third_T, third_H, 3)
    nested = combine_estimates([combine_estimates([a, b]), c])
    want, _ = _oracle(A_U + B_U + third_U, A_T + B_T + third_T, A_H + B_H + third_H)
    got = (nested.D, nested.D_ci, nested.M0, nested.M0_ci, nested.mean_duration, nested.mean_duration_ci)
    assert got == pytest.approx((want["D"] * D0, want["D_ci"] * D0, want["M0"] * V0, want["M0_ci"] * V0,
                                 want["mean_duration"] * TAU0, want["mean_duration_ci"] * TAU0), rel=1e-12)
