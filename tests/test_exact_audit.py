r"""Exact white-noise results, the OU step and the DI step against independent oracles (mutation audit).

Every expected value here is computed from a defining formula of MODEL_NOTES section 2 / paper section 6.2 by
scipy quadrature (or written by hand), never taken from the code under test:

* the stationary density and the exact M0, E[V^2] and D for finite :math:`\tau_L` in *physical* units
  (:math:`\Gamma, \Delta \ne 1`, so a wrong unit power shows), by nested quadrature of
  :math:`D = (2/\Gamma)\int F^2/p`;
* Touchette's propagator against its Fokker-Planck equation (finite differences, both sides of the kink at 0),
  and the stationary correlation against :math:`C(t) = \int v_0 p_s(v_0) \langle v(t)\rangle_{v_0} dv_0`;
* the OU pair's mean and covariance from the defining integrals of :math:`\mathrm{Cov}(X_s, X_{s'})`, on both
  sides of the series switch r = 1 and of the white-noise switch r = 1e8;
* one DI step in each branch of the soft threshold (stuck, released, sliding, stopped, reversed; both signs),
  with dyadic inputs whose results are exact, and the DI model's thresholds.
"""
import math
import warnings

import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate

from dryfric_jax import Params, theory
from dryfric_jax.di import make_di_model
from dryfric_jax.ou import ou_moments, ou_step

# --------------------------------------------------------------------------------------------------------
# stationary density, M0, E[V^2], D (physical units)
# --------------------------------------------------------------------------------------------------------
G_PHYS, DELTA_PHYS = 2.0, 0.5  # tau0 = 8, v0 = 4, D0 = 64


def _psi(u, Gamma, Delta, tau_L, gbar):
    """log of the unnormalised density, MODEL_NOTES section 2 (physical units; tau_L = inf allowed)."""
    return -u * u / (2 * Gamma * tau_L) - Delta * abs(u) / Gamma + gbar * u / Gamma


