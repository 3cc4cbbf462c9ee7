r"""Brute force on a fixed horizon (paper section 5.2, Algorithm 2's idea on the DI).

N' independent paths of the same discrete chain as :mod:`dryfric_jax.excursions` (no
regeneration, no reset) start at :math:`(X, V) = (x_{\Delta}, 0)`, optionally run ``burn_in``
steps that are not counted, and accumulate :math:`U(t)` over exactly ``n_steps`` steps (t = n h).
:math:`\hat D^t_{N'}` is biased by :math:`O(1/t)`; choose t long against the correlation time
(:func:`dryfric_jax.api.bruteforce_diffusivity` warns below 100 of them).

Path k's key is :func:`path_keys`'s, whatever the chunk of lanes it runs in: with the seed, the
block size K fixes the numbers, the chunk size does not.
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


#: paths per key group: path k's key is ``split(fold_in(key, k // KEY_GROUP), KEY_GROUP)[k % KEY_GROUP]``
KEY_GROUP = 4096


def path_keys(key, start: int, stop: int):
    r"""The keys of paths ``start .. stop - 1``: path k's is
    :math:`\mathrm{split}(\mathrm{fold\_in}(key, \lfloor k/G \rfloor), G)[k \bmod G]` with G =
    :data:`KEY_GROUP`, so a path's random stream does not depend on how the paths are chunked
    (before 0.2.6, chunk c's keys were split from ``fold_in(key, c)`` at the chunk's size, and
    ``chunk_lanes`` = 4096, 1000 and 7 gave D_t = 0.8346, 0.8346 and 0.8555 for one seed).  The
    default chunk of 4096 paths had these keys already."""
    parts = []
    for g in range(start // KEY_GROUP, (stop - 1) // KEY_GROUP + 1):
        lo, hi = max(start - g * KEY_GROUP, 0), min(stop - g * KEY_GROUP, KEY_GROUP)
        parts.append(jax.random.split(jax.random.fold_in(key, g), KEY_GROUP)[lo:hi])
    return parts[0] if len(parts) == 1 else jnp.concatenate(parts)


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
    counted).  Path k draws from :func:`path_keys`'s key k: ``block`` changes the numbers (a block
    of K steps draws its normals at once), ``chunk_lanes`` (paths compiled and run at once) does not.

    Returns:
        ``(U, t)`` in nondimensional units, t = n_steps h.
    """
    n_paths, n_steps = check_count("n_paths", n_paths, 1), check_count("n_steps", n_steps, 1)
    burn_in_steps = check_count("burn_in_steps", burn_in_steps, 0)
    lanes = min(check_count("chunk_lanes", chunk_lanes, 1), n_paths)
    out = []
    for c in range(-(-n_paths // lanes)):
        # the last chunk runs only its paths (padded to a full chunk it cost up to twice the work asked for, and
        # the work and speed reported did not count it)
        keys = path_keys(key, c * lanes, min((c + 1) * lanes, n_paths))
        out.append(np.asarray(over_lanes(_run_paths, (model, keys, jnp.asarray(burn_in_steps, jnp.int64),
                                                      jnp.asarray(n_steps, jnp.int64)),
                                         (False, True, False, False), block=block)))
    U = np.concatenate(out)[:n_paths]
    return U, n_steps * float(model.h)
