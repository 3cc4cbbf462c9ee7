r"""Where the random numbers come from: a block of every lane's numbers, drawn at once.

The numbers are exactly ``jax.random.normal`` / ``jax.random.uniform`` of each lane's key (the
threefry2x32 generator, JAX's default, with ``jax_threefry_partitionable``, JAX's default): the
module only compiles them differently on a CPU.  JAX lowers threefry's 20 rounds there as a
rolled loop of 5 iterations (for compile time), which writes both 32-bit words of every counter
to memory and reads them back at each iteration.  Here the rounds are unrolled, so a block's
hashes are one fused kernel, and the bits are materialised by a ``lax.cond`` whose branches
are the same function (its predicate does not matter): without it XLA:CPU would fuse the hash
into every consumer of the bits and recompute it there (the float64 normal transform has three).

For counter :math:`i` of a lane with key :math:`(k_1, k_2)`, ``(a, b) = threefry2x32(k, (0, i))``
and the bits are :math:`a \,\|\, b` (64-bit numbers) or :math:`a \oplus b` (32-bit); the mantissa
bits give :math:`f \in [0, 1)`, and

.. math::
    U = \max(lo, f\,(hi - lo) + lo), \qquad Z = \sqrt2\,\operatorname{erf}^{-1}(U)
    \ \text{with}\ (lo, hi) = (\operatorname{nextafter}(-1, 0), 1),

as in ``jax.random``.  Measured, 256 lanes x 128 steps x 2 normals per block, one CPU device:
float64 3.6e7 -> 7.6e7 lane-steps/s, float32 4.7e7 -> 2.7e8 (``tests/test_rng.py`` checks the
numbers are bit-identical to ``jax.random``).  On other platforms (a GPU, whose lowering is
already unrolled) :func:`normals` and :func:`uniforms` call ``jax.random`` itself, except for
rows of a longer stream (``start``), which they hash the same way without the ``lax.cond``.

Keys are derived the same way: ``fold_in(key, d)`` and ``split(key)[i]`` are the keys
``threefry2x32(key, (0, d))`` and ``threefry2x32(key, (0, i))``; :func:`fold_in`, :func:`split_at`
and :func:`uniform` (one number per key) compute them elementwise, where JAX's CPU lowering runs
one rolled loop per call (the lane engine derives three keys and a coin per lane and block).
Keys of another generator (``rbg``, ``unsafe_rbg``) go through ``jax.random`` under ``vmap``: for
those JAX's batched numbers differ from one call per key, so "the same as ``jax.random``" holds
for threefry keys only (audit).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))


def threefry2x32(k1, k2, x0, x1):
    """The threefry2x32 hash (Salmon et al. 2011, 20 rounds) of the counter pair ``(x0, x1)``
    under the key ``(k1, k2)``, unrolled; uint32 arrays that broadcast together."""
    ks = (k1, k2, k1 ^ k2 ^ np.uint32(0x1BD11BDA))
    x0, x1 = x0 + ks[0], x1 + ks[1]
    for j in range(5):
        for r in _ROTATIONS[j % 2]:
            x0 = x0 + x1
            x1 = x0 ^ ((x1 << np.uint32(r)) | (x1 >> np.uint32(32 - r)))
        x0, x1 = x0 + ks[(j + 1) % 3], x1 + ks[(j + 2) % 3] + np.uint32(j + 1)
    return x0, x1


def _uint(dtype):
    return np.uint64 if np.dtype(dtype).itemsize == 8 else np.uint32


def _join(a, b, wide: bool):
    """``jax.random``'s bits from one hash ``(a, b)``: :math:`a \\| b` (64-bit) or :math:`a \\oplus b`."""
    return (a.astype(jnp.uint64) << np.uint64(32)) | b.astype(jnp.uint64) if wide else a ^ b


def materialised(compute, kd):
    """``compute()``, materialised: a ``lax.cond`` on the key data ``kd`` ((lanes, 2)) whose two branches are
    ``compute`` itself, so XLA:CPU writes its outputs once instead of fusing (and recomputing) the
    hash into every consumer (module docstring).  The predicate does not matter."""
    return lax.cond(kd[0, 0] > np.uint32(0x7FFFFFFF), compute, compute)


def _bits(kd, block: int, n: int, dtype, start=0, materialise: bool = True):
    """The random bits of counters ``(start + r) n + c`` (row r, column c) of every lane (key
    data ``kd``, (lanes, 2)): one (block, lanes) array per column, materialised by the
    ``lax.cond`` (module docstring) if ``materialise`` (on a CPU)."""
    k1, k2 = kd[:, 0][None, :], kd[:, 1][None, :]
    wide = np.dtype(dtype).itemsize == 8
    rows = jnp.arange(block, dtype=jnp.uint32)[:, None] + jnp.asarray(start).astype(jnp.uint32)

    def hashes():
        out = []
        for c in range(n):
            i = rows * np.uint32(n) + np.uint32(c)
            out.append(_join(*threefry2x32(k1, k2, jnp.zeros_like(i), i), wide))
        return tuple(out)

    return materialised(hashes, kd) if materialise else hashes()


def _unit(bits, dtype, lo, hi):
    """``jax.random.uniform``'s transform of the bits to [lo, hi)."""
    dtype = np.dtype(dtype)
    ut = _uint(dtype)
    one = np.array(1.0, dtype).view(ut)
    f = lax.bitcast_convert_type((bits >> ut(8 * dtype.itemsize - np.finfo(dtype).nmant)) | one, dtype)
    lo, hi = np.array(lo, dtype), np.array(hi, dtype)
    return lax.max(lo, (f - np.array(1.0, dtype)) * (hi - lo) + lo)