def _q(f, a, b, epsrel=1e-13):
    """quad at epsrel 1e-13; its round-off warning (the kink of p at 0 under 1e-13) is expected."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        return integrate.quad(f, a, b, epsabs=0, epsrel=epsrel, limit=400)[0]


class _Law:
    r"""p, m, E[V^2] and D of the white-noise law by plain nested quadrature in physical units.  The
    integration variable is w = v/v0 (v0 = Gamma/Delta, an exact change of variables: dv = v0 dw)."""

    def __init__(self, Gamma, Delta, tau_L, gbar):
        self.v0 = Gamma / Delta
        self.Gamma = Gamma
        self.psi = lambda w: _psi(w * self.v0, Gamma, Delta, tau_L, gbar)
        mode = 0.0 if math.isinf(tau_L) or abs(gbar) <= Delta else math.copysign(abs(gbar) - Delta, gbar) * tau_L
        self.cuts = sorted({0.0, mode / self.v0})
        self.z = self._sum(lambda w: math.exp(self.psi(w)))
        self.p = lambda w: math.exp(self.psi(w)) / self.z / self.v0  # density in v
        self.m = self.v0 * self.v0 * self._sum(lambda w: w * self.p(w))
        self.m2 = self.v0 ** 3 * self._sum(lambda w: w * w * self.p(w))

    def _sum(self, f, cuts=()):
        pts = sorted(set(self.cuts) | set(cuts))
        pieces = [(-np.inf, pts[0]), *zip(pts[:-1], pts[1:]), (pts[-1], np.inf)]
        return sum(_q(f, a, b) for a, b in pieces)

    def D(self):
        """(2/Gamma) int F^2/p dv, F(v) = int_{-inf}^v (u - m) p(u) du taken from the nearer tail
        (-int_v^inf for v > m): MODEL_NOTES section 2."""
        m_w = self.m / self.v0

        def F_over_p(w):  # F(v)/p(v) in units of v0 * v0 (du = v0 dw, u - m = v0 (w - m_w))
            g = lambda u: (u - m_w) * math.exp(self.psi(u) - self.psi(w))  # noqa: E731
            if w > m_w:
                return -sum(_q(g, a, b, 1e-11) for a, b in self._pieces_from(w, np.inf))
            return sum(_q(g, a, b, 1e-11) for a, b in self._pieces_from(-np.inf, w))

        # int F^2/p dv = int p(v) (F/p)^2 dv, with dv = v0 dw and F/p = v0^2 F_over_p(w)
        integrand = lambda w: self.p(w) * self.v0 * (self.v0 * self.v0 * F_over_p(w)) ** 2  # noqa: E731
        return 2.0 / self.Gamma * self._sum(integrand, (m_w,))

    def _pieces_from(self, a, b):
        inner = [c for c in self.cuts if a < c < b]
        pts = [a, *inner, b]
        return list(zip(pts[:-1], pts[1:]))


# (tau_L', gamma_bar'): the strong-damping mean (tau_L' <= 1) with |g'| < 1/2 and >= 1/2, the quadrature
# (tau_L' > 1), a bias beyond the friction, and one whose bump lies > 8 widths from 0 (extra break points)
LAWS = [(0.5, 0.3), (0.25, -0.8), (3.0, 0.3), (3.0, -0.7), (3.0, 1.7), (5.0, -6.0)]


def _params(tl_nd, g_nd):
    return Params.from_nondim(1e-3, tl_nd, g_nd, Gamma=G_PHYS, Delta=DELTA_PHYS)


@pytest.mark.parametrize("tl_nd,g_nd", LAWS + [(math.inf, 0.4), (math.inf, -0.9)])
def test_stationary_density_is_the_model_notes_law_in_physical_units(tl_nd, g_nd):
    p = _params(tl_nd, g_nd)
    law = _Law(p.Gamma, p.Delta, p.tau_L, p.gamma_bar)
    w = np.array([-7.0, -1.3, -0.2, 0.0, 0.15, 0.9, 4.0]) + law.cuts[-1]
    got = theory.stationary_density(w * law.v0, p)
    want = [law.p(x) for x in w]
    np.testing.assert_allclose(got, want, rtol=1e-11, atol=0)


#: exact_D is checked on three of the laws (it takes ~1.5 s each): the mean of the strong-damping formula,
#: the quadrature's, and the one with the extra break points
D_LAWS = [(0.25, -0.8), (3.0, -0.7), (5.0, -6.0)]


@pytest.mark.parametrize("tl_nd,g_nd", LAWS)
def test_exact_moments_and_D_equal_a_plain_nested_quadrature(tl_nd, g_nd):
    r"""exact_M0, exact_mean_square_velocity and exact_D for finite tau_L against :class:`_Law` (physical units,
    scipy quad at epsrel 1e-13, no series, no erfcx, no tail scaling): to 1e-11 (moments) and 1e-9 (D)."""
    p = _params(tl_nd, g_nd)
    law = _Law(p.Gamma, p.Delta, p.tau_L, p.gamma_bar)
    assert theory.exact_M0(p) == pytest.approx(law.m, rel=1e-11, abs=0)
    assert theory.exact_mean_square_velocity(p) == pytest.approx(law.m2, rel=1e-11, abs=0)
    if (tl_nd, g_nd) in D_LAWS:
        assert theory.exact_D(p) == pytest.approx(law.D(), rel=1e-9, abs=0)


def test_closed_forms_without_damping_equal_the_nested_quadrature():
    """tau_L = inf (closed forms) in physical units, same oracle."""
    for g_nd in (0.0, 0.45, -0.8):
        p = _params(math.inf, g_nd)
        law = _Law(p.Gamma, p.Delta, p.tau_L, p.gamma_bar)
        assert theory.exact_M0(p) == pytest.approx(law.m, rel=1e-11, abs=1e-14)
        assert theory.exact_mean_square_velocity(p) == pytest.approx(law.m2, rel=1e-11, abs=0)
        assert theory.exact_D(p) == pytest.approx(law.D(), rel=1e-9, abs=0)


@pytest.mark.parametrize("tl_nd,g_nd", [(1e6, 0.9), (1e6, -0.95), (0.01, 0.5), (math.inf, 0.99), (3.0, -0.7)])
def test_law_width_covers_both_tails(tl_nd, g_nd):
    """``theory._scale`` (which sizes chain_law's grid) is the *wider* side's decay length: p's mass beyond
    30 of them is below 1e-12 on each side (a lopsided law, |g'| -> 1, is 1/(1 - |g'|) wide on one side)."""
    itl = 0.0 if math.isinf(tl_nd) else 1.0 / tl_nd
    L = 30.0 * theory._scale(itl, g_nd)
    law = _Law(1.0, 1.0, tl_nd, g_nd)
    assert law._sum(law.p, (-L, L)) == pytest.approx(1.0, rel=1e-12)
    assert _q(law.p, -np.inf, -L) < 1e-12 and _q(law.p, L, np.inf) < 1e-12


# --------------------------------------------------------------------------------------------------------
# Touchette: propagator, correlation
# --------------------------------------------------------------------------------------------------------
def _fp_residual(v, t, v0, d=3e-4):
    r""":math:`\partial_t p - \partial_v(\mathrm{sgn}(v)\,p) - \partial_v^2 p` by central differences (v != 0,
    |v| > d): the Fokker-Planck equation of :math:`dv = -\mathrm{sgn}(v)\,dt + \sqrt2\,dW`.  Truncation
    ~d^2 (measured: ~1e-6 of max p at d = 3e-4, scaling as d^2 from 1e-2 to 1e-4), round-off ~eps/d^2 ~ 2e-9."""
    P = lambda vv, tt: float(theory.propagator(vv, tt, v0))  # noqa: E731
    dt = (P(v, t + d) - P(v, t - d)) / (2 * d)
    dv = (P(v + d, t) - P(v - d, t)) / (2 * d)
    dvv = (P(v + d, t) - 2 * P(v, t) + P(v - d, t)) / (d * d)
    return dt - math.copysign(1.0, v) * dv - dvv


@pytest.mark.parametrize("t,v0", [(0.3, 0.8), (1.0, -1.5), (2.5, 0.0), (6.0, 2.0)])
def test_propagator_solves_the_fokker_planck_equation(t, v0):
    """The propagator solves the FP equation on both sides of 0, and at 0 its flux -sgn(v) p - dp/dv is
    continuous: dp/dv(0+) - dp/dv(0-) = -2 p(0) (one-sided 2nd-order differences)."""
    P = lambda vv: float(theory.propagator(vv, t, v0))  # noqa: E731
    scale = max(P(x) for x in np.linspace(-4, 4, 81))
    for v in (-3.1, -1.2, -0.4, 0.35, 0.9, 2.7):
        if abs(v - v0) > 0.05:  # away from the initial point (large derivatives for small t)
            assert abs(_fp_residual(v, t, v0)) < 1e-5 * scale, v
    d = 1e-4
    right = (-3 * P(0.0) + 4 * P(d) - P(2 * d)) / (2 * d)
    left = (3 * P(0.0) - 4 * P(-d) + P(-2 * d)) / (2 * d)
    assert right - left == pytest.approx(-2 * P(0.0), abs=1e-6 * scale)


def test_propagator_relaxes_to_the_stationary_laplace_law():
    """t -> inf: p -> e^{-|v|}/2 (the stationary law of dv = -sgn v dt + sqrt2 dW), from either side."""
    v = np.array([-3.0, -0.5, 0.0, 0.7, 2.0])
    for v0 in (-1.0, 2.0):
        np.testing.assert_allclose(theory.propagator(v, 400.0, v0), np.exp(-np.abs(v)) / 2, rtol=1e-10)


@pytest.mark.parametrize("t", [0.0, 0.3, 1.0, 4.0, 20.0])
def test_correlation_is_the_stationary_average_of_the_first_moment(t):
    r""":math:`C(t) = \int v_0 \tfrac12 e^{-|v_0|}\langle v(t)\rangle_{v_0}\,dv_0 = \int_0^\infty v_0 e^{-v_0}
    \langle v(t)\rangle_{v_0} dv_0` (the mean is odd in v0): C's closed form against Touchette's first moment,
    which test_theory checks against the propagator's mean and Table 1."""
    want = _q(lambda a: a * math.exp(-a) * float(theory.first_moment(t, a)), 0.0, np.inf)
    assert float(theory.correlation(t)) == pytest.approx(want, rel=1e-9, abs=0)


