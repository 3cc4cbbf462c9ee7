"""Mutation audit of dryfric_jax/ou.py (the exact OU step: m(h), Sigma(h), the series of ghat, the
stable 2x2 Cholesky factor, OUStep.sample/astype, the reference in decimal) and dryfric_jax/di.py (the
DI step, move, the lane-engine interface of DIModel, the coin, make_di_model).

106 one-line mutants (54 in ou.py, 52 in di.py) run with pytest -x against test_ou.py,
test_exact_audit.py, test_stress.py::test_ou_step_matrix, test_bruteforce_mutants.py,
test_internals_audit.py, test_di_step.py and test_regeneration.py, and the survivors touching the
engine interface against test_engine.py -k "rebuild or fused or default_event_layout or di_durations"
(test_di_exact.py, 160 s, and the rest of test_engine.py were not used).

* 84 killed before: 79 by the files above (series coefficients, signs and cut at 10 terms, the r < 1 and
  r > 1e8 switches moved to 10 and to 1e4 < r, every closed form of m, Sigma and L, the argument checks,
  the sample's pairing of the normals, the step, the trapezoid, the candidate rule, the coin's set and
  normals, thresholds, units and casts of make_di_model), 5 by test_engine.py (start_regenerated and
  regen_after_step flipped, cpu_events "branch", fused_quiet False, draw_lanes on the coin's key half).
* 12 equivalent: O7/O8 the white-noise switch at 1e4 or 1e12 instead of 1e8 (e^{-r} is 0 in both
  dtypes there and r^2 does not overflow float32 below 1e12: both forms agree to rounding); O9 the
  series also at r = 1 (series and closed form both accurate there); O15 the switch ``r >= 1e8``
  (same at r = 1e8); O12/O16/O21 the placeholders of the branches that ``where`` discards (5.0 for
  0.5, rb = r for r > 1e8, rh = 0: values only, never selected); O45 the ``max(., 0)`` around
  ghat p - q^2 dropped (measured: never negative in rounding, 2e5 r in [1e-320, 1e300] in float64 and
  [1e-45, 1e30] in float32); D7 the soft threshold as sign(w) max(|w| - h, 0) (differs only by -0,
  which compares and adds as 0); D33 ``log u <= log r`` (a tie has probability 0, and log r = 0 is
  never reached by u < 1); D36 check_params dropped (check_h checks params first); D44 itl = 1/tau_L'
  for tau_L' = inf (Python gives 0.0).
* 8 killed only here: the ghat series cut after 20 terms (up to 7 ulp at r -> 1) or used only
  below r = 0.1 (the closed form loses 3 digits at r = 0.1); DIModel.fixed_dt in float32; advance's dU
  in float64 for a float32 model; the coin's uniform with minval 0; make_di_model's dtype taken as
  given and its check_h dropped; the float32 model's OU step (hence its split sets) built in float32.
* 2 alive, not pinned: ou_moments and ou_step converting tau without h's dtype.  They differ only for
  mixed explicit dtypes (a float32 h with a float64-array tau: computed in float64 instead of
  float32); a Python-number tau is weakly typed in both, and no rule for mixed dtypes is documented.

No defect found.  Oracles, all independent of the code under test: the printed closed forms of paper
section 6.2 (ghat, m, Sigma) in 60-digit decimal arithmetic with the 2x2 Cholesky factor and
regeneration's a = L^{-1} m and half width written out; numpy float32 arithmetic for the trapezoid;
the documented contracts (fixed_dt float64, dU in the simulation dtype, uniform on [tiny, 1), the
ValueErrors and the default h = 0.01 min(tau0, tau_L) of README "Choosing h").
"""
import math
from decimal import Decimal, localcontext

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import rng
from dryfric_jax.di import make_di_model
from dryfric_jax.ou import ou_moments
from test_di_step import DELTA, GAMMA, GBAR, H, TAU, _model


def _ghat_60_digits(r):
    r"""The printed :math:`\hat g(r) = (2r - 3 + 4e^{-r} - e^{-2r})/r^2` in 60-digit decimal arithmetic
    (the cancellation is beaten by precision), rounded once to float64."""
    with localcontext() as c:
        c.prec = 60
        R = Decimal(repr(float(r)))
        return float((2 * R - 3 + 4 * (-R).exp() - (-2 * R).exp()) / R**2)


