r"""Mutation audit of :mod:`dryfric_jax.params`: the validation's messages and edges, ``from_nondim``'s
own checks, the numpy-scalar helpers, and ``inv_tau_L``.

Expected values are worked out by hand from the definitions (module docstring, MODEL_NOTES section 1):
:math:`\tau_0 = \Gamma/\Delta^2`, :math:`\tau = \tau'\tau_0`, :math:`\tau_L = \tau_L'\tau_0`,
:math:`\bar\gamma = \bar\gamma'\Delta`.  Units: Gamma = 2, Delta = 3 (tau0 = 2/9 s, in
:class:`fractions.Fraction`), or Gamma = 2, Delta = 4 (tau0 = 1/8 s, a power of two, so that
tau' = tau/tau0 lands exactly on the edges 1e-300 and 1e300 of SCALE_RANGE).

The checks are layered: a value one check lets through is often refused by a later one (an infinite
tau or gamma_bar by _check_scales, a negative Delta in from_nondim by Params itself), but under another
name or with the wrong valid range.  So the refusals here pin the whole first line of the message.
Each test's docstring names the mutants (edits of params.py) it kills; 66 were tried, the other
tests killed 39 and 5 are equivalent.
"""
import json
import math
from fractions import Fraction as F

import jax
import numpy as np
import pytest

from dryfric_jax.params import Params, check_finite, check_positive, plain_number, real_or_none, shown

# Gamma = 2, Delta = 3: tau0 = Gamma/Delta^2 = 2/9 s (hand arithmetic)
TAU0 = F(2, 9)
BASE = dict(Gamma=2.0, Delta=3.0, tau=1.0, tau_L=0.5, gamma_bar=0.25)


@pytest.mark.parametrize("field,bad,msg", [
    ("Gamma", math.inf, r"^Gamma must be finite and > 0 \(got inf\)"),
    ("Delta", math.inf, r"^Delta must be finite and > 0 \(got inf\)"),
    ("tau", math.inf, r"^tau must be finite and > 0 \(got inf\)"),
    ("tau_L", -math.inf, r"^tau_L must be > 0 or inf \(got -inf\)"),
    ("gamma_bar", math.inf, r"^gamma_bar must be a finite number \(got inf\)"),
    ("gamma_bar", -math.inf, r"^gamma_bar must be a finite number \(got -inf\)"),
    ("gamma_bar", math.nan, r"^gamma_bar must be a finite number \(got nan\)"),
])
def test_non_finite_fields_are_refused_by_their_own_check(field, bad, msg):
    """An infinite Gamma or tau, or a non-finite gamma_bar, is caught by _check_scales too, but as
    "Gamma and Delta must keep tau0 ..." or "gamma_bar must keep |gamma_bar/Delta| <= 1e300": the
    field's own check must say it first.  Kills allow_inf=True on Gamma (M20) or on tau (M19),
    check_finite accepting inf (``math.isnan(v)``, M17), the gamma_bar check dropped from
    __check_init__ (M22) and check_finite's message no longer saying "finite" (M66)."""
    with pytest.raises(ValueError, match=msg):
        Params(**(BASE | {field: bad}))


def test_check_finite_refuses_inf_and_nan_by_name():
    """Kills ``math.isnan(v)`` in check_finite (M17: inf accepted) directly, without Params' later checks."""
    for bad in (math.inf, -math.inf, math.nan):
        with pytest.raises(ValueError, match="^v0 must be a finite number"):
            check_finite("v0", bad)
    check_finite("v0", -1e300)


def test_traced_gamma_bar_is_validated_on_the_concrete_call():
    """gamma_bar under jit: check_finite must leave a tracer alone (Params' own __check_init__ runs on
    it).  gamma_bar' = 1.5/3 = 0.5.  Kills check_finite without its ``v is not None`` guard (M18:
    ``math.isfinite(None)``, a TypeError)."""
    f = jax.jit(lambda g: Params(2.0, 3.0, 1.0, gamma_bar=g).gamma_bar_nd)
    assert float(f(1.5)) == 0.5
    assert np.array_equal(jax.vmap(lambda g: Params(2.0, 3.0, 1.0, gamma_bar=g).gamma_bar_nd)(np.array([3.0, -6.0])),
                          [1.0, -2.0])