# --------------------------------------------------------------------------------------------------------
# OU pair: mean and covariance from their defining integrals
# --------------------------------------------------------------------------------------------------------
def _ou_defining_integrals(h, tau):
    r"""For :math:`\tau dX = -X dt + \sqrt2 dW`: :math:`E[X_s | X_0 = x] = x e^{-s/\tau}` and, for
    :math:`s' \le s`, :math:`\mathrm{Cov}(X_{s'}, X_s) = \tau^{-1} e^{-(s-s')/\tau}(1 - e^{-2s'/\tau})`.
    Returns ``(m1, m2, S11, S12, S22)`` of :math:`(h^{-1}\int_0^h X, X_h)` by quadrature (S11 over the
    triangle s' <= s, where the integrand is smooth, times 2)."""
    cov = lambda sp, s: math.exp(-(s - sp) / tau) * -math.expm1(-2 * sp / tau) / tau  # noqa: E731
    m1 = _q(lambda s: math.exp(-s / tau), 0.0, h) / h
    S11 = 2 * integrate.dblquad(lambda sp, s: cov(sp, s), 0.0, h, 0.0, lambda s: s, epsabs=0, epsrel=1e-12)[0] / h**2
    S12 = _q(lambda sp: cov(sp, h), 0.0, h) / h
    return m1, math.exp(-h / tau), S11, S12, cov(h, h)


