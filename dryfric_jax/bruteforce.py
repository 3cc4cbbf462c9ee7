r"""Brute force on a fixed horizon (paper section 4.2, Algorithm 2's idea on the DI).

N' independent paths of the same discrete chain as :mod:`dryfric_jax.excursions` (no
regeneration, no reset) start at :math:`(X, V) = (x_{\Delta}, 0)`, optionally run ``burn_in``
steps that are not counted, and accumulate :math:`U(t)` over ``n_steps`` steps (t = n h).
:math:`\hat D^t_{N'}` is biased by :math:`O(1/t)`; choose t long against the correlation time.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .di import DIModel
from . import rng
from .excursions import BLOCK, block_keys
from .sharding import over_lanes


def _run_paths(model: DIModel, keys, n_burn_blocks, n_blocks, *, block: int):
    """U of every lane after the burn-in and ``n_blocks`` blocks; lane l's block b draws
    ``jax.random.normal(fold_in(keys[l], b), (block, 2))`` (through :mod:`dryfric_jax.rng`, the same
    numbers, all lanes at once)."""
    dt = model.h.dtype
    n = keys.shape[0]

    def blk(b, c):
        z1, z2 = rng.normals(block_keys(keys, b), block, 2, dt)
        count = b >= n_burn_blocks

        def step(i, c2):
            X, V, U = c2
            _, Xn, Vn, dU = model.move(X, V, z1[i], z2[i])
            return Xn, Vn, U + jnp.where(count, dU, 0.0)

        return jax.lax.fori_loop(0, block, step, c)

    init = (jnp.full((n,), model.x_plus, dt), jnp.zeros((n,), dt), jnp.zeros((n,), jnp.float64))
    return jax.lax.fori_loop(0, n_burn_blocks + n_blocks, blk, init)[2]


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
        out.append(np.asarray(over_lanes(_run_paths, (model, keys, jnp.asarray(n_burn), jnp.asarray(n_blocks)),
                                         (False, True, False, False), block=block)))
    U = np.concatenate(out)[:n_paths]
    return U, n_blocks * block * float(model.h)
