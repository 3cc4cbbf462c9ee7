"""Python API bad input: a ValueError naming the parameter, never a TypeError or AttributeError
from deep inside, and numpy scalars accepted wherever Python numbers are (the CLI's bad input
is in test_cli.py, the parameters' own checks in test_params.py).  Nothing here simulates: every
case is refused, or planned only."""
import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import paths, theory
from dryfric_jax.chain_law import white_chain_law

P = dj.Params(**dj.FIG3)


@pytest.mark.parametrize("bad", [dict(dj.FIG3), None, "x", 5, [P]])
@pytest.mark.parametrize("call", [
    lambda p: dj.estimate_diffusivity(p, 0, n_excursions=50),
    lambda p: dj.bruteforce_diffusivity(p, 0, t=1.0, n_paths=4),
    lambda p: dj.plan_estimate(p),
    theory.exact_D, theory.exact_M0, theory.exact_mean_square_velocity,
    lambda p: white_chain_law(p, 1e-3), dj.default_h, dj.plan.h_max,  # default_h(FIG3) was an AttributeError
])
def test_params_that_are_not_Params_are_refused_by_name(call, bad):
    with pytest.raises(ValueError, match="^params must be a dryfric_jax.Params"):
        call(bad)


CALLS_ON_PARAMS = [
    lambda p: dj.estimate_diffusivity(p, 0, n_excursions=50),
    lambda p: dj.bruteforce_diffusivity(p, 0, t=1.0, n_paths=4),
    lambda p: dj.plan_estimate(p), theory.exact_D, lambda p: white_chain_law(p, 1e-3), dj.default_h,
]


@pytest.mark.parametrize("call", CALLS_ON_PARAMS)
@pytest.mark.parametrize("transform,G", [(jax.jit, 5.0), (jax.grad, 5.0), (jax.vmap, jnp.array([2.0, 5.0]))])
def test_tracing_an_estimator_is_refused_by_name_at_once(call, transform, G):
    """Under jit, grad or vmap (a notebook user's first try at a sweep) the host-side drivers failed deep
    inside with JAX's ConcretizationTypeError (vmap over keys after a 12 s compile; a user audit)."""
    f = transform(lambda G: call(dj.Params(G, 3.84, 0.5, 0.067, 0.342)))
    with pytest.raises(ValueError,
                       match=r"^params\.Gamma is a JAX tracer \(under jax.jit, vmap or grad\).*Python loop"):
        f(G)


def test_a_traced_key_is_refused_before_any_work():
    keys = jax.random.split(jax.random.key(0), 2)
    with pytest.raises(ValueError, match=r"^key is a JAX tracer"):
        jax.vmap(lambda k: dj.estimate_diffusivity(P, k, n_excursions=50).D)(keys)
    with pytest.raises(ValueError, match=r"^key is a JAX tracer"):
        jax.vmap(lambda k: dj.bruteforce_diffusivity(P, k, t=1.0, n_paths=4).D_t)(keys)


@pytest.mark.parametrize("call", CALLS_ON_PARAMS)
@pytest.mark.parametrize("field,value,match", [
    ("Gamma", -1.0, r"^Gamma must be finite and > 0 \(got -1.0\)"),
    ("tau_L", 0.0, r"^tau_L must be > 0 or inf"),
    ("gamma_bar", float("nan"), r"^gamma_bar must be a finite number"),
    ("tau", np.ones(3), r"^tau must be a real number \(got an array of shape \(3,\)\)"),
])
def test_params_edited_around_their_checks_are_checked_again(call, field, value, match):
    """eqx.tree_at (and tree_map) build a Params without __check_init__: Gamma = -1 got through and was
    refused as "tau_L must be >= 1e-60 tau0 = -6.78e-62 s", an array as a bare TypeError (a user audit)."""
    bad = eqx.tree_at(lambda p: getattr(p, field), P, value)
    with pytest.raises(ValueError, match=match):
        call(bad)