# both sides of the series switch (r = 1) and well inside each branch
@pytest.mark.parametrize("r", [1e-3, 0.3, 0.999, 1.001, 4.0, 30.0])
def test_ou_step_is_the_pair_law_of_the_defining_integrals(r):
    """ou_moments, and ou_step's factor applied by ``sample`` to unit normals, against the quadrature:
    sample(x, 0, 0) = x m, sample(0, 1, 0) = (L11, L21), sample(0, 0, 1) = (0, L22), and L L^T = Sigma
    entrywise (1e-9)."""
    tau, x = 0.7, 1.3
    m1, m2, S11, S12, S22 = _ou_defining_integrals(r * tau, tau)
    got = [float(a) for a in ou_moments(r * tau, tau)]
    np.testing.assert_allclose(got, [m1, m2, S11, S12, S22], rtol=1e-10, atol=0)
    s = ou_step(r * tau, tau)
    assert [float(c) for c in s.sample(jnp.float64(x), 0.0, 0.0)] == pytest.approx([x * m1, x * m2], rel=1e-10)
    col1 = np.array([float(c) for c in s.sample(jnp.float64(0.0), 1.0, 0.0)])
    col2 = np.array([float(c) for c in s.sample(jnp.float64(0.0), 0.0, 1.0)])
    assert col2[0] == 0.0 and col1[0] > 0 and col2[1] > 0  # lower triangular, positive diagonal
    cov = np.outer(col1, col1) + np.outer(col2, col2)
    np.testing.assert_allclose(cov, [[S11, S12], [S12, S22]], rtol=1e-9, atol=0)


@pytest.mark.parametrize("r", [1e7, 1e9])
def test_ou_step_white_noise_limit_on_both_sides_of_r_1e8(r):
    r"""r = h/tau >> 1: Sigma = tau^{-1}[[2/r - 3/r^2, 1/r], [1/r, 1]] up to e^{-r} (0 in float64 here), i.e.
    h Var(Xi) -> 2 (the integral of the noise correlation, MODEL_NOTES section 1)."""
    tau = 1e-3
    s = ou_step(r * tau, tau)
    L11, L21, L22 = (float(c) for c in (s.L11, s.L21, s.L22))
    np.testing.assert_allclose([L11**2, L11 * L21, L21**2 + L22**2], [(2 - 3 / r) / r / tau, 1 / r / tau, 1 / tau],
                               rtol=1e-13)
    assert float(s.m1) == pytest.approx(1 / r, rel=1e-15) and float(s.m2) == 0.0


# --------------------------------------------------------------------------------------------------------
# DI step by hand
# --------------------------------------------------------------------------------------------------------
H = 0.0625  # nondimensional step (the largest allowed is 0.1 min(1, tau_L')): dyadic inputs, exact results


def _di(tl_nd, g_nd):
    """Physical units other than 1 (tau0 = 1/2, gamma_bar = 2 g'), so that a unit slip shows."""
    p = Params.from_nondim(4.0, tl_nd, g_nd, Gamma=2.0, Delta=2.0)
    return make_di_model(p, H * p.tau0)


# (V, Xi, V_next) for tau_L = inf, gamma_bar' = -1/2: w = V + (Xi - 1/2)/16, V' = sgn(w) max(|w| - 1/16, 0)
HAND = [(0.0, 0.5, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 0.0),  # stuck (w = 0, 1/32, -1/32)
        (0.0, 24.5, 1.4375), (0.0, -23.5, -1.4375),  # released up / down (w = +-1.5)
        (0.0, 1.5, 0.0), (0.0, -0.5, 0.0),  # |w| = h exactly: stays stuck (both signs)
        (0.0, 1.5 + 2**-20, 2**-24), (0.0, -0.5 - 2**-20, -2**-24),  # just past it: released
        (1.0, 0.5, 0.9375), (-1.0, 0.5, -0.9375),  # sliding on, both signs (w = +-1)
        (0.0625, -0.5, 0.0), (-0.0625, 2.5, 0.0),  # sliding to a stop (w = 0, w = h)
        (0.03125, -0.5, 0.0), (-0.03125, 1.5, 0.0),  # ... and with 0 < |w| < h (w = -1/32, 1/32)
        (0.03125, -1.5, -0.03125), (-0.03125, 4.5, 0.15625)]  # reversal through 0 (w = -0.09375, 0.21875)


