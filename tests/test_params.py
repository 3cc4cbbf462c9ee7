import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import FIG3, Params


def test_reference_units_and_nondim_numbers():
    p = Params(**FIG3)
    assert p.tau0 == pytest.approx(5 / 3.84**2, rel=1e-15)
    assert p.u0 == pytest.approx(25 / 3.84**3, rel=1e-15)
    assert p.tau_nd == pytest.approx(0.5 * 3.84**2 / 5, rel=1e-15)  # 1.47456, the paper's 1.47
    assert p.gamma_bar_nd == pytest.approx(0.342 / 3.84, rel=1e-15)
    assert p.D0 == pytest.approx(p.u0**2 / p.tau0, rel=1e-14)
    assert p.v0 == pytest.approx(p.u0 / p.tau0, rel=1e-14)


def test_nondim_round_trip():
    p = Params(Gamma=0.16, Delta=3.84, tau=1e-5, tau_L=0.067, gamma_bar=0.342)
    nd = p.nondim()
    assert (nd.Gamma, nd.Delta) == (1.0, 1.0)
    back = Params.from_nondim(nd.tau, nd.tau_L, nd.gamma_bar, Gamma=p.Gamma, Delta=p.Delta)
    for k, v in p.as_dict().items():
        assert getattr(back, k) == pytest.approx(v, rel=1e-14)


def test_tau_L_inf_is_proper():
    p = Params(1.0, 1.0, 0.1)
    assert p.tau_L == math.inf and p.inv_tau_L == 0.0 and p.nondim().tau_L == math.inf


@pytest.mark.parametrize("field,bad", [
    ("Gamma", 0.0), ("Gamma", -1.0), ("Gamma", math.nan), ("Gamma", math.inf),
    ("Delta", 0.0), ("Delta", math.nan), ("tau", -1e-3), ("tau", math.inf),
    ("tau_L", 0.0), ("tau_L", -1.0), ("tau_L", math.nan), ("gamma_bar", math.nan), ("gamma_bar", math.inf),
])
def test_validation_names_parameter(field, bad):
    kw = dict(Gamma=1.0, Delta=1.0, tau=1.0, tau_L=1.0, gamma_bar=0.0)
    kw[field] = bad
    with pytest.raises(ValueError, match=field):
        Params(**kw)


def test_thresholds():
    p = Params(Gamma=4.0, Delta=2.0, tau=1.0, gamma_bar=0.5)
    xp, xm = p.x_thresholds
    assert xp == pytest.approx((2.0 - 0.5) / 2.0) and xm == pytest.approx((-2.0 - 0.5) / 2.0)


@pytest.mark.parametrize("bad", ["5", None, True, 1 + 2j, np.array([1.0, 2.0]), np.array([])])
def test_anything_but_a_real_scalar_is_refused_by_name(bad):
    """Before, a string or a bool passed validation (float("5") works) and failed later with a
    TypeError, and None or an array skipped it (taken for a tracer)."""
    with pytest.raises(ValueError, match="^Gamma must be a real number"):
        Params(Gamma=bad, Delta=1.0, tau=1.0)


@pytest.mark.parametrize("G", [5, 5.0, np.float32(5.0), np.int64(5), np.array(5.0), jnp.asarray(5.0)])
def test_real_scalars_of_any_type_are_accepted(G):
    assert float(Params(G, 2.0, 1.0).tau0) == 1.25


def test_traced_parameters_are_validated_on_the_concrete_call():
    f = jax.jit(lambda G: Params(G, 2.0, 1.0).tau_nd)
    assert float(f(5.0)) == pytest.approx(0.8, rel=1e-15)
    assert np.allclose(jax.vmap(lambda G: Params(G, 2.0, 1.0).tau_nd)(jnp.array([1.0, 4.0])), [4.0, 1.0])


