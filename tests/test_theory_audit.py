r"""Exact white-noise D and M0 at hard parameters (a theory audit against 30-digit mpmath found four
defects, each pinned here by a test that failed before the fix; elsewhere the package matched mpmath
to ~1e-15).

1. M0 with :math:`\tau_L' > 1` and a small :math:`|\bar\gamma'|` lost :math:`\epsilon/|\bar\gamma'|`
   (1.1e-4 at 1e-12) and was 0.0 at 1e-300.
2. A nondimensional D' or M0' below float64's normal range, scaled by a large unit, lost digits
   (1.1e-5 of D at :math:`\tau_L' = 10^{-160}`) or came back 0.0.
3. D's that float64 holds were refused (D = 2e-200, 2e300) because D' alone left the range.
4. :math:`|\bar\gamma'| = 1` at :math:`\tau_L' \ge 10^{160}` raised a raw ``OverflowError``.

The oracles are independent of the code paths they check: linear response
(:math:`dM_0'/d\bar\gamma'|_0 = E_0[V'^2]`, a different quadrature), the closed form
:func:`~dryfric_jax.theory.D_viscous_only` (:math:`2\Gamma\tau_L^2`) and the drift's mean velocity
:math:`\bar\gamma\tau_L`, which strong damping approaches, and the quadrature against the asymptote.
"""
import math
import warnings

import pytest

from dryfric_jax import theory
from dryfric_jax.params import Params


def P(Gamma, Delta, tl_nd, g_nd):
    """Params from nondimensional tau_L' and gamma_bar' at physical Gamma and Delta (white noise)."""
    tau0 = Gamma / Delta / Delta
    return Params(Gamma, Delta, 1e-9 * tau0, tl_nd * tau0, g_nd * Delta)


def close(x, want, rel):
    """|x/want - 1| <= rel (pytest.approx adds an absolute 1e-12, which a 0.0 for 1e-280 passed)."""
    return want != 0 and abs(x / want - 1.0) <= rel


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


@pytest.mark.parametrize("tl", [2.0, 1e3, 1e6])
def test_a_tiny_bias_gives_m0_by_linear_response(tl):
    r"""p ∝ exp(ψ0(v) + γ̄' v): :math:`M_0'(\bar\gamma') = \bar\gamma' E_0[V'^2] + O(\bar\gamma'^3)`, with
    :math:`E_0[V'^2]` from the second-moment quadrature at γ̄' = 0.  At γ̄' = ±1e-12 and 1e-300 (Γ = Δ = 1)
    M0/γ̄ matches it to 1e-12 (it was 1.1e-4 off at 1e-12, and M0 was 0.0 at 1e-300)."""
    slope = theory.exact_mean_square_velocity(P(1.0, 1.0, tl, 0.0))
    for g in (1e-12, -1e-12, 1e-300):
        assert close(theory.exact_M0(P(1.0, 1.0, tl, g)) / g, slope, 1e-12), g


@pytest.mark.parametrize("tl", [1e-160, 1e-200, 1e-250])
def test_strong_damping_d_is_the_viscous_closed_form_where_d_prime_leaves_the_range(tl):
    r"""At :math:`\tau_L' \le 10^{-160}` D' is below 2.2e-308 but D is not (Γ = 1e100, Δ = 1e25):
    D = 2Γτ_L² (:func:`D_viscous_only`) to 1e-14 (the friction's share is :math:`O(\sqrt{\tau_L'})`).
    It lost 1.1e-5 at 1e-160 and refused 1e-200 ("D underflows").  At 1e-300, D = 2e-400 itself
    underflows and is refused."""
    p = P(1e100, 1e25, tl, 0.5)
    assert close(theory.exact_D(p), theory.D_viscous_only(p.Gamma, p.tau_L), 1e-14)
    with pytest.raises(ValueError, match=r"^D underflows float64 .*\|D\| ~ 1e-(399|400)"):
        theory.exact_D(P(1e100, 1e25, 1e-300, 0.5))


@pytest.mark.parametrize("g", [0.0, 0.5, -0.999999, 2.0, 1e5])
def test_the_strong_damping_asymptote_matches_the_quadrature_where_it_takes_over(g):
    r"""Below :data:`VISCOUS_TAU_L_ND` exact_D takes :math:`D' = 2\tau_L'^2(1 - 2\sqrt{2\tau_L'/\pi})`; the
    quadrature (a different method) gives the same at the switch, 1e-30, and at 1e-25, to 1e-13."""
    for tl in (theory.VISCOUS_TAU_L_ND, 1e-25):
        asym = 2 * tl * tl * (1 - 2 * math.sqrt(2 * tl / math.pi))
        assert close(theory._exact_D_nd(1 / tl, g), asym, 1e-13), tl
    assert close(theory.exact_D(P(1.0, 1.0, theory.VISCOUS_TAU_L_ND, g)),
                 theory._exact_D_nd(1 / theory.VISCOUS_TAU_L_ND, g), 1e-13)


def test_strong_damping_m0_is_the_drifts_mean_velocity_below_the_normal_range():
    r"""Γ = 1e100, Δ = 1e50, τ_L' = 1e-300: M0' ~ 1e-320 is subnormal but M0 is not; it is
    :math:`\bar\gamma\tau_L` to 1e-14 (the friction's share is :math:`O(\sqrt{\tau_L'})`).  It lost 1.1e-5 at
    γ̄' = 1e-20 and was 0.0 at 1e-30."""
    for g in (1e-20, -1e-20, 1e-30):
        p = P(1e100, 1e50, 1e-300, g)
        assert close(theory.exact_M0(p), p.gamma_bar * p.tau_L, 1e-14), g


def test_the_linear_limit_gives_a_d_that_float64_holds_where_d_prime_does_not():
    r"""γ̄' = 2 at τ_L' = 1e200 (Γ = 1e-20, Δ = 1e10): the friction never acts, D = 2Γτ_L² = 2e300; it was
    refused ("D overflows") because D' = 2e400."""
    p = P(1e-20, 1e10, 1e200, 2.0)
    assert close(theory.exact_D(p), theory.D_viscous_only(p.Gamma, p.tau_L), 1e-14)


@pytest.mark.parametrize("g", [1.0, -1.0])
def test_a_nondimensional_overflow_is_a_valueerror_naming_d(g):
    r"""|γ̄'| = 1 at τ_L' = 1e160 and 1e200: D' ≈ 3.4 τ_L'² is past float64 in any units; a ValueError
    naming D and the nondimensional parameters (it was a raw ``OverflowError``).  At 1e150, D' = 3.36e299
    is returned (the audit's value)."""
    for tl in (1e160, 1e200):
        with pytest.raises(ValueError, match=r"^D overflows float64 in nondimensional units .*tau_L' = 1e\+"):
            theory.exact_D(P(1.0, 1.0, tl, g))
    assert close(theory.exact_D(P(1.0, 1.0, 1e150, g)), 3.36e299, 0.01)