def _pair_law_60_digits(h, tau):
    r"""``(m1, m2, L11, L21, L22)`` of the OU pair from the printed closed forms of paper section 6.2
    (module docstring of ou.py), 60 digits, with the 2x2 lower Cholesky factor written out:
    :math:`L_{11} = \sqrt{\Sigma_{11}}`, :math:`L_{21} = \Sigma_{12}/L_{11}`,
    :math:`L_{22} = \sqrt{\Sigma_{22} - L_{21}^2}`; each rounded once to float64."""
    with localcontext() as c:
        c.prec = 60
        h_, t_ = Decimal(repr(float(h))), Decimal(repr(float(tau)))
        r = h_ / t_
        e1, e2 = (-r).exp(), (-2 * r).exp()
        S11 = t_ / h_**2 * (2 * r - 3 + 4 * e1 - e2)
        S12 = (1 - e1) ** 2 / h_
        S22 = (1 - e2) / t_
        L11 = S11.sqrt()
        L21 = S12 / L11
        L22 = (S22 - L21 * L21).sqrt()
        return tuple(float(v) for v in (t_ / h_ * (1 - e1), e1, L11, L21, L22))


# ------------------------------------------------------------------------------------------ ou.py


def test_the_time_average_variance_is_correctly_rounded_below_the_series_switch():
    r""":math:`\Sigma_{11} = \hat g(r)/\tau` with tau = 1 (an exact division) for 1001 r in [0.05, 1),
    where ou.py sums the Taylor series, against the printed closed form in 60 digits: within 4 ulp
    (Horner's rounding on an alternating series with :math:`\sum|c_j r^j| / \hat g < 5`; measured 2).
    Kills: the series cut after 20 terms instead of 30 (its first dropped term is
    :math:`2^{23} r^{21}/23! \approx 3e-16`, up to 7 ulp at r -> 1), and the series used only below
    r = 0.1 (the printed form loses ~3 digits to cancellation at r = 0.1)."""
    rs = np.concatenate([np.linspace(0.05, 0.999999, 1000), [0.1]])
    got = np.asarray(jax.vmap(lambda h: ou_moments(h, 1.0)[2])(jnp.asarray(rs)))  # a tracer h is not checked
    want = np.array([_ghat_60_digits(r) for r in rs])
    ulps = np.abs(got - want) / np.spacing(want)
    assert ulps.max() <= 4, (rs[ulps.argmax()], ulps.max())


# ------------------------------------------------------------------------------------------ di.py


def test_a_float32_model_keeps_float64_time_and_float32_random_numbers():
    r"""``fixed_dt``: "step length in float64: excursion durations are n h with an integer n", the
    float32 step widened (exactly) to float64; ``random_dtype``: the simulation dtype, float32.
    Kills: ``fixed_dt`` returning the float32 h itself."""
    m32 = _model("float32")
    assert m32.fixed_dt.dtype == jnp.float64 and float(m32.fixed_dt) == float(np.float32(H))
    assert m32.random_dtype == jnp.float32 and m32.h.dtype == jnp.float32


def test_a_float32_models_split_sets_are_the_float64_ones_rounded_once():
    r"""make_di_model builds the OU step and both split sets in float64 and casts them to the
    simulation dtype.  Oracle: regeneration's definitions with the 60-digit pair law
    (:math:`a = L^{-1} m`, :math:`a_1 = m_1/L_{11}`, :math:`a_2 = (m_2 - L_{21} a_1)/L_{22}`, half width
    :math:`w = \min(\kappa/|a|, 4/\sqrt{\tau'})` with :math:`\kappa = 1`, C_+- = x_+- -+ w, x_+- = +-1 -
    gamma_bar'), each rounded once to float32: a float64 value within ~1e-13 of the truth rounds the
    same way unless it lies that close to a float32 midpoint, which these fixed numbers do not.  r =
    h'/tau' = 1e-3.  Kills: the OU step built in the simulation dtype (the split sets' a, |a|^2 and
    bounds then came from float32 arithmetic)."""
    tau, h, gbar = 2.0, 2e-3, 0.25
    p = dj.Params.from_nondim(tau, 3.0, gbar, Gamma=GAMMA, Delta=DELTA)
    m32 = make_di_model(p, h * p.tau0, "float32")
    m1, m2, L11, L21, L22 = _pair_law_60_digits(h, tau)
    with localcontext() as c:
        c.prec = 60
        a1 = Decimal(m1) / Decimal(L11)
        a2 = (Decimal(m2) - Decimal(L21) * a1) / Decimal(L22)
        a_sq = a1 * a1 + a2 * a2
        w = min(1 / a_sq.sqrt(), 4 / Decimal(tau).sqrt())
        for s, x in ((m32.plus, 1 - Decimal(gbar)), (m32.minus, -1 - Decimal(gbar))):
            want = [np.float32(float(v)) for v in (a1, a2, a_sq, x - w, x + w)]
            got = [np.asarray(getattr(s, f)) for f in ("a1", "a2", "a_sq", "c1", "c2")]
            assert all(g.dtype == np.float32 for g in got)
            assert [float(g) for g in got] == [float(v) for v in want]
    assert [float(getattr(m32.ou, f)) for f in ("m1", "m2", "L11", "L21", "L22")] == [
        float(np.float32(v)) for v in (m1, m2, L11, L21, L22)]