@pytest.mark.parametrize("kw,names", [
    (dict(Gamma=1e-300), "Gamma and Delta"),  # tau0 underflows
    (dict(Gamma=1e150), "Gamma and Delta"),  # D0 = Gamma^3/Delta^4 overflows
    (dict(Delta=1e-300), "Gamma and Delta"),  # Delta^2 underflows to 0: was a ZeroDivisionError
    (dict(Delta=1e300), "Gamma and Delta"),  # Delta^2 overflows: was an OverflowError
    (dict(Gamma=1e200, Delta=1e-200), "Gamma and Delta"),
    (dict(tau=1e300), "tau"),
    (dict(tau=1e-305), "tau"),
    (dict(tau_L=1e300), "tau_L"),
    (dict(gamma_bar=1e300, Delta=1e-10, Gamma=1e-20), "gamma_bar"),
])
def test_units_out_of_floating_range_are_refused_by_name(kw, names):
    """D and M0 are reported as D' D0 and M0' v0: a reference unit or a nondimensional number
    outside [1e-300, 1e300] would make a finite estimate inf or 0, or crash the planner."""
    full = dict(Gamma=5.0, Delta=3.84, tau=0.5, tau_L=0.067, gamma_bar=0.342) | kw
    with pytest.raises(ValueError, match=f"^{names} must keep"):
        Params(**full)


def test_extreme_but_representable_units_are_exact():
    """Gamma = 1e200, Delta = 1e100: Delta**2 etc. would overflow in Python floats (OverflowError)
    although every unit is representable; the units are built as products."""
    p = Params(1e200, 1e100, 1.0, 1.0)
    assert p.tau0 == 1.0 and p.v0 == 1e100
    assert p.u0 == pytest.approx(1e100, rel=1e-14) and p.D0 == pytest.approx(1e200, rel=1e-14)
    assert p.D0 == pytest.approx(p.u0 * p.u0 / p.tau0, rel=1e-14)


def test_numpy_scalars_are_held_as_python_floats():
    """A float32 or float16 value used to stay float32 in the units: Delta = float32(1e-10) made D0
    = Gamma^3/Delta^4 overflow to inf (and D = inf), a float16 tau made tau' inf."""
    d32 = np.float32(1e-10)
    p = Params(1.0, d32, 1e20)
    assert all(type(getattr(p, k)) is float for k in ("Gamma", "Delta", "tau", "tau_L", "gamma_bar"))
    assert math.isfinite(p.D0) and p.D0 == Params(1.0, float(d32), 1e20).D0
    assert Params(1.0, 1.0, np.float16(60000)).tau_nd == 60000.0


def test_a_huge_integer_is_refused_in_one_short_line():
    with pytest.raises(ValueError, match=r"^Gamma must be a real number \(got 1000.*\.\.\. \(401 characters\)\)$"):
        Params(10**400, 1.0, 1.0)


@pytest.mark.parametrize("kw,name", [
    # the numbers given, by their own names (tau', not the tau = tau' tau0 they would make)
    (dict(tau=True), "tau'"), (dict(tau="1"), "tau'"), (dict(tau=None), "tau'"), (dict(tau=1.0, tau_L=[1.0]), "tau_L'"),
    (dict(tau=1.0, gamma_bar="0"), "gamma_bar'"), (dict(tau=-1.0, Gamma=2.0, Delta=3.0), "tau'"),
    (dict(tau=1.0, tau_L=0.0, Gamma=2.0, Delta=3.0), "tau_L'"),
    (dict(tau=1.0, gamma_bar=math.nan, Delta=3.0), "gamma_bar'"),
    # tau_L' = 1e300 in a tau0 of 1e10 s overflowed to tau_L = inf, then was refused as
    # "|gamma_bar| >= Delta with tau_L = inf"
    (dict(tau=1.0, tau_L=1e300, gamma_bar=2.0, Gamma=1e10), "tau_L"),
    # tau0 = 1e-200/1e400 underflowed to 0 and tau = tau' tau0 = 0 was refused as "tau must be > 0 (got 0.0)"
    (dict(tau=1.0, Gamma=1e-200, Delta=1e200), "Gamma and Delta"),
])
def test_from_nondim_refuses_by_name(kw, name):
    with pytest.raises(ValueError, match=f"^{name} must") as e:
        Params.from_nondim(**kw)
    if name.endswith("'") and isinstance(kw[name[:-1]], float):
        assert str(e.value).endswith(f"(got {kw[name[:-1]]!r})")  # the value given, not tau' tau0 = -0.222


