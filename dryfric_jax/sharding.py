"""Independent paths over all local devices: the lane axis of a jitted function split evenly.

Brute force and the path scenes (:mod:`dryfric_jax.bruteforce`, :mod:`dryfric_jax.paths`, the PDMP's in
:mod:`dryfric_jax.pdmp`) run many independent paths; a plain ``jax.jit`` would run them all on the first device
(one CPU core of the forced host devices, one GPU).  :func:`over_lanes` runs each device's share of the
lanes in its own copy of the function (``shard_map``, no communication), so a path's numbers
do not depend on the device count, up to the last bits: XLA:CPU compiles each shard's shape to
its own code (of 6 brute-force paths on 1 and 3 devices, one differed by 1 unit in the 16th
digit; the lane engine's DI estimates agree bit for bit, tested, its PDMP's to the last bits: README).  (The
lane engine shards its rounds itself: :func:`dryfric_jax.excursions._sharded_round`.)
"""
from __future__ import annotations

from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec


@lru_cache(maxsize=None)
def _compiled(fn, static: tuple, lane_args: tuple, devices: tuple):
    f = partial(fn, **dict(static))
    if len(devices) == 1:
        return jax.jit(f)
    mesh = Mesh(np.array(devices), ("lanes",))
    specs = tuple(PartitionSpec("lanes") if a else PartitionSpec() for a in lane_args)
    return jax.jit(jax.shard_map(f, mesh=mesh, in_specs=specs, out_specs=PartitionSpec("lanes"), check_vma=False))


def over_lanes(fn, args: tuple, lane_args: tuple, **static):
    """``fn(*args, **static)`` jitted, with axis 0 of the arguments flagged in ``lane_args`` (and
    of every output) split over the local devices.  The lane count is padded to a multiple of
    the device count by repeating lanes, whose outputs are dropped.  Compiled once per
    ``fn``, static values and device set (``fn`` must be a module-level function)."""
    devices = tuple(jax.local_devices())
    n = next(a for a, flag in zip(args, lane_args) if flag).shape[0]
    pad = -n % len(devices)
    if pad:
        args = tuple(jnp.concatenate([a, a[jnp.arange(pad) % n]]) if flag else a for a, flag in zip(args, lane_args))
    out = _compiled(fn, tuple(sorted(static.items())), tuple(lane_args), devices)(*args)
    return jax.tree_util.tree_map(lambda o: o[:n], out) if pad else out
