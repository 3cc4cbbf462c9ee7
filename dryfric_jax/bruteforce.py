r"""Brute force on a fixed horizon (paper section 4.2, Algorithm 2's idea on the DI).

N' independent paths of the same discrete chain as :mod:`dryfric_jax.excursions` (no
regeneration, no reset) start at :math:`(X, V) = (x_{\Delta}, 0)`, optionally run ``burn_in``
steps that are not counted, and accumulate :math:`U(t)` over exactly ``n_steps`` steps (t = n h).
:math:`\hat D^t_{N'}` is biased by :math:`O(1/t)`; choose t long against the correlation time.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .di import DIModel
from . import rng
from .excursions import BLOCK, block_keys
from .plan import check_count
from .sharding import over_lanes


def _run_paths(model: DIModel, keys, burn_in_steps, n_steps, *, block: int):
    """U of every lane over steps ``[burn_in_steps, burn_in_steps + n_steps)`` of its chain, run
    in whole blocks (the steps after them are run and not counted); lane l's block b draws
    ``rng.normal(fold_in(keys[l], b), (block, 2))`` (through :func:`dryfric_jax.rng.normals`, the
    same numbers, all lanes at once)."""
    dt = model.h.dtype
    n = keys.shape[0]

    def blk(b, c):
        z1, z2 = rng.normals(block_keys(keys, b), block, 2, dt)

        def step(i, c2):
            X, V, U = c2
            _, Xn, Vn, dU = model.move(X, V, z1[i], z2[i])
            g = b * block + i - burn_in_steps  # the step's index after the burn-in (one for all lanes)
            return Xn, Vn, U + jnp.where((g >= 0) & (g < n_steps), dU, 0.0)

        return jax.lax.fori_loop(0, block, step, c)

    init = (jnp.full((n,), model.x_plus, dt), jnp.zeros((n,), dt), jnp.zeros((n,), jnp.float64))
    n_blocks = (burn_in_steps + n_steps + block - 1) // block
    return jax.lax.fori_loop(0, n_blocks, blk, init)[2]


def simulate_bruteforce(model: DIModel, key, n_paths: int, n_steps: int, *, burn_in_steps: int = 0,
                        block: int = BLOCK, chunk_lanes: int = 4096) -> tuple[np.ndarray, float]:
    """U(t) of ``n_paths`` paths over exactly ``n_steps`` steps after ``burn_in_steps`` uncounted
    ones (the chain runs in whole blocks of ``block`` steps; the rest of the last block is not
    counted).

    Returns:
        ``(U, t)`` in nondimensional units, t = n_steps h.
    """
    n_paths, n_steps = check_count("n_paths", n_paths, 1), check_count("n_steps", n_steps, 1)
    burn_in_steps = check_count("burn_in_steps", burn_in_steps, 0)
    lanes = min(check_count("chunk_lanes", chunk_lanes, 1), n_paths)
    out = []
    for c in range(-(-n_paths // lanes)):
        # the last chunk runs only its paths (padded to a full chunk it cost up to twice the work asked for, and
        # the work and speed reported did not count it); the keys are those of a full chunk
        keys = jax.random.split(jax.random.fold_in(key, c), lanes)[: n_paths - c * lanes]
        out.append(np.asarray(over_lanes(_run_paths, (model, keys, jnp.asarray(burn_in_steps, jnp.int64),
                                                      jnp.asarray(n_steps, jnp.int64)),
                                         (False, True, False, False), block=block)))
    U = np.concatenate(out)[:n_paths]
    return U, n_steps * float(model.h)