def _normal(bits, dtype):
    dtype = np.dtype(dtype)
    lo = np.nextafter(np.array(-1.0, dtype), np.array(0.0, dtype), dtype=dtype)
    return np.array(np.sqrt(2), dtype) * lax.erf_inv(_unit(bits, dtype, lo, 1.0))


def per_lane(sample, keys, n: int):
    """``jax.random`` itself: ``sample(key)`` (an array of shape (block, n)) for every lane, as n
    arrays of shape (block, lanes).  The path off a CPU, and the reference."""
    zs = jax.vmap(sample, out_axes=2)(keys)
    return tuple(zs[:, c] for c in range(n))


def is_threefry(keys) -> bool:
    """True for keys of JAX's default generator (threefry2x32, partitionable, JAX's default),
    which this module compiles itself on a CPU and which row offsets (``start``) need."""
    return str(jax.random.key_impl(keys)) == "threefry2x32" and jax.config.jax_threefry_partitionable


def _hashed(keys, x1, finish, via_jax):
    """``finish(a, b)`` of ``(a, b) = threefry2x32(key, (0, x1))`` for every key (any shape),
    elementwise: one fused kernel on a CPU, where JAX's own lowering is a rolled loop of 5
    iterations per call; ``via_jax(keys)`` on other platforms and for other generators."""
    if not is_threefry(keys):
        return via_jax(keys)

    def fused(ks):
        kd = jax.random.key_data(ks)
        x1_ = jnp.broadcast_to(jnp.asarray(x1).astype(jnp.uint32), kd.shape[:-1])
        return finish(*threefry2x32(kd[..., 0], kd[..., 1], jnp.zeros_like(x1_), x1_))

    return lax.platform_dependent(keys, cpu=fused, default=via_jax)


def _each(f, keys, *args):
    """``f(key, *arg)`` for every key (any shape; ``args`` broadcast to it), through ``vmap``."""
    flat = [jnp.broadcast_to(a, keys.shape).reshape(-1) for a in args]
    out = jax.vmap(f)(keys.reshape(-1), *flat)
    return out.reshape(keys.shape + out.shape[1:])


def _key(a, b):
    return jax.random.wrap_key_data(jnp.stack([a, b], -1), impl="threefry2x32")


def fold_in(keys, data):
    """``jax.random.fold_in(key, data)`` of every key (``data``: an integer, or one per key): the
    key ``threefry2x32(key, (0, data))`` (partitionable threefry)."""
    return _hashed(keys, data, _key, lambda ks: _each(jax.random.fold_in, ks, data))


def split_at(keys, i: int):
    """``jax.random.split(key)[i]`` of every key (i = 0 or 1): the key ``threefry2x32(key, (0, i))``."""
    return _hashed(keys, i, _key, lambda ks: _each(lambda k: jax.random.split(k)[i], ks))


def _check_dtype(dtype) -> None:
    if np.dtype(dtype) not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"dtype must be float32 or float64 (got {np.dtype(dtype).name})")


def uniform(keys, dtype, minval: float = 0.0, maxval: float = 1.0):
    """``jax.random.uniform(key, (), dtype, minval, maxval)`` of every key, elementwise (so it also
    runs under ``vmap``): counter 0's bits, transformed as in :func:`uniforms`."""
    _check_dtype(dtype)
    wide = np.dtype(dtype).itemsize == 8
    return _hashed(keys, 0, lambda a, b: _unit(_join(a, b, wide), dtype, minval, maxval),
                   lambda ks: _each(lambda k: jax.random.uniform(k, (), dtype, minval, maxval), ks))


def _draw(keys, block: int, n: int, dtype, sample, transform, start=None):
    """``per_lane(sample, keys, n)``; on a CPU, for threefry keys, the same numbers as
    ``transform`` of the fused hash's bits (module docstring).  With ``start``, rows
    ``[start, start + block)`` of the per-lane array (``sample`` is then not used): the fused
    hash on every platform, materialised on a CPU only (a GPU would read the ``lax.cond``'s
    predicate back to the host)."""
    _check_dtype(dtype)
    via_jax = lambda ks: per_lane(sample, ks, n)
    if not is_threefry(keys):
        if start is not None:
            raise ValueError("row offsets (start) need threefry keys, JAX's default generator")
        return via_jax(keys)
    s = 0 if start is None else start
    fused = lambda m: lambda ks: tuple(transform(b) for b in _bits(jax.random.key_data(ks), block, n, dtype, s, m))
    return lax.platform_dependent(keys, cpu=fused(True), default=via_jax if start is None else fused(False))


def normals(keys, block: int, n: int, dtype, start=None):
    """Every lane's ``jax.random.normal(key, (block, n), dtype)``, as n arrays of shape
    (block, lanes) (column c of lane l is ``out[c][:, l]``): a step reads one contiguous row.

    Args:
        keys: typed keys, one per lane (shape (lanes,)).
        block, n: numbers per lane, (block, n).
        dtype: float32 or float64.
        start: if given (an int or a traced integer), rows ``[start, start + block)`` of every
            lane's ``jax.random.normal(key, (rows, n), dtype)`` for any ``rows >= start + block``
            with ``rows * n < 2**32``: a long stream drawn a block at a time, the same numbers
            as drawn at once (threefry keys only).
    """
    return _draw(keys, block, n, dtype, lambda k: jax.random.normal(k, (block, n), dtype),
                 lambda b: _normal(b, dtype), start)


def uniforms(keys, block: int, n: int, dtype, minval: float = 0.0, maxval: float = 1.0):
    """Every lane's ``jax.random.uniform(key, (block, n), dtype, minval, maxval)``, laid out as
    :func:`normals`."""
    return _draw(keys, block, n, dtype, lambda k: jax.random.uniform(k, (block, n), dtype, minval, maxval),
                 lambda b: _unit(b, dtype, minval, maxval))