def test_jax_64_bit_mode_turned_off_is_said_not_a_traceback_from_jax():
    """Every runner refuses: the long-excursion count, a model built then and a pool of two results ran silently
    in float32 (the count with int32 counters) and said float64 (an audit; the count's mean moved 5%)."""
    runs = [dj.estimate_diffusivity(P, s, n_excursions=50) for s in (1, 2)]
    di, pd = dj.make_di_model(P, 1e-3), dj.make_pdmp_model(P, 0.125)
    key = jax.random.key(0)
    jax.config.update("jax_enable_x64", False)
    try:
        for call in (lambda: dj.estimate_diffusivity(P, 0, n_excursions=50, dtype="float32"),
                     lambda: dj.bruteforce_diffusivity(P, 0, t=1.0, n_paths=4),
                     lambda: dj.di_long_excursion_duration(P, 0, n_excursions=10),
                     lambda: dj.combine_estimates(runs),
                     lambda: dj.make_di_model(P, 1e-3), lambda: dj.make_pdmp_model(P, 0.125),
                     lambda: paths.di_transient(di, 0, 4, [10]),
                     lambda: dj.pdmp.excursion_skeleton(pd, key)):  # float32 times, int32 levels (a review)
            with pytest.raises(RuntimeError, match=r"needs JAX's 64-bit mode.*jax_enable_x64', True"):
                call()
    finally:
        jax.config.update("jax_enable_x64", True)


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
    (dict(dtype=np.float32(np.nan)), "dtype"), (dict(dtype=np.zeros(2)), "dtype"),  # values, not dtypes (audit)
    (dict(method=5), "method"),
])
def test_settings_are_refused_by_name(kw, name):
    with pytest.raises(ValueError, match=f"^{name} must"):
        dj.estimate_diffusivity(P, 0, n_excursions=50, **kw)


@pytest.mark.parametrize("kw", [dict(burn_in=True), dict(burn_in=np.float32(-1.0)), dict(t=True),
                                dict(max_events=5)])  # max_events with the DI was taken and ignored
def test_bruteforce_settings_are_refused_by_name(kw):
    name = next(iter(kw))
    with pytest.raises(ValueError, match=f"^{name} must"):
        dj.bruteforce_diffusivity(P, 0, **{"t": 1.0, "n_paths": 4, **kw})


def test_two_bruteforce_paths_are_refused_before_any_work():
    """With 2 paths the centred U^2 are equal and the D_t CI came out 0."""
    with pytest.raises(ValueError,
                       match=r"^n_paths must be an integer in \[3, 67108864\] \(with 2 paths the D_t CI is 0; "):
        dj.bruteforce_diffusivity(P, 0, t=1e6, n_paths=2)  # refused first: 1e6 s would be past max_work


@pytest.mark.parametrize("kw", [dict(h=np.float32(1e-3)), dict(h=np.array(1e-3)), dict(h=np.int64(0) + 1e-3),
                                dict(method="pdmp", delta=np.float32(0.05)), dict(dtype=np.float32)])
def test_numpy_settings_plan_like_python_ones(kw):
    """A float32 h, a 0-d array or np.float32 as dtype were refused as out of range (or not
    numbers) although they hold admissible values."""
    plan = dj.plan_estimate(P, n_excursions=50, **kw)
    py = {k: (float(v) if k in ("h", "delta") else "float32") for k, v in kw.items() if k != "method"}
    want = dj.plan_estimate(P, n_excursions=50, method=kw.get("method", "di"), **py)
    assert (plan.method, plan.h, plan.delta, plan.dtype) == (want.method, want.h, want.delta, want.dtype)


@pytest.mark.parametrize("call", [
    lambda: dj.plan_estimate(P, n_excursions=2**70, max_work=1e308),  # a TypeError from lanes_for (np.log2)
    lambda: dj.estimate_diffusivity(P, 0, n_excursions=np.array(2**62 + 1, dtype=object), max_work=1e308),
    lambda: dj.bruteforce_diffusivity(P, 0, t=1.0, n_paths=2**70, max_work=1e308),  # ran 2^70 paths
], ids=["plan", "estimate", "bruteforce"])
def test_counts_beyond_int64_are_refused_by_name(call):
    with pytest.raises(ValueError,
                       match=r"^(n_excursions must be an integer in \[2, 2\^62\]"
                             r"|n_paths must be an integer in \[3, 67108864\])"):
        call()


@pytest.mark.parametrize("rtol", [1e-160, 5e-324])
def test_time_left_for_a_tiny_rtol_does_not_overflow(rtol):
    """(rel/rtol)^2 overflowed (OverflowError): the excursions a target asks for are capped at
    2^62, and max_work still ends the projection."""
    from dryfric_jax.api import time_left

    assert time_left(10.0, 1e6, 100, 10, 200, rtol=rtol, rel=0.1, max_work=1e9) == (9990.0, "max_work")
    left, to = time_left(10.0, 1e6, 100, 10, 200, rtol=rtol, rel=0.1)
    assert to == "target" and left == pytest.approx((2**62 - 110) * 1e6 / 110 / 1e5)


_HUGE = 10**400