def test_the_coin_at_the_smallest_uniform_is_tails_for_a_tiny_ratio(monkeypatch):
    r"""The coin is heads when :math:`\log u < \log r(x, y)` for a uniform u on [tiny, 1) ("from a
    fresh uniform", ``jax.random.uniform(key, (), dt, tiny)``).  At its smallest value u = tiny
    (all-zero bits, as test_internals_audit checks for draw_lanes) and a ratio
    :math:`\log r \approx -2000 < \log(\mathrm{tiny}) = -708.4`, the coin must be tails; with u = 0
    it would be heads for every ratio.  log r from regeneration's definition, C_+ = [c1, c2], x = c2:
    :math:`\min(-d_1 z\cdot a - d_1^2|a|^2/2,\ 0)` with :math:`d_1 = c_2 - c_1`.
    Kills: the coin's uniform drawn with minval 0."""
    m = _model()
    s = m.plus
    monkeypatch.setattr(rng, "uniform", lambda key, dtype, minval=0.0, maxval=1.0: jnp.asarray(minval, dtype))
    x = float(s.c2)
    d1 = x - float(s.c1)
    z1 = 2000.0 / (d1 * float(s.a1))
    log_r = min(-d1 * z1 * float(s.a1) - 0.5 * d1 * d1 * float(s.a_sq), 0.0)
    assert -2100 < log_r < -2000 and math.log(np.finfo(np.float64).tiny) > log_r
    state = (jnp.float64(x), jnp.float64(0.0))
    heads = m.coin(state, (jnp.float64(z1), jnp.float64(0.0)), jnp.bool_(True), jax.random.key(0))
    assert not bool(heads)


def test_advance_gives_the_increment_in_the_simulation_dtype():
    r"""``advance``: "dU = h (V_n + V_{n+1})/2 is in the simulation dtype (move's is float64)".  A
    float32 model from a sliding state: dU is float32 and is the float32 trapezoid of the float32 h
    and velocities (numpy float32 arithmetic, each operation correctly rounded as XLA's), while
    ``move`` without a dtype gives float64.  Kills: advance calling move without the state's dtype."""
    m32 = _model("float32")
    X, V, z1, z2 = (jnp.float32(a) for a in (0.3, 0.25, 0.4, -0.2))
    (Xn, Vn), dU, _, _ = m32.advance((X, V), (z1, z2), jnp.bool_(True))
    assert dU.dtype == jnp.float32 and Vn.dtype == jnp.float32 and float(Vn) > 0
    h, v, vn = np.float32(m32.h), np.float32(V), np.float32(Vn)
    assert float(dU) == float(np.float32(0.5) * h * (v + vn))
    assert m32.move(X, V, z1, z2)[3].dtype == jnp.float64


def test_make_di_model_refuses_bad_arguments_by_name():
    r"""make_di_model's docstring: "ValueError naming the one that is wrong: params a Params, h in
    [1e-12, 0.1]*min(tau0, tau_L) s (None: the default step), dtype float32 or float64".  tau0 = 8
    (Gamma = 2, Delta = 0.5), tau_L = 16: h <= 0.8; the default h is 0.01 min(tau0, tau_L) = 0.08
    (README "Choosing h"), h' = 0.01.  Kills: check_h dropped (h = 1.0 accepted, None a TypeError),
    the dtype taken as given (float16 accepted).  (check_params dropped is equivalent: check_h checks
    params first, the dict line pins that.)"""
    p = dj.Params.from_nondim(TAU, 2.0, GBAR, Gamma=GAMMA, Delta=DELTA)
    assert p.tau0 == 8.0 and p.tau_L == 16.0
    with pytest.raises(ValueError, match="^params must be a dryfric_jax.Params"):
        make_di_model({"Gamma": 2.0, "Delta": 0.5, "tau": 4.0}, 0.08)
    for bad in (1.0, 0.0, -0.08, float("nan")):
        with pytest.raises(ValueError, match=r"^h must be in \[8e-12, 0.8\] s"):
            make_di_model(p, bad)
    for bad in ("float16", jnp.float16, "foo", None):
        with pytest.raises(ValueError, match=r"^dtype must be one of \['float32', 'float64'\]"):
            make_di_model(p, 0.08, bad)
    assert float(make_di_model(p, None).h) == pytest.approx(0.01, rel=1e-15)
    assert make_di_model(p, 0.8, "float32").h.dtype == jnp.float32
