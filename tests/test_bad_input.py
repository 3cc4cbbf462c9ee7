"""Python API bad input: a ValueError naming the parameter, never a TypeError or AttributeError
from deep inside, and numpy scalars accepted wherever Python numbers are (the CLI's bad input
is in test_cli.py, the parameters' own checks in test_params.py).  Nothing here simulates: every
case is refused, or planned only."""
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import theory
from dryfric_jax.chain_law import white_chain_law

P = dj.Params(**dj.FIG3)


@pytest.mark.parametrize("bad", [dict(dj.FIG3), None, "x", 5, [P]])
@pytest.mark.parametrize("call", [
    lambda p: dj.estimate_diffusivity(p, 0, n_excursions=50),
    lambda p: dj.bruteforce_diffusivity(p, 0, t=1.0, n_paths=4),
    lambda p: dj.plan_estimate(p),
    theory.exact_D, theory.exact_M0, theory.exact_mean_square_velocity,
    lambda p: white_chain_law(p, 1e-3),
])
def test_params_that_are_not_Params_are_refused_by_name(call, bad):
    with pytest.raises(ValueError, match="^params must be a dryfric_jax.Params"):
        call(bad)


@pytest.mark.parametrize("bad", ["1", None, True, [1.0, "a"], [[1.0, 2.0], [3.0]], b"1"])
@pytest.mark.parametrize("call", [
    lambda t: theory.first_moment(t, 1.0), theory.correlation,
    lambda t: theory.first_moment_unit_intensity(t, 1.0),
])
def test_closed_form_times_that_are_not_numbers_are_refused(call, bad):
    """A numeric string was read as a number, None was refused as "got nan"."""
    with pytest.raises(ValueError, match="^t must be a real number or an array of real numbers"):
        call(bad)


def test_closed_form_times_take_numpy_numbers_and_arrays():
    assert theory.correlation(np.float32(0.0)) == 2.0 and theory.correlation(np.int64(0)) == 2.0
    assert np.array_equal(theory.correlation(np.array([-1.0, 1.0])), theory.correlation([1, 1]))
    assert theory.first_moment(np.float32(0.0), 1.0) == 1.0


@pytest.mark.parametrize("kw,name", [
    (dict(rtol=np.float32(2.0)), "rtol"), (dict(rtol=True), "rtol"), (dict(rtol="0.1"), "rtol"),
    (dict(max_time=True), "max_time"), (dict(max_time=np.float64(-1.0)), "max_time"),
    (dict(h=True), "h"), (dict(h=np.array([1e-3])), "h"),
    (dict(method="pdmp", delta=True), "delta"),
    (dict(dtype=None), "dtype"),  # jnp.dtype(None) is float64: it used to be taken for the default
    (dict(method=5), "method"),
])
def test_settings_are_refused_by_name(kw, name):
    with pytest.raises(ValueError, match=f"^{name} must"):
        dj.estimate_diffusivity(P, 0, n_excursions=50, **kw)


@pytest.mark.parametrize("kw", [dict(burn_in=True), dict(burn_in=np.float32(-1.0)), dict(t=True)])
def test_bruteforce_settings_are_refused_by_name(kw):
    name = next(iter(kw))
    with pytest.raises(ValueError, match=f"^{name} must"):
        dj.bruteforce_diffusivity(P, 0, **{"t": 1.0, "n_paths": 4, **kw})


@pytest.mark.parametrize("kw", [dict(h=np.float32(1e-3)), dict(h=np.array(1e-3)), dict(h=np.int64(0) + 1e-3),
                                dict(method="pdmp", delta=np.float32(0.05)), dict(dtype=np.float32)])
def test_numpy_settings_plan_like_python_ones(kw):
    """A float32 h, a 0-d array or np.float32 as dtype were refused as out of range (or not
    numbers) although they hold admissible values."""
    plan = dj.plan_estimate(P, n_excursions=50, **kw)
    py = {k: (float(v) if k in ("h", "delta") else "float32") for k, v in kw.items() if k != "method"}
    want = dj.plan_estimate(P, n_excursions=50, method=kw.get("method", "di"), **py)
    assert (plan.method, plan.h, plan.delta, plan.dtype) == (want.method, want.h, want.delta, want.dtype)