@pytest.mark.parametrize("kw,expect", [
    (dict(tau=1e-300 / 8), "tau"),  # tau' = (1e-300/8)/(1/8) = 1e-300, the bottom of SCALE_RANGE
    (dict(tau=1e300 / 8), "tau"),  # tau' = 1e300, the top
    (dict(tau_L=1e-300 / 8), "tau_L"),
    (dict(tau_L=1e300 / 8), "tau_L"),
    (dict(gamma_bar=4 * 1e300), "gamma_bar"),  # gamma_bar' = 4e300/4 = 1e300 (scaling by 4 is exact)
    (dict(gamma_bar=-4 * 1e300), "gamma_bar"),
])
def test_scale_range_is_closed(kw, expect):
    """SCALE_RANGE = [1e-300, 1e300] is a closed range (the message says "in [1e-300, 1e300]",
    "<= 1e300"): with Gamma = 2, Delta = 4 (tau0 = 1/8 s exactly) the edges are reached exactly and
    accepted, the next float beyond them refused.  Kills ``lo < x`` (M31) and ``x < hi`` (M32) in
    _check_scales and ``|gamma_bar/Delta| < hi`` (M34)."""
    p = Params(**(dict(Gamma=2.0, Delta=4.0, tau=1.0, tau_L=1.0, gamma_bar=0.0) | kw))
    assert p.tau0 == 0.125
    nd = dict(tau=p.tau_nd, tau_L=p.tau_L_nd, gamma_bar=p.gamma_bar_nd)[expect]
    assert abs(nd) in (1e-300, 1e300)
    outside = math.nextafter(abs(nd), 0.0 if abs(nd) < 1.0 else math.inf)
    unit = dict(tau=0.125, tau_L=0.125, gamma_bar=4.0)[expect]
    with pytest.raises(ValueError, match=f"^{expect} must keep"):
        Params(**(dict(Gamma=2.0, Delta=4.0, tau=1.0, tau_L=1.0, gamma_bar=0.0) | {expect: outside * unit}))


def test_inv_tau_L_is_in_physical_units():
    """inv_tau_L = 1/tau_L in s^-1 (the drift is -v/tau_L), not 1/tau_L' = tau0/tau_L: tau_L = 0.5 s
    gives 2 s^-1 (1/tau_L' would be (2/9)/0.5 = 4/9).  Kills ``1.0 / self.tau_L_nd`` (M45)."""
    assert Params(**BASE).inv_tau_L == 2.0
    assert Params(**(BASE | dict(tau_L=0.125))).inv_tau_L == 8.0


def test_from_nondim_scales_by_float64_units_whatever_the_type_of_gamma_and_delta():
    """tau = tau' Gamma/Delta^2, tau_L = tau_L' Gamma/Delta^2 and gamma_bar = gamma_bar' Delta with
    Gamma = 2, Delta = 3 given as float32 (or ints): tau' = 1.5 -> 1/3 s, tau_L' = 0.75 -> 1/6 s,
    gamma_bar' = 0.5 -> 1.5.  Kills computing tau0 in float32 (``Gamma, Delta = Gamma, Delta``,
    M56: tau0 = float32(2/9), 1e-8 off)."""
    want = dict(Gamma=2.0, Delta=3.0, tau=float(F(3, 2) * TAU0), tau_L=float(F(3, 4) * TAU0), gamma_bar=1.5)
    for G, D in ((np.float32(2.0), np.float32(3.0)), (np.int64(2), np.int64(3)), (2, 3)):
        got = Params.from_nondim(1.5, 0.75, 0.5, Gamma=G, Delta=D).as_dict()
        assert got == pytest.approx(want, rel=1e-15, abs=0.0)


