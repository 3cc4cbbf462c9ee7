r"""Mutation audit of :mod:`dryfric_jax.chain_law` against an independent discretisation of the same chain.

The oracle is written from the chain's definition (chain_law's module docstring), not from its code:
:math:`w = v + h(\bar\gamma' - v/\tau_L') + \sqrt{2h}Z`, :math:`V' = \mathrm{sign}(w)\max(|w| - h, 0)`.  It is
Ulam's cell method, not Nystrom's: cells of width d on each half line plus the atom at 0, the chain started
from each cell's centre, the probability of landing in a cell an exact difference of normal cdfs (so every
column sums to 1 without renormalising; the outermost cells take the tails).  D comes from the Green-Kubo
sum of the velocity's autocovariance, :math:`D = h\,[2\sum_{k \ge 0} C_k - C_0]` with :math:`C_k =
\mathrm{Cov}_\pi(V_0, V_k)`, i.e. from :math:`U_N = h\sum V_n` (the trapezoid sum differs from it by the
bounded :math:`h(V_N - V_0)/2`), with the sum taken in the forward direction by one linear solve.

Its error is :math:`O(d^2)` (midpoint sources and centres): it is run at d = s/6 and s/12 (s the step-noise
sd) and Richardson-extrapolated; the tolerance is the fine result's estimated error :math:`|f_{12} - f_6|/3`
(a bound on the extrapolation's higher-order remainder) plus twice chain_law's documented grid error
(1e-4 relative at 8 nodes per sd).  Measured at the cases below: chain_law is within 0.05-0.09 tolerances of
the extrapolation for M0, E[V^2] and D, 0.3 for P(V = 0); the tolerances are 6e-4 (M0), 1.0-1.2e-3 (E[V^2]),
5e-4 (P(V = 0)) and 1.3-1.5e-3 (D) relative.
Units: Gamma = 2, Delta = 3, so tau0 = 2/9 s, v0 = 2/3 m/s and D0 = 8/81 m^2/s all differ from 1 (with
Gamma/Delta^2 = 1, as in test_chain_law's unit test, a physical h used for the nondimensional one passed).
"""
import math
import re

import numpy as np
import pytest
from scipy import linalg, special

import dryfric_jax as dj
import dryfric_jax.chain_law as cl
from dryfric_jax.chain_law import white_chain_law

GRID_REL = 2e-4  # twice chain_law's documented grid error at its default 8 nodes per sd


def _phi_cdf(z):
    return 0.5 * special.erfc(-z / math.sqrt(2))


def _ulam(itl, g, h, d, L):
    """Transition matrix P[i, j] (j -> i), stationary law and cell values of the chain on cells of width d
    over [-L, L]; index K is the atom at 0."""
    K = int(round(L / d))
    e = np.arange(K + 1) * d
    c = 0.5 * (e[1:] + e[:-1])
    v = np.concatenate([-c[::-1], [0.0], c])
    s = math.sqrt(2 * h)
    m = v + h * (g - itl * v)
    ep = e.copy()
    ep[-1] = np.inf
    pos = np.diff(_phi_cdf((ep[:, None] + h - m[None, :]) / s), axis=0)  # y in [e_i, e_i+1) <=> w - h there
    neg = -np.diff(_phi_cdf((-ep[:, None] - h - m[None, :]) / s), axis=0)  # y in (-e_i+1, -e_i] <=> w + h there
    atom = _phi_cdf((h - m) / s) - _phi_cdf((-h - m) / s)
    P = np.concatenate([neg[::-1], atom[None, :], pos])
    n = v.size
    A = P - np.eye(n)
    A[K] = 1.0  # a balance equation is redundant: normalise instead
    rhs = np.zeros(n)
    rhs[K] = 1.0
    return P, linalg.solve(A, rhs), v