def test_di_step_each_branch_of_the_soft_threshold_by_hand():
    m = _di(math.inf, -0.5)
    assert float(m.inv_tau_L) == 0.0 and float(m.h) == H and float(m.gamma_bar) == -0.5
    for v, xi, want in HAND:
        assert float(m.step(jnp.float64(v), jnp.float64(xi))) == want, (v, xi)
    # viscous term, tau_L' = 2, gamma_bar' = 1/2: w = +-1 + (1/2 -+ 1/2 +- 1/2)/16 = +-1.03125, both signs
    m = _di(2.0, 0.5)
    assert float(m.inv_tau_L) == 0.5
    assert float(m.step(jnp.float64(1.0), jnp.float64(0.5))) == 0.96875
    assert float(m.step(jnp.float64(-1.0), jnp.float64(-1.5))) == -0.96875


@pytest.mark.parametrize("g_nd", [0.3, -0.6])
def test_di_model_thresholds_and_start(g_nd):
    r"""Noise thresholds :math:`x_{\pm} = \pm 1 - \bar\gamma'` (a stuck particle moves up when
    :math:`\bar\gamma' + X > 1`): C_+ holds x_+ and not x_-, C_- the reverse; lanes start stuck at x_+.
    The model's OU step is the nondimensional one, (h', tau') = (1/16, 4), from the defining integrals."""
    m = _di(2.0, g_nd)
    m1, _, S11, S12, S22 = _ou_defining_integrals(H, 4.0)
    L11, L21, L22 = (float(c) for c in (m.ou.L11, m.ou.L21, m.ou.L22))
    assert float(m.ou.m1) == pytest.approx(m1, rel=1e-12) and float(m.ou.m2) == pytest.approx(math.exp(-H / 4))
    np.testing.assert_allclose([L11**2, L11 * L21, L21**2 + L22**2], [S11, S12, S22], rtol=1e-9)
    xp, xm = 1.0 - g_nd, -1.0 - g_nd
    assert float(m.x_plus) == pytest.approx(xp, rel=1e-15)
    assert bool(m.plus.contains(xp)) and not bool(m.plus.contains(xm))
    assert bool(m.minus.contains(xm)) and not bool(m.minus.contains(xp))
    X, V = m.init_state(3)
    assert np.all(np.asarray(X) == float(m.x_plus)) and np.all(np.asarray(V) == 0.0)


# --------------------------------------------------------------------------------------------------------
# the white-noise values say so when the params carry a correlation time they ignore (a user audit: given
# Fig. 3's params, exact_D returned 0.0227 without a word, 8.5x the colored-noise D)
# --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("f", [theory.exact_D, theory.exact_M0, theory.exact_mean_square_velocity,
                               lambda p: theory.stationary_density(0.01, p)])
def test_white_noise_values_warn_when_given_a_tau_they_ignore(f):
    from dryfric_jax import DryfricWarning
    G, D = 5.0, 3.84
    tau0 = G / D**2
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        at = f(Params(G, D, 1e-3 * tau0, 0.067, 0.342))  # tau/tau0 = 1e-3 (rounded at most 1 ulp): white
        quiet = [w for w in ws if issubclass(w.category, DryfricWarning)]
        above = f(Params(G, D, 1.01e-3 * tau0, 0.067, 0.342))
    said = [str(w.message) for w in ws if issubclass(w.category, DryfricWarning)]
    assert not quiet and len(said) == 1 and "white-noise (tau -> 0) value" in said[0] and "not used" in said[0]
    assert at == above  # the value itself does not depend on tau
    assert ws[-1].filename == __file__  # said at the caller's line


def test_cli_theory_says_tau_is_not_used_in_its_help_and_warns_nothing(capsys):
    from dryfric_jax.cli import main
    for argv in (["theory"], ["theory", "--h", "0.001"]):  # Fig. 3's tau = 0.5 s: the library's warning silenced
        assert main(argv) == 0
        out = capsys.readouterr()
        assert out.err == "" and out.out.startswith("white-noise D  = ")
    with pytest.raises(SystemExit):
        main(["theory", "--help"])
    assert "--tau is not used" in capsys.readouterr().out