@pytest.mark.parametrize("kw,msg", [
    (dict(Gamma=0.0), r"^Gamma must be finite and > 0 \(got 0.0\)"),
    (dict(Gamma=-2.0), r"^Gamma must be finite and > 0 \(got -2.0\)"),
    (dict(Gamma=math.inf), r"^Gamma must be finite and > 0 \(got inf\)"),
    (dict(Delta=0.0), r"^Delta must be finite and > 0 \(got 0.0\)"),  # Gamma/0/0: a ZeroDivisionError
    (dict(Delta=math.nan), r"^Delta must be finite and > 0 \(got nan\)"),
])
def test_from_nondim_checks_gamma_and_delta_by_name(kw, msg):
    """from_nondim checks its own Gamma and Delta before it divides by them.  Without those checks a
    zero, negative or infinite Gamma makes tau0 <= 0 or inf ("Gamma and Delta must keep tau0 ..."), a
    zero Delta a ZeroDivisionError in _tau0.  Kills dropping ``check_positive("Gamma", Gamma)`` (M55)
    and ``check_positive("Delta", Delta)`` (M54) from from_nondim."""
    with pytest.raises(ValueError, match=msg):
        Params.from_nondim(1.0, **kw)


def test_from_nondim_refuses_an_overflowing_tau0_as_such():
    """Gamma = 1e200, Delta = 1e-100: tau0 = 1e200/1e-200 = 1e400 overflows.  It must be refused as
    the unit out of range, not as "tau must keep tau' x its unit finite" (the user gave tau' = 1).
    Kills dropping the upper bound of the tau0 check (``lo <= tau0``, M53)."""
    with pytest.raises(ValueError, match=r"^Gamma and Delta must keep tau0 = Gamma/Delta\^2 in \[1e-300, 1e\+300\]"):
        Params.from_nondim(1.0, Gamma=1e200, Delta=1e-100)


def test_from_nondim_overflow_guard_uses_delta_as_the_unit_of_gamma_bar():
    """gamma_bar = gamma_bar' Delta: its guard must multiply by Delta, not tau0.  Gamma = 1e10,
    Delta = 1: tau0 = 1e10 s and gamma_bar' = 1e300 gives gamma_bar = 1e300, representable (with
    tau0 as unit the guard saw 1e310 and refused it).  Gamma = 1e20, Delta = 1e10: tau0 = 1 s and
    gamma_bar = 1e300 x 1e10 overflows: refused by the guard, by name and with its unit.  Kills the
    guard's unit ``("gamma_bar", gamma_bar, tau0)`` (M51)."""
    p = Params.from_nondim(1.0, gamma_bar=1e300, Gamma=1e10, Delta=1.0)
    assert (p.tau, p.gamma_bar, p.gamma_bar_nd) == (1e10, 1e300, 1e300)
    msg = r"^gamma_bar must keep gamma_bar' x its unit finite \(got gamma_bar' = 1e\+300 with unit 1e\+10\)"
    with pytest.raises(ValueError, match=msg):
        Params.from_nondim(1.0, gamma_bar=1e300, Gamma=1e20, Delta=1e10)


@pytest.mark.parametrize("args, kw, msg", [
    # tau' = 1e-300 is in range, but tau = 1e-310 is subnormal: it was refused as "tau' ... got 9.99e-301 ... tau =
    # 1e-310", numbers the user never gave
    ((1e-300, 1.0), dict(Gamma=1e-10), r"^tau must keep tau' x its unit above 2.23e-308 \(got tau' = 1e-300 with "
                                       r"unit 1e-10\): choose a larger Gamma or a smaller Delta$"),
    # tau_L = 1e-330 underflowed to 0 and was refused as "tau_L must be > 0 or inf (got 0.0)"
    ((1.0, 1e-320), dict(Gamma=1e-10), r"^tau_L' must lie in \[1e-300, 1e\+300\] \(got 1e-320\)"),
    ((1e-301,), {}, r"^tau' must lie in \[1e-300, 1e\+300\] \(got 1e-301\)"),
    ((1.0, 2e301), {}, r"^tau_L' must lie in \[1e-300, 1e\+300\] \(got 2e\+301\)"),
    # tau' = 1e300 exactly: tau/tau0 rounds to 1.0000000000000002e300; the message says what it came from
    ((1e300,), dict(Gamma=1e5), r"^tau must keep tau' = tau/tau0 in .* \(from_nondim's tau' = 1e\+300, tau_L' = inf, "
                                r"gamma_bar' = 0.0 in units tau0 = 100000.0 s, Delta = 1.0\)$"),
    ((1e200,), dict(Gamma=1e200),
     r"^tau must keep tau' x its unit finite .*: choose a smaller Gamma or a larger Delta$"),
])
def test_from_nondim_names_the_nondimensional_numbers_it_was_given(args, kw, msg):
    """from_nondim checks tau' and tau_L' as given (in the scale range, and times tau0 a normal float) before it
    makes the physical Params, and an error of Params itself names the nondimensional numbers behind it.  The last
    case: a larger Delta, not "a smaller Delta" (tau0 = Gamma/Delta^2)."""
    with pytest.raises(ValueError, match=msg):
        Params.from_nondim(*args, **kw)