@pytest.mark.parametrize("call,name", [
    (lambda: dj.plan_estimate(P, max_work=_HUGE), "max_work"),  # an OverflowError
    (lambda: dj.estimate_diffusivity(P, 0, n_excursions=50, max_work=_HUGE), "max_work"),
    (lambda: dj.bruteforce_diffusivity(P, 0, t=1.0, n_paths=4, max_work=_HUGE), "max_work"),
    (lambda: dj.estimate_diffusivity(P, 0, n_excursions=50, rtol=_HUGE), "rtol"),
    (lambda: dj.estimate_diffusivity(P, 0, n_excursions=50, max_time=-_HUGE), "max_time"),
    (lambda: dj.plan_estimate(P, h=_HUGE), "h"),
    (lambda: dj.plan_estimate(P, method="pdmp", delta=_HUGE), "delta"),
])
def test_huge_ints_are_refused_in_one_short_line(call, name):
    """A 400-digit int was printed in full (or raised an OverflowError for max_work), and delta's
    was shown as "got inf"; now as its first digits and its length."""
    with pytest.raises(ValueError, match=f"^{name} must") as e:
        call()
    assert len(str(e.value)) < 400 and "0" * 30 not in str(e.value)
    assert re.search(r"\(40[12] characters\)", str(e.value))  # -10**400 has 402


def test_progress_that_is_not_callable_is_refused_before_any_work(tmp_path):
    """It raised a TypeError after the first round (estimate) or after writing refusals (sweep)."""
    from dryfric_jax import sweep

    live = r"must be a callable, True \(a live status line\), False or None"
    with pytest.raises(ValueError, match="^progress " + live):
        dj.estimate_diffusivity(P, 0, n_excursions=50, progress=5)
    with pytest.raises(ValueError, match="^progress " + live):
        sweep.run_sweep([{}], str(tmp_path / "s.jsonl"), n_excursions=50, progress=5)
    with pytest.raises(ValueError, match="^point_progress " + live + r" \(got 'bar'\)$"):
        sweep.run_sweep([{}], str(tmp_path / "s.jsonl"), n_excursions=50, point_progress="bar")
    assert not (tmp_path / "s.jsonl").exists()


def test_0d_arrays_are_taken_like_python_numbers():
    """README: numpy scalars and 0-d arrays are taken like Python numbers; max_work, n_excursions,
    lanes and seed refused 0-d arrays."""
    from dryfric_jax.api import _key, check_seed

    plan = dj.plan_estimate(P, n_excursions=np.array(50), max_work=np.array(1e9), lanes=np.array(16),
                            block=np.array(64))
    want = dj.plan_estimate(P, n_excursions=50, max_work=1e9, lanes=16, block=64)
    assert plan == want and type(plan.lanes) is int and type(plan.max_work) is float
    assert check_seed(np.array(3)) == 3 and _key(np.array(3))[1] == 3
    assert dj.plan_estimate(P, n_excursions=np.int64(50), max_steps=np.array(1000)).max_steps == 1000
    # 0-d JAX arrays too (jnp.array(50) was refused as "n_excursions must be an integer in [2, 2^62]"; found by a
    # user audit); a jax.random key is not a number and stays a key, a float is no count
    import jax
    import jax.numpy as jnp

    plan = dj.plan_estimate(P, n_excursions=jnp.array(50), max_work=jnp.array(1e9), lanes=jnp.array(16),
                            block=jnp.array(64))
    assert plan == want and type(plan.lanes) is int and type(plan.max_work) is float
    assert check_seed(jnp.array(3)) == 3 and _key(jnp.array(3))[1] == 3
    k = jax.random.key(3)
    assert _key(k) == (k, None)
    with pytest.raises(ValueError, match=r"^n_excursions must be an integer in \[2, 2\^62\] \(got 50\.0\)"):
        dj.plan_estimate(P, n_excursions=jnp.array(50.0))


def _estimate_dict(run_seed, sums=(), **edit):
    """An estimate result's to_dict() (``sums`` updates its sums): the refusals below come before
    its sums are pooled."""
    from dryfric_jax.excursions import STAT_NAMES

    d = dict(D=1.0, D_ci=0.1, M0=0.0, M0_ci=0.1, mean_duration=1.0, n_excursions=200, n_truncated=0, method="di",
             h=6.7e-4, dtype="float64", seed=run_seed, wall_s=1.0, lane_steps_per_s=1e6, params=P.as_dict(),
             sums={**dict.fromkeys(STAT_NAMES, 1.0), **dict(sums)})
    return {**d, **edit}


