"""Independent paths split over the local devices (sharding.over_lanes): the same numbers as one
jitted function on one device, for lane counts that do not divide evenly, and no recompilation."""
import jax
import jax.numpy as jnp
import numpy as np

from dryfric_jax import sharding


def _paths(keys, x, scale, *, n):
    return x[:, None] * scale + jax.vmap(lambda k: jax.random.normal(k, (n,)))(keys)


def test_over_lanes_matches_one_device_and_does_not_recompile(key):
    for lanes in (1, 5, 8):  # 1 and 5: padded on 2 devices
        keys = jax.random.split(key, lanes)
        x = jnp.arange(lanes, dtype=jnp.float64)
        got = sharding.over_lanes(_paths, (keys, x, jnp.asarray(2.0)), (True, True, False), n=3)
        ref = jax.jit(_paths, static_argnames="n")(keys, x, 2.0, n=3)
        assert got.shape == (lanes, 3)
        np.testing.assert_array_equal(np.asarray(got), np.asarray(ref))
    f = sharding._compiled(_paths, (("n", 3),), (True, True, False), tuple(jax.local_devices()))
    size = f._cache_size()
    args = (jax.random.split(jax.random.fold_in(key, 1), 8), jnp.ones(8), jnp.asarray(3.0))  # made (compiled) first
    # XLA compilations counted while the call runs (f's cache size alone could not fail: without the lru_cache
    # each call made a new jit object, which compiled, and f's cache stayed as it was)
    compiles, listening = [], [True]
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, _s, **_kw: compiles.append(event) if listening[0] and "backend_compile" in event else None)
    try:
        sharding.over_lanes(_paths, args, (True, True, False), n=3)
        seen = len(compiles)
        jax.jit(lambda x: x * 7.25)(jnp.ones(3))  # a new function does compile: the listener hears it
    finally:
        listening[0] = False
    assert seen == 0 and len(compiles) >= 1 and f._cache_size() == size >= 1
