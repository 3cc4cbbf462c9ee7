"""The PDMP path recorder (Fig. 4) against a plain event loop over the same random stream."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax.params import FIG3, Params
from dryfric_jax.paths import pdmp_stationary
from dryfric_jax.pdmp import flow, make_pdmp_model


def _reference(model, key, n_records, dt_rec, burn):
    """One path event by event in Python: V at burn + j dt_rec from the segment containing it."""
    ev = jax.jit(lambda s, r: model.event(s, r))
    vdt = model.delta.dtype
    state = jax.tree_util.tree_map(lambda a: a[0], model.s_plus(1))
    T, i, out = 0.0, 0, []
    grid = burn + dt_rec * np.arange(n_records)
    while len(out) < n_records:
        u = jax.random.uniform(jax.random.fold_in(key, i), (2,), vdt, minval=jnp.finfo(vdt).tiny)
        dt, a, new, _, _ = ev(state, (u[0], u[1]))
        T1 = T + float(dt)
        _, y, v = state
        for tj in grid[len(out):]:
            if tj > T1:
                break
            out.append(float(flow(v, a, model.inv_tau_L, jnp.asarray(tj - T, vdt))) if y != 0 else 0.0)
        state, T, i = new, T1, i + 1
    return np.array(out)


@pytest.mark.parametrize("tau", [0.25, 1.0])
def test_pdmp_recorder_matches_event_loop(tau):
    p = Params(FIG3["Gamma"], FIG3["Delta"], tau, FIG3["tau_L"], FIG3["gamma_bar"])
    m = make_pdmp_model(p, 0.125)
    key = jax.random.key(5)
    V = pdmp_stationary(m, key, 4, 200, 0.05, 2.0)
    keys = jax.random.split(key, 4)
    for i in (2, 3):
        assert np.mean(V[i] != 0) > 0.1  # the path slides: the check is not on a stuck particle
        np.testing.assert_allclose(V[i], _reference(m, keys[i], 200, 0.05, 2.0), rtol=1e-9, atol=1e-12)


def test_pdmp_recorder_reports_its_event_bound():
    p = Params(FIG3["Gamma"], FIG3["Delta"], 1.0, FIG3["tau_L"], FIG3["gamma_bar"])
    with pytest.raises(RuntimeError, match="max_events"):
        pdmp_stationary(make_pdmp_model(p, 0.125), jax.random.key(0), 4, 100, 0.05, 10.0, max_events=50)