def test_from_nondim_under_jit():
    """tau', tau_L' and gamma_bar' traced (jit): the physical parameters are tau' tau0, tau_L' tau0 and
    gamma_bar' Delta, with tau0 = Gamma/Delta^2 = 2/9 s and Delta = 3 (a TypeError before: the tracer was
    taken for a number to check)."""
    fields = lambda q: (q.Gamma, q.Delta, q.tau, q.tau_L, q.gamma_bar)
    got = jax.jit(lambda t, tl, g: fields(Params.from_nondim(t, tl, g, Gamma=2.0, Delta=3.0)))(4.5, 9.0, 0.5)
    assert [float(x) for x in got] == pytest.approx([2.0, 3.0, 1.0, 2.0, 1.5], rel=1e-15)


@pytest.mark.parametrize("G,D,tau0", [(1e300, 1e155, 1e-10), (1e-170, 1e-160, 1e150), (1e-300, 1e-300, 1e300)])
def test_units_representable_although_delta_squared_is_not(G, D, tau0):
    """Delta^2 overflows (1e310) or underflows (1e-320, 1e-600) while tau0 = Gamma/Delta^2, v0, u0
    and D0 all lie in range: such parameters were refused as "tau0 ... (got 0)" (or inf), and
    from_nondim with them too.  Expected values: powers of ten, by hand."""
    p = Params(G, D, tau0, tau0)
    assert p.tau0 == pytest.approx(tau0, rel=1e-14) and p.tau_nd == pytest.approx(1.0, rel=1e-14)
    assert p.u0 == pytest.approx(tau0 * G / D, rel=1e-14) and p.D0 == pytest.approx(tau0 * (G / D) ** 2, rel=1e-14)
    assert Params.from_nondim(2.0, Gamma=G, Delta=D).tau == pytest.approx(2 * tau0, rel=1e-14)


def test_a_unit_just_past_its_bound_is_shown_in_full():
    """Gamma = 1e300, Delta = 1e150 give D0 = 1.0000000000000002e300, just past 1e300: refused rightly, but
    the message said "(got 1e+300 ..." against the range [1e-300, 1e+300] (found by an audit).  Three digits
    are kept where they show a value off its bound."""
    with pytest.raises(ValueError, match=r"D0 = Gamma\^3/Delta\^4 in \[1e-300, 1e\+300\] \(got 1\.0000000000000002e\+300 "):
        Params(1e300, 1e150, 1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match=r"tau0 = Gamma/Delta\^2 in \[1e-300, 1e\+300\] \(got 1e-310 from"):
        Params(1e-300, 1e5, 1.0, 1.0, 0.0)


def test_params_read_back_from_a_results_json_with_an_infinite_tau_L():
    """The results' strict JSON writes an infinite tau_L as "inf" (outfiles.dumps): json.loads of a result's
    params then gave Params a string, which it refused (an audit).  Only the infinities are taken so."""
    import json
    import re

    from dryfric_jax.outfiles import dumps

    text = dumps({"params": {**FIG3, "tau_L": math.inf}})
    assert '"tau_L": "inf"' in text
    assert Params(**json.loads(text)["params"]) == Params(**{**FIG3, "tau_L": math.inf})
    for bad in ("1.0", "nan", "Infinity", "+inf"):
        with pytest.raises(ValueError, match=f"^tau_L must be a real number \\(got '{re.escape(bad)}'\\)$"):
            Params(**{**FIG3, "tau_L": bad})