@pytest.mark.parametrize("edit,match", [
    (dict(sums={"n": 1e20}), "finite excursion sums, n a whole number"),  # a TypeError (no callable sqrt method)
    (dict(sums={"n": 2.5}), "finite excursion sums, n a whole number"),
    (dict(h="0.00067"), "h a number > 0"), (dict(dtype="float16"), "dtype one of"), (dict(method="rk4"), "method"),
    (dict(seed=2**80), "seed an integer in"), (dict(delta="x"), "delta"), (dict(L_X=-1.0), "L_X"),
    (dict(ci_level=0.9), None),
])
def test_combine_refuses_a_malformed_field_by_name(edit, match):
    """Accepted before (or a TypeError / 'Unknown format code' naming no field); two levels were
    pooled at the first's."""
    bad = _estimate_dict(2, **edit)
    msg = f"^b.json must have {match}" if match else "^results must share ci_level: a.json has 0.95, b.json has 0.9"
    with pytest.raises(ValueError, match=msg):
        dj.combine_estimates([_estimate_dict(1), bad], labels=["a.json", "b.json"])


@pytest.mark.parametrize("labels", [["a"], 5, "ab", ["a", 2], ["a", "b", "c"]])
def test_combine_labels_must_be_one_string_per_result(labels):
    """Fewer labels than results: a TypeError (zip cut the checks short), or an IndexError where
    the results differ in h; labels=5: a TypeError."""
    rs = [_estimate_dict(1), _estimate_dict(2, h=1e-3)]
    with pytest.raises(ValueError, match=r"^labels must be a list of 2 strings"):
        dj.combine_estimates(rs, labels=labels)
    with pytest.raises(ValueError, match="^results must share h"):
        dj.combine_estimates(rs, labels=["a", "b"])


@pytest.mark.parametrize("call,name", [
    (lambda x: theory.D_pure_dry(x, 3.84), "Gamma"),
    (lambda x: theory.D_constant_bias(5.0, x, 0.3), "Delta"),
    (lambda x: theory.M0_constant_bias(5.0, 3.84, x), "gamma_bar"),
    (lambda x: theory.D_viscous_only(5.0, x), "tau_L"),
    (lambda x: dj.make_di_model(P, x * 1e-3), "h"),
    (lambda x: white_chain_law(dj.Params.from_nondim(1.0), x * 0.03).p_stuck, "h"),  # told the chain law's range
    (lambda x: dj.make_pdmp_model(P, x * 0.4), "delta"),  # told "delta must be in (0, 0.3338)"
])
@pytest.mark.parametrize("transform", [jax.grad, jax.jit])
def test_closed_forms_and_the_step_under_a_transformation_name_the_tracer(call, name, transform):
    """The closed forms raised JAX's ConcretizationTypeError, and make_di_model under jit said "h must be in
    [6.7e-14, 0.0067] s (got JitTracer(...))", a range its value lay in (an audit)."""
    with pytest.raises(ValueError, match=f"^{name} is a JAX tracer \\(under jax.jit, vmap or grad\\)"):
        transform(call)(0.3)


def test_the_unit_intensity_moment_names_the_callers_values():
    """t and v0 are doubled: 1e308 was refused as "got inf", a value never passed (an audit)."""
    with pytest.raises(ValueError, match=r"^t must be <= 8\.99e\+307 \(it is doubled; got 1e\+308\)"):
        theory.first_moment_unit_intensity(1e308, 1.0)
    with pytest.raises(ValueError, match=r"^v0 must satisfy \|v0\| <= 8\.99e\+307 \(it is doubled; got -1e\+308\)"):
        theory.first_moment_unit_intensity(1.0, -1e308)
    assert theory.first_moment_unit_intensity(8e307, 1.0) == 0.5 * theory.first_moment(1.6e308, 2.0)


@pytest.mark.parametrize("kw,match", [
    (dict(delta=0.05), r"^delta must not be given with method 'di': it is the PDMP noise grid step \(method 'pdmp'\)$"),
    (dict(method="pdmp", h=1e-3), r"^h must not be given with method 'pdmp': it is the DI step \(method 'di'\)$"),
    (dict(method=5), r"^method must be 'di' or 'pdmp' for brute force \(got 5\)$"),
    (dict(method="auto"), r"^method must be 'di' or 'pdmp' for brute force \(got 'auto'\)$"),
])
def test_brute_force_offers_only_the_methods_it_takes(kw, match):
    """Its refusals offered method 'auto', which it then refused (an audit)."""
    with pytest.raises(ValueError, match=match):
        dj.bruteforce_diffusivity(P, 0, t=1.0, n_paths=10, **kw)
