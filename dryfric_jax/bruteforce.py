r"""Brute force on a fixed horizon (paper section 4.2, Algorithm 2's idea on the DI).

N' independent paths of the same discrete chain as :mod:`dryfric_jax.excursions` (no
regeneration, no reset) start at :math:`(X, V) = (x_{\Delta}, 0)`, optionally run ``burn_in``
steps that are not counted, and accumulate :math:`U(t)` over ``n_steps`` steps (t = n h).
:math:`\hat D^t_{N'}` is biased by :math:`O(1/t)`; choose t long against the correlation time.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .di import DIModel
from .excursions import BLOCK


@partial(jax.jit, static_argnames=("block",))
def _run_paths(model: DIModel, keys, n_burn_blocks, n_blocks, *, block: int):
    dt = model.h.dtype

    def lane(key):
        def blk(b, c):
            X, V, U = c
            k1 = jax.random.fold_in(key, b)
            zs = jax.random.normal(k1, (block, 2), dt)
            count = b >= n_burn_blocks

            def step(i, c2):
                X, V, U = c2
                _, Xn, Vn, dU = model.move(X, V, zs[i, 0], zs[i, 1])
                return Xn, Vn, U + jnp.where(count, dU, 0.0)

            return jax.lax.fori_loop(0, block, step, (X, V, U))

        init = (model.x_plus, jnp.zeros((), dt), jnp.zeros((), jnp.float64))
        return jax.lax.fori_loop(0, n_burn_blocks + n_blocks, blk, init)[2]

    return jax.vmap(lane)(keys)


def simulate_bruteforce(model: DIModel, key, n_paths: int, n_steps: int, *, burn_in_steps: int = 0,
                        block: int = BLOCK, chunk_lanes: int = 4096) -> tuple[np.ndarray, float]:
    """U(t) of ``n_paths`` paths over ``n_steps`` steps (rounded up to whole blocks).

    Returns:
        ``(U, t)`` in nondimensional units, t = (steps actually counted) x h.
    """
    n_blocks = -(-n_steps // block)
    n_burn = -(-burn_in_steps // block)
    lanes = min(chunk_lanes, n_paths)
    out = []
    for c in range(-(-n_paths // lanes)):
        keys = jax.random.split(jax.random.fold_in(key, c), lanes)
        out.append(np.asarray(_run_paths(model, keys, n_burn, n_blocks, block=block)))
    U = np.concatenate(out)[:n_paths]
    return U, n_blocks * block * float(model.h)