def _oracle(itl, g, h, nps, L=20.0):
    """(E V, E V^2, P(V = 0), D) of the Ulam chain with nps cells per step-noise sd."""
    P, pi, v = _ulam(itl, g, h, math.sqrt(2 * h) / nps, L)
    mean = pi @ v
    mu = pi * (v - mean)  # a signed measure of total mass 0: sum_k P^k mu converges
    n = v.size
    x = linalg.solve(np.eye(n) - P + np.outer(pi, np.ones(n)), mu)  # sum_k P^k mu (1.x = 0 for 1.mu = 0)
    D = h * (2 * (v @ x) - v @ mu)
    return np.array([mean, pi @ v**2, pi[n // 2], D])


def _extrapolated(itl, g, h):
    f6, f12 = _oracle(itl, g, h, 6), _oracle(itl, g, h, 12)
    return (4 * f12 - f6) / 3, np.abs(f12 - f6) / 3


# (tau_L', gamma_bar'): Fig. 5's point, and a stronger bias of the other sign (M0 = -0.64: a drift term of
# the wrong sign or a D off by a multiple of h M0^2 shows); both with the drag 1/tau_L' at h' = 0.1
CASES = [(6.17472, 0.0890625), (6.17472, -0.5)]


@pytest.mark.parametrize("tl,g", CASES)
def test_chain_law_equals_an_independent_ulam_discretisation(tl, g):
    """M0, E[V^2], P(V = 0) and D at h' = 0.1 against the Ulam/Green-Kubo oracle (module docstring), in
    physical units with tau0 != 1.  Kills the trapezoid's full end weight at 0+- (``hw[0] = dv``: E[V^2] 4%
    off), ``a = dU + mu - ...`` and ``a = dU - ...`` / ``mu = 0`` (D off by 4 h M0^2 or h M0^2: 3% and 0.8%
    at gamma_bar' = -0.5) and the atom's probability from the physical h (``_norm_cdf((h - m) / s)``). ~3 s."""
    p = dj.Params.from_nondim(1e-4, tl, g, Gamma=2.0, Delta=3.0)
    h = 0.1
    ref, err = _extrapolated(1 / tl, g, h)
    law = white_chain_law(p, h * p.tau0)
    got = np.array([law.M0 / p.v0, law.mean_v2 / p.v0**2, law.p_stuck, law.D / p.D0])
    tol = err + GRID_REL * np.abs(ref)
    assert np.all(np.abs(got - ref) <= tol), f"chain_law {got}, oracle {ref} +- {tol}"


def test_the_step_a_refusal_suggests_is_the_smallest_that_fits():
    """The refusal says 'h must be in [X, ...]': X is 1% above the smallest step whose grid fits MAX_NODES, printed to
    3 digits, so 2% below it (1% below the smallest) is refused in turn.  test_chain_law checks that X
    fits; this checks that X is not needlessly large.  Kills ``need = 1.0 * (...)`` (X twice the
    smallest step: 0.98 X was accepted). ~0.1 s on the code; the mutant solves a 4300-node grid first."""
    p = dj.Params.from_nondim(1e-4, *CASES[0])
    with pytest.raises(ValueError, match="for the chain law") as err:
        white_chain_law(p, 1e-4 * p.tau0)
    x = float(re.search(r"h must be in \[(\S+),", str(err.value)).group(1))
    with pytest.raises(ValueError, match="would exceed"):
        white_chain_law(p, 0.98 * x)


@pytest.mark.parametrize("ratio,fits", [(499.5, False), (498.5, True)])
def test_the_node_bound_is_the_documented_grid_against_max_nodes(monkeypatch, ratio, fits):
    """The grid (module docstring): trapezoid nodes at spacing s / nodes_per_sd on [-L, 0-] and [0+, L] plus
    the atom, L = width widths of the law + 10 step-noise sds (MAX_NODES_PER_SD's comment), so 2 ceil(L / dv)
    + 3 nodes.  At b = 0 (tau_L = inf, gamma_bar = 0) the law is exp(-|v|)/2, of width 1: with width = 15 and
    4 nodes per sd, L / dv = 60 / s + 40.  With MAX_NODES set to 1001, L / dv = 499.5 needs 1003 nodes and is
    refused; L / dv = 498.5 needs exactly 1001 and is solved with that many.  Kills ``2 * kf + 1 >
    MAX_NODES`` (1003 accepted), ``math.floor(ratio)`` (999 nodes: the grid stops short of L) and a margin of
    5 sds instead of 10 (981 nodes). ~0.5 s.  The grid's own check is tested: the range check before it
    (``_check_chain_h``, 1% above the least h that fits) is bypassed here."""
    from dryfric_jax.plan import check_h

    monkeypatch.setattr(cl, "MAX_NODES", 1001)
    monkeypatch.setattr(cl, "_check_chain_h", lambda params, h, *a: check_h(params, h))
    s = 60 / (ratio - 40)
    p = dj.Params.from_nondim(1e-4, math.inf, 0.0)
    h = 0.5 * s * s * p.tau0
    if fits:
        assert white_chain_law(p, h, nodes_per_sd=4, width=15.0).n_nodes == 1001
    else:
        with pytest.raises(ValueError, match="1e\\+03 grid nodes > 1001"):
            white_chain_law(p, h, nodes_per_sd=4, width=15.0)


def test_D_to_richardson_accuracy_at_a_strong_bias():
    """D at tau_L' = 1, gamma_bar' = 0.9, h' = 0.1 (a drift-dominated law: the chain is farthest from
    reversible there, measured over six cases), both sides Richardson-extrapolated: chain_law at 8 and 16
    nodes per sd (its O(dv^2) grid error, 1.6e-4 relative at 8, cancels), the oracle at 6, 12 and 24 cells
    per sd.  Tolerance: chain_law's Richardson correction |c16 - c8| / 3 (4e-5 relative; a bound on the
    extrapolation's higher-order remainder) plus the oracle's |R(12, 24) - R(6, 12)| (3e-7 relative);
    measured gap 6e-9 relative.  Kills ``a = dU - mu + g(V_n) - g(V_n+1)``, the Poisson correction with the wrong sign:
    for a reversible chain E[(dU - mu)(g(V_n+1) - g(V_n))] = 0 with the symmetric trapezoid dU, so the sign
    only shows through the chain's irreversibility, O(h): 2.0e-4 of D here (1e-4 at Fig. 5's point, below
    the other tests' bands). ~5 s."""
    tl, g, h = 1.0, 0.9, 0.1
    p = dj.Params.from_nondim(1e-4, tl, g, Gamma=2.0, Delta=3.0)
    f6, f12, f24 = (_oracle(1 / tl, g, h, n, L=15.0)[3] for n in (6, 12, 24))
    r1, r2 = (4 * f12 - f6) / 3, (4 * f24 - f12) / 3
    c8, c16 = (white_chain_law(p, h * p.tau0, nodes_per_sd=n, width=15.0).D / p.D0 for n in (8, 16))
    rc = (4 * c16 - c8) / 3
    tol = abs(c16 - c8) / 3 + abs(r2 - r1)
    assert abs(rc - r2) <= tol, f"chain_law {rc:.9g} (8: {c8:.9g}, 16: {c16:.9g}), oracle {r2:.9g} +- {tol:.2g}"
