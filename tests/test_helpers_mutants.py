"""Mutation audit of four small number-producing helpers: ``figures.common.exact_steps``, the
closed split set of ``regeneration.SplitSet.contains``, ``figures.speed_error.fit_slope`` and
``figures.diffusivity.local_exponent``, each against an independent oracle (hand-picked
floating-point traps, numpy.polyfit, a hand-written delta method).  Each docstring names the
mutants it kills; the existing tests killed every other mutant of the audit."""
import math

import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax.figures.common import exact_steps
from dryfric_jax.figures.diffusivity import local_exponent
from dryfric_jax.figures.speed_error import fit_slope
from dryfric_jax.ou import ou_step
from dryfric_jax.regeneration import split_set


@pytest.mark.parametrize("t,h,n", [(0.3, 0.1, 3), (0.7, 0.1, 7), (2.3, 0.1, 23), (3.3, 1.1, 3),  # t/h just below n
                                   (0.07, 0.01, 7), (0.27, 0.09, 3), (0.33, 0.03, 11),  # t/h just above n
                                   (0.05, 5e-4, 100), (0.05, 2e-3, 25), (3e-10, 1e-10, 3)])
def test_exact_steps_rounds_through_floating_point_traps(t, h, n):
    """0.3 / 0.1 = 2.9999999999999996 and 3 * 0.1 = 0.30000000000000004; 0.07 / 0.01 =
    7.000000000000001: the count is the nearest whole number and the time is compared with a
    relative tolerance, not for equality.  Kills ``n = int(t / h)`` (floor: refused 0.3, 0.1),
    ``n = math.ceil(t / h)`` (refused 0.07, 0.01) and ``n * h != t`` (refused 0.3, 0.1)."""
    got = exact_steps(t, h)
    assert got == n and type(got) is int


@pytest.mark.parametrize("t,h", [(1.5e-10, 1e-10), (0.125, 0.003),  # 1.5 and 41.7 steps
                                 (1e-4, 1.5e-4), (0.125, 2e-3),  # 0.67 and 62.5 steps
                                 (1.0 + 1e-7, 0.1)])  # off by 1e-7 relative
def test_exact_steps_refuses_a_near_miss_at_every_scale(t, h):
    """A time that is not a whole number of steps is refused whatever its scale.  Kills an absolute
    tolerance ``abs(n * h - t) > 1e-9`` (accepted t = 1.5e-10, h = 1e-10 as 2 steps, simulating
    2e-10) and a half-step one ``abs(n * h - t) > 0.5 * h`` (accepted t = 0.125, h = 0.003 as 42
    steps, 0.126, and t = 1e-4, h = 1.5e-4 as one step)."""
    with pytest.raises(ValueError, match="whole number of steps"):
        exact_steps(t, h)


@pytest.mark.parametrize("t,h,n", [(np.float32(0.5), 0.125, 4), (np.int64(3), 0.25, 12), (1, np.float32(0.125), 8),
                                   (np.float64(0.3), np.float64(0.1), 3), (0.5, np.array(0.125), 4)])
def test_exact_steps_takes_numpy_scalars(t, h, n):
    """A numpy float32 or int64 (a value read from an array) is the number it holds: 0.5 and 0.125
    are exact in float32, so 4 steps.  Was refused as "t and h must be finite numbers" (the check
    asked for a Python int or float)."""
    got = exact_steps(t, h)
    assert got == n and type(got) is int


@pytest.mark.parametrize("t,h", [(True, 0.5), (1.0, True), (np.bool_(True), 0.5), ("1", 0.5), (None, 0.5)])
def test_exact_steps_refuses_what_is_no_time(t, h):
    """A bool is no time (True was taken as t = 1: 2 steps of 0.5), nor a string or None."""
    with pytest.raises(ValueError, match="must be finite numbers > 0"):
        exact_steps(t, h)