@pytest.mark.parametrize("u", [np.uint8(2), np.uint16(2), np.uint32(2), np.uint64(2), np.array(2, dtype=np.uint8)])
def test_unsigned_integers_are_real_numbers(u):
    """The docstrings accept "an int, a numpy scalar, a 0-d array": unsigned ones too.  Gamma = 2,
    Delta = 3: tau0 = 2/9, and from_nondim with tau' = 2: tau = 4/9 s.  Params' converter makes a
    float of the field first, but from_nondim and check_positive (t of the API) call _concrete on it
    as given.  Kills dtype kind "if" instead of "iuf" in _concrete (M03) and in real_or_none (M10)."""
    assert Params(u, 3.0, 1.0).tau0 == pytest.approx(float(TAU0), rel=1e-15)
    assert Params.from_nondim(u, Gamma=u, Delta=3.0).tau == pytest.approx(float(2 * TAU0), rel=1e-15)
    check_positive("t", u)
    assert real_or_none(u) == 2.0 and type(real_or_none(u)) is float
    assert plain_number(u) == 2.0 and type(plain_number(u)) is float


@pytest.mark.parametrize("b", [np.array(True), np.array(False)])
def test_a_0d_boolean_array_is_not_a_number(b):
    """A 0-d bool array is neither a bool nor an np.bool_ (the isinstance tuples miss it): only the
    dtype kind keeps it out.  Kills dtype kind "biuf" in _concrete (M01: Gamma = array(True) read as
    1.0) and in real_or_none (M07: a setting h = array(True) read as 1.0)."""
    with pytest.raises(ValueError, match=r"^Gamma must be a real number \(got array\((True|False)\)\)$"):
        Params(b, 3.0, 1.0)
    assert real_or_none(b) is None and plain_number(b) is b


def test_array_refusals_say_what_to_do_instead():
    """An array of a model parameter is a grid (one Params per point, or the sweep); any other array
    (t of first_moment, say) is one call per value.  Kills the inverted ``name not in _FIELDS`` (M04)."""
    with pytest.raises(ValueError, match=r"^tau_L must be a real number \(got an array of shape \(2,\)\): make one "
                                         r"Params per grid point \(or run 'dryfric sweep'\)$"):
        Params(2.0, 3.0, 1.0, tau_L=np.array([0.5, 1.0]))
    with pytest.raises(ValueError, match=r"^t must be a real number \(got an array of shape \(3,\)\): call once per "
                                         r"value$"):
        check_positive("t", np.ones(3))


def test_as_dict_gives_python_floats_for_a_params_out_of_jit():
    """A Params returned from a jitted function holds jax arrays (the pytree is rebuilt without the
    converter); as_dict is what the CLI and bench write to JSON, so it must give Python floats.
    Hand values: the inputs.  Kills ``{k: getattr(self, k) ...}`` without float() (M58)."""
    q = jax.jit(lambda p: p)(Params(**BASE))
    d = q.as_dict()
    assert all(type(v) is float for v in d.values())
    assert json.loads(json.dumps(d)) == BASE


def test_shown_keeps_up_to_width_characters():
    """repr('a' * 58) is 60 characters, the width: kept whole; 61 are cut to the first 24 (the
    opening quote and 23 letters) and the length.  Kills ``len(text) < width`` (M62)."""
    assert shown("a" * 58) == "'" + "a" * 58 + "'"
    assert shown("a" * 59) == "'" + "a" * 23 + "... (61 characters)"
