"""Second mutation audit of paths.py: the parts the first (test_paths_mutants.py) did not target:
_check_model, _record_steps, _segment, _stationary/di_stationary, autocovariance/_acf_args/_per_path_acf,
autocorrelation, _excursion/di_excursion and _pdmp_sampled/pdmp_stationary.  54 one-line mutants: 33 killed
by test_paths.py / test_paths_mutants.py / test_figure_numbers.py, 6 equivalent (FFT padding 2n + 2 instead of 2n;
``ends`` on phase >= 2; U not reset at the regeneration, where it is 0 already; an event exactly at a grid time;
the clamp max(tj - T, 0); ok[-1] for all(ok)), 15 killed only here (a negative step count accepted, _segment's
2**31 guard, a 1-row block remainder dropped, a 1-step burn-in skipped, V with 0 samples / complex / 3-d / int
refused or accepted wrongly, a numpy-bool center, V not worked in float64 (and the first audit's alive float32
rounding), the excursion's seek bound of 50 max_steps, its start at x_+, max_events off by one, burn = 0
refused), 0 alive.  One defect, fixed in paths._excursion: an excursion of exactly max_steps steps was reported
incomplete.  (_excursion/di_excursion, the regeneration cycle step by step, was removed on 2026-12-07, once Figs.
1-2 plotted di_long_excursion and nothing else used it; its two tests went with it.)

The oracles are independent of paths.py: the documented per-path random numbers stepped by a plain
numpy loop of the pure dry friction DI step (as in test_paths_mutants.py), a direct O(n * lag) sum
for the autocovariance, and the PDMP's own event law (pdmp.PDMPModel.event) stepped in Python to
count the events a record needs.
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import rng
from dryfric_jax.di import make_di_model
from dryfric_jax.params import FIG3, Params
from dryfric_jax.paths import _record_steps, autocorrelation, autocovariance, di_stationary, pdmp_stationary
from dryfric_jax.pdmp import make_pdmp_model
from test_paths_mutants import H, TAU, _numpy_run


def test_record_steps_refuses_negative_step_counts():
    """'non-negative integers' (a negative first count made a negative segment, run as a block's
    remainder from a negative row offset)."""
    for bad in ([-1], [-3, 5]):
        with pytest.raises(ValueError, match="^record_steps must"):
            _record_steps(bad)
    assert _record_steps([0]) == [0]


def test_di_stationary_with_a_one_step_burn_in_and_a_one_row_remainder():
    """Kills: a burn-in of 1 step skipped (``if burn > 1``) and a segment's last row dropped when a
    block of 128 leaves 1 (``if rest > 1``): no test ran burn_steps = 1 or a segment of 129 steps.
    Path p: X0 = N(0, 1/tau') from fold_in(k, n_records + 1), one burn step with the numbers of
    fold_in(k, n_records), then record i from fold_in(k, i); U from the end of the burn-in."""
    model = make_di_model(Params.from_nondim(TAU), H)
    key = jax.random.key(8)
    every, n_rec = 129, 2
    V, U = di_stationary(model, key, 2, n_rec, every=every, burn_steps=1)
    for p, k in enumerate(jax.random.split(key, 2)):
        x = float(jax.random.normal(jax.random.fold_in(k, n_rec + 1), (), jnp.float64)) / math.sqrt(TAU)
        x, v, _ = _numpy_run(model, x, 0.0, rng.normal(jax.random.fold_in(k, n_rec), (1, 2), jnp.float64))
        u_tot = 0.0
        for i in range(n_rec):
            x, v, u = _numpy_run(model, x, v, rng.normal(jax.random.fold_in(k, i), (every, 2), jnp.float64))
            u_tot += u
            assert V[p, i] == pytest.approx(v, rel=1e-12, abs=1e-13)
            assert U[p, i] == pytest.approx(u_tot, rel=1e-12, abs=1e-13)


def test_segment_refuses_a_segment_of_2_31_steps():
    """_segment's own guard (the public functions name their argument first): a segment of 2**31
    steps would count its rows past uint32.  Traced only (jax.eval_shape): nothing runs."""
    from dryfric_jax.paths import _segment

    model = make_di_model(Params.from_nondim(TAU), H)
    keys = jax.random.split(jax.random.key(0), 2)
    carry = (jnp.zeros(2), jnp.zeros(2), jnp.zeros(2, jnp.float64))
    with pytest.raises(ValueError, match=r"^a recorded segment must have fewer than 2\*\*31 steps"):
        jax.eval_shape(lambda c: _segment(model, c, keys, 2**31), carry)
    jax.eval_shape(lambda c: _segment(model, c, keys, 2**31 - 1), carry)  # the largest is taken

def _direct_acov(W, max_lag):
    """Per path, the mean over the n - k pairs of W[t] W[t + k], in float64."""
    W = np.asarray(W, np.float64)
    n = W.shape[1]
    return np.array([[np.mean(w[: n - k] * w[k:]) for k in range(max_lag + 1)] for w in W])


def test_autocovariance_takes_integer_and_float32_series_in_float64():
    """'a real array': integers are accepted (``dtype.kind`` "i"), and a float32 series is worked
    in float64 (numpy's FFT keeps float32, ~1e-7 off).  Oracle: the direct lagged sum of the same
    values in float64."""
    rng = np.random.default_rng(11)
    Vi = rng.integers(-5, 6, (3, 40)).cumsum(1)
    ref = _direct_acov(Vi - Vi.mean(), 39)
    c, se = autocovariance(Vi, 39, center=True)
    np.testing.assert_allclose(c, ref.mean(0), rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    V32 = rng.normal(0.0, 1.0, (3, 500)).cumsum(1).astype(np.float32)
    ref = _direct_acov(V32, 20)
    c, se = autocovariance(V32, 20)
    assert c.dtype == np.float64
    np.testing.assert_allclose(c, ref.mean(0), rtol=1e-12)
    np.testing.assert_allclose(se, ref.std(0, ddof=1) / math.sqrt(3), rtol=1e-9)


@pytest.mark.parametrize("V", [np.zeros((3, 0)), np.ones((2, 4), complex), np.ones((2, 3, 4))],
                         ids=["no samples", "complex", "3-d"])
def test_autocovariance_refuses_what_is_no_real_paths_by_samples_array(V):
    """'V is (paths, samples), finite ... real', with at least 1 sample: refused naming V."""
    for f in (autocovariance, autocorrelation):
        with pytest.raises(ValueError, match="^V must be a real array of shape"):
            f(V, 0)


def test_center_may_be_a_numpy_bool():
    """center is 'True or False'; a numpy bool (from a comparison) is one."""
    V = np.random.default_rng(2).normal(1.0, 1.0, (3, 10))
    for f in (autocovariance, autocorrelation):
        for a, b in zip(f(V, 4, center=np.bool_(True)), f(V, 4, center=True)):
            np.testing.assert_array_equal(a, b)


def _events_needed(model, key, t_last):
    """The number of PDMP events, drawn as the documented stream (event i from uniforms of
    fold_in(key, i), from s_+ at t = 0), until one ends at or after t_last."""
    ev = jax.jit(lambda s, r: model.event(s, r))
    vdt = model.delta.dtype
    state = jax.tree_util.tree_map(lambda a: a[0], model.s_plus(1))
    T, i = 0.0, 0
    while True:
        u = jax.random.uniform(jax.random.fold_in(key, i), (2,), vdt, minval=jnp.finfo(vdt).tiny)
        dt, _, state, _, _ = ev(state, (u[0], u[1]))
        T, i = T + float(dt), i + 1
        if T >= t_last:
            return i


@pytest.fixture(scope="module")
def pdmp():
    return make_pdmp_model(Params(FIG3["Gamma"], FIG3["Delta"], 1.0, FIG3["tau_L"], FIG3["gamma_bar"]), 0.125)


def test_pdmp_event_bound_is_exact(pdmp):
    """max_events bounds the events per path: a path that needs exactly max_events events (the
    one starting at t = 0 included) records, one fewer raises.  Kills ``i <= max_events``."""
    key = jax.random.key(4)
    need = _events_needed(pdmp, jax.random.split(key, 1)[0], 0.5 + 9 * 0.1)
    assert need > 5
    V = pdmp_stationary(pdmp, key, 1, 10, 0.1, 0.5, max_events=need)
    assert V.shape == (1, 10) and np.all(np.isfinite(V))
    with pytest.raises(RuntimeError, match="^1 PDMP paths hit max_events"):
        pdmp_stationary(pdmp, key, 1, 10, 0.1, 0.5, max_events=need - 1)


def test_pdmp_burn_zero_and_one_event(pdmp):
    """burn >= 0 and max_events >= 1, as documented: with burn = 0 and one record the first event
    covers t = 0, where the path is at s_+ (V = 0)."""
    V = pdmp_stationary(pdmp, 1, 3, 1, 0.1, 0.0, max_events=1)
    np.testing.assert_array_equal(V, np.zeros((3, 1)))