def test_split_set_is_closed():
    """C = [c1, c2] (module docstring): both ends belong to it, their float neighbours outside do
    not.  Kills strict inequalities in ``SplitSet.contains`` (``x > c1`` and ``x < c2``)."""
    for tau in (1.0, 1e-4):
        s = split_set(ou_step(1e-2, tau), 0.3, tau)
        c1, c2 = s.c1, s.c2
        assert bool(s.contains(c1)) and bool(s.contains(c2)) and bool(s.contains(s.center))
        assert not bool(s.contains(jnp.nextafter(c1, -jnp.inf))) and not bool(s.contains(jnp.nextafter(c2, jnp.inf)))


def _polyfit_oracle(x, y, reps):
    """Slope and SE from numpy.polyfit on log-log data with weights 1/sigma = sqrt(2 R): the larger of
    the SE with known sigma (cov='unscaled') and the one scaled by chi2 / (n - 2) (cov=True)."""
    lx, ly = np.log(x), np.log(y)
    w = np.ones_like(lx) if reps is None else np.sqrt(2.0 * np.asarray(reps, float))
    coef, cov_u = np.polyfit(lx, ly, 1, w=w, cov="unscaled")
    _, cov_s = np.polyfit(lx, ly, 1, w=w, cov=True)
    se_known = math.sqrt(cov_u[0, 0]) if reps is not None else 0.0
    return coef[0], max(se_known, math.sqrt(cov_s[0, 0]))


@pytest.mark.parametrize("case", ["residuals win", "propagated wins", "no replicates"])
def test_fit_slope_against_polyfit(case):
    """Five points, unequal replicates 1..64, against numpy.polyfit (weights, unscaled and scaled
    covariance).  Kills (as do the existing hand-computed tests) sigma = 1/sqrt(R) or 1/(2R), weights
    1/sigma, unweighted chi2 or covariance, dof n or n - 1, a missing sqrt on either SE, no max."""
    rng = np.random.default_rng(7)
    x = np.geomspace(1e3, 1e7, 5)
    reps = None if case == "no replicates" else np.array([64, 16, 4, 2, 1])
    noise = {"residuals win": 1.0, "propagated wins": 1e-3, "no replicates": 0.3}[case]
    y = 5.0 * x**-0.5 * np.exp(noise * rng.standard_normal(5))
    want = _polyfit_oracle(x, y, reps)
    got = fit_slope(x, y, reps)
    assert got == pytest.approx(want, rel=1e-10)
    if reps is not None:  # the case exercises the branch it names
        se_prop = math.sqrt(np.polyfit(np.log(x), np.log(y), 1, w=np.sqrt(2.0 * reps), cov="unscaled")[1][0, 0])
        assert (got[1] > se_prop * 1.01) == (case == "residuals win")


def test_local_exponent_against_a_hand_written_delta_method():
    """Uneven Gamma steps, a D that is no power law and unequal CIs, against a scalar loop:
    s = (ln D1 - ln D0) / (ln G1 - ln G0), half-width sqrt((c1/D1)^2 + (c0/D0)^2) / (ln G1 - ln G0)
    (c/D the half-width of ln D to first order), at sqrt(G0 G1).  Kills (as do the existing tests)
    an arithmetic midpoint, CIs added linearly, divided by sqrt 2 or times 1.96, a crossed D index,
    a one-sided relative difference and a D at the geometric mean."""
    G = [0.25, 0.4, 1.1, 3.0, 8.0]
    D = [0.02, 0.09, 0.5, 4.0, 30.0]
    c = [0.001, 0.02, 0.01, 0.9, 0.0]
    gm, s, ci = local_exponent(G, D, c)
    for i in range(4):
        dl = math.log(G[i + 1]) - math.log(G[i])
        assert gm[i] == pytest.approx(math.sqrt(G[i] * G[i + 1]), rel=1e-14)
        assert s[i] == pytest.approx((math.log(D[i + 1]) - math.log(D[i])) / dl, rel=1e-13)
        assert ci[i] == pytest.approx(math.hypot(c[i + 1] / D[i + 1], c[i] / D[i]) / dl, rel=1e-13)
