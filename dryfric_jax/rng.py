r"""Where the random numbers come from: a block of every lane's numbers, drawn at once.

The bits are exactly ``jax.random.bits`` of each lane's key (the threefry2x32 generator, JAX's
default, with ``jax_threefry_partitionable``, JAX's default), and the uniforms exactly
``jax.random.uniform``'s; the normals are Box-Muller pairs of the bits' uniforms
(:mod:`dryfric_jax.boxmuller`), not ``jax.random.normal``'s inverse error function, which XLA:CPU
evaluates with a scalar float64 logarithm.  JAX lowers threefry's 20 rounds on a CPU as a rolled
loop of 5 iterations (for compile time), which writes both 32-bit words of every counter to
memory and reads them back at each iteration.  Here the rounds are unrolled, so a block's hashes
are one fused kernel, and the bits are materialised by a ``lax.cond`` whose branches are the
same function (its predicate does not matter): without it XLA:CPU would fuse the hash into every
consumer of the bits and recompute it there.

For counter :math:`i` of a lane with key :math:`(k_1, k_2)`, ``(a, b) = threefry2x32(k, (0, i))``
and the bits are :math:`a \,\|\, b` (64-bit numbers) or :math:`a \oplus b` (32-bit).  Their top
:math:`m` bits (m = 52, 23: the mantissa) are an integer :math:`k`.  The uniform is

.. math::
    U = \max(lo, k 2^{-m} (hi - lo) + lo),

as in ``jax.random.uniform``.  The normals come in pairs, numbers :math:`2j` and :math:`2j + 1` of
the last axis (``shape[-1]`` even), from two integers :math:`k, k'` of :math:`m` bits:

.. math::
    (Z_{2j}, Z_{2j+1}) = \sqrt{-2 \ln u}\,(\cos 2\pi t, \sin 2\pi t), \qquad
    u = (k + \tfrac12)\, 2^{-m}, \quad t = k' 2^{-m}.

In float32, k and k' are the top m = 23 bits of numbers 2j and 2j + 1 of ``jax.random.bits(key,
shape, uint32)`` (t is then ``jax.random.uniform``'s number).  In float64 a pair is **one hash**:
k and k' are the two 32-bit words a and b (m = 32) of number j of ``jax.random.bits(key, shape[:-1]
+ (shape[-1] / 2,), uint64)``, its high and low halves (version 0.3.0; before it, two 64-bit numbers
and m = 52: twice the hashing, and XLA:CPU's 64-bit integer vectors, for bits the normals do not
need).  u is the midpoint of one of :math:`2^m` equally likely cells (never 0 or 1), so the pair's
law is exactly invariant under the reflections :math:`t \to 1 - t`, :math:`t \to t + 1/2`, with
:math:`|Z| \le \sqrt{2 (m + 1) \ln 2}`: 6.76 in float64 (a normal's chance to exceed it is
1.3e-11) and 5.77 in float32.  The grid moves the law by :math:`O(2^{-m})` elsewhere too
(float64: t = 1/4 and 3/4 are cells, so :math:`P(Z_1 = 0) = 2^{-31}`; the variance is
:math:`1 - 8 \cdot 10^{-11}`).  A DI step's two normals are one pair.  The numbers are the same
on every platform: on a CPU the fused hash, elsewhere (a GPU, whose lowering is already
unrolled) ``jax.random.bits`` and the same transform.

Keys are derived the same way: ``fold_in(key, d)`` and ``split(key)[i]`` are the keys
``threefry2x32(key, (0, d))`` and ``threefry2x32(key, (0, i))``; :func:`fold_in`, :func:`split_at`
and :func:`uniform` (one number per key) compute them elementwise, where JAX's CPU lowering runs
one rolled loop per call (the lane engine derives three keys and a coin per lane and block).
Keys of another generator (``rbg``, ``unsafe_rbg``) go through ``jax.random`` under ``vmap``: for
those JAX's batched numbers differ from one call per key, so "one lane as drawn alone" holds
for threefry keys only (audit).
"""
from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from . import boxmuller

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


def _bits(kd, block: int, n: int, dtype, start=0, materialise: bool = True, pairs: bool = False):
    """The random bits of counters ``(start + r) n + c`` (row r, column c) of every lane (key
    data ``kd``, (lanes, 2)): one (block, lanes) array per column, materialised by the
    ``lax.cond`` (module docstring) if ``materialise`` (on a CPU).  With ``pairs`` in float64 (the
    normals' bits), columns c and c + 1 (c even) are instead the two 32-bit words (a, b) of counter
    ``(start + r) n / 2 + c / 2``: a pair's one hash (module docstring)."""
    k1, k2 = kd[:, 0][None, :], kd[:, 1][None, :]
    wide = np.dtype(dtype).itemsize == 8
    rows = jnp.arange(block, dtype=jnp.uint32)[:, None] + jnp.asarray(start).astype(jnp.uint32)

    def hashes():
        out = []
        if pairs and wide:
            for j in range(n // 2):
                i = rows * np.uint32(n // 2) + np.uint32(j)
                out.extend(threefry2x32(k1, k2, jnp.zeros_like(i), i))
            return tuple(out)
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


# jitted so that a call outside jit rounds as inside one: XLA:CPU contracts a * b + c into a fused
# multiply-add within a fusion, which op-by-op execution does not (the numbers differed in the last bit)
@functools.partial(jax.jit, static_argnums=2)
def _normal(bits_u, bits_t, dtype):
    r""":func:`normal`'s transform of a pair's bits: :func:`boxmuller.pair` of
    :math:`u = (k + 1/2) 2^{-m}` and :math:`t = k' 2^{-m}`.  float64: ``bits_u`` and ``bits_t`` are
    one hash's two 32-bit words, k and k' themselves (m = 32), and u and t are exact whatever the
    order XLA adds and scales them in (:math:`k + \tfrac12` and the products need 33 bits).
    float32: k and k' are the top m = 23 bits of 32-bit numbers, t is :func:`_unit`'s
    (``jax.random.uniform``'s) number, and u is made exactly as :math:`(2k + 1) 2^{-m-1}` from the
    integer.  (Written as :math:`(f - 1) + 2^{-m-1}` from the bits' float f in [1, 2), XLA's
    simplifier may fold the constants into one rounded constant, as it did to 0.2.4's
    :math:`((f - 1) + 2^{-m-1}) - 1/2`.)"""
    dtype = np.dtype(dtype)
    if dtype.itemsize == 8:
        scale = np.array(2.0 ** -32, dtype)
        u = (bits_u.astype(dtype) + np.array(0.5, dtype)) * scale
        return boxmuller.pair(u, bits_t.astype(dtype) * scale)
    ut = _uint(dtype)
    m = np.finfo(dtype).nmant
    k = bits_u >> ut(8 * dtype.itemsize - m)
    u = (k * ut(2) + ut(1)).astype(dtype) * np.array(2.0 ** -(m + 1), dtype)
    return boxmuller.pair(u, _unit(bits_t, dtype, 0.0, 1.0))


def _pairs(shape) -> None:
    if not shape or shape[-1] % 2:
        raise ValueError("normals come in Box-Muller pairs: the last dimension must be even "
                         f"(got shape {tuple(shape)})")


def normal(key, shape, dtype):
    r"""The engine's standard normals of one key through Box-Muller, numbers 2j and 2j + 1 of the last axis a
    pair (module docstring; ``shape[-1]`` must be even): in float32 from numbers 2j and 2j + 1 of
    ``jax.random.bits(key, shape, uint32)``, in float64 from the high and low words of number j of
    ``jax.random.bits(key, shape[:-1] + (shape[-1] / 2,), uint64)``.  The per-key definition that
    :func:`normals` computes for every lane at once.  Not ``jax.random.normal(key, shape, dtype)``."""
    _check_dtype(dtype)
    shape = tuple(shape)
    _pairs(shape)
    return jnp.stack(_normal(*_pair_bits(key, shape[:-1] + (shape[-1] // 2,), dtype), dtype), -1).reshape(shape)


def _pair_bits(key, shape, dtype):
    """The bits of one key's pairs of :func:`normal` (``shape``: the pairs), through ``jax.random.bits``: a
    64-bit number's high and low words (float64), or two 32-bit numbers (float32)."""
    if np.dtype(dtype).itemsize == 8:
        return _halves(jax.random.bits(key, shape, jnp.uint64))
    b = jax.random.bits(key, shape[:-1] + (2 * shape[-1],), jnp.uint32)
    return b[..., 0::2], b[..., 1::2]


def _halves(w):
    """The high and low 32-bit words (a, b) of 64-bit numbers ``a || b``: a float64 pair's bits."""
    return (w >> np.uint64(32)).astype(jnp.uint32), w.astype(jnp.uint32)


def per_lane(sample, keys, n: int):
    """``sample(key)`` (an array of shape (block, n), e.g. :func:`normal` of the key) for every
    lane under ``vmap``, as n arrays of shape (block, lanes).  The path off a CPU, and the reference."""
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


def _draw(keys, block: int, n: int, dtype, sample, transform, start=None, n_out=None, bits=None):
    """``per_lane(sample, keys, n_out)`` (``n_out`` columns, n unless told); on a CPU, for threefry keys, the same
    numbers as ``transform`` of the fused hash's bits (n columns; module docstring), elsewhere ``sample`` itself.
    With ``start``, rows ``[start, start + block)`` of the per-lane array (``sample`` is then not used):
    the fused hash on every platform, materialised on a CPU only (a GPU would read the
    ``lax.cond``'s predicate back to the host).  ``bits(kd, start, materialise)``: the bits to transform, if not
    :func:`_bits`'s n columns."""
    _check_dtype(dtype)
    via_jax = lambda ks: per_lane(sample, ks, n if n_out is None else n_out)
    if not is_threefry(keys):
        if start is not None:
            raise ValueError("row offsets (start) need threefry keys, JAX's default generator")
        return via_jax(keys)
    s = 0 if start is None else start
    bits = bits or (lambda kd, s_, m: _bits(kd, block, n, dtype, s_, m))
    fused = lambda m: lambda ks: transform(bits(jax.random.key_data(ks), s, m))
    return lax.platform_dependent(keys, cpu=fused(True), default=via_jax if start is None else fused(False))


def normals(keys, block: int, n: int, dtype, start=None):
    """Every lane's :func:`normal` ``(key, (block, n), dtype)``, as n arrays of shape
    (block, lanes) (column c of lane l is ``out[c][:, l]``): a step reads one contiguous row.

    Args:
        keys: typed keys, one per lane (shape (lanes,)).
        block, n: numbers per lane, (block, n); n even (Box-Muller pairs of columns).
        dtype: float32 or float64.
        start: if given (an int or a traced integer), rows ``[start, start + block)`` of every
            lane's :func:`normal` ``(key, (rows, n), dtype)`` for any ``rows >= start + block``
            with ``rows * n < 2**32``: a long stream drawn a block at a time, the same numbers
            as drawn at once (threefry keys only).
    """
    _pairs((n,))
    return _draw(keys, block, n, dtype, lambda k: normal(k, (block, n), dtype),
                 lambda bs: sum((_normal(bs[c], bs[c + 1], dtype) for c in range(0, n, 2)), ()), start,
                 bits=lambda kd, s, m: _bits(kd, block, n, dtype, s, m, pairs=True))


def _spare(bits_u, bits_t, dtype):
    r"""float32: a uniform in (0, 1) from the low bits of a pair's two numbers that :func:`_normal` leaves unused
    (it reads only their top 23 bits): :math:`(k + \tfrac12)\,2^{-18}` with :math:`k = l_u 2^9 + l_t`, :math:`l`
    the low 9 bits: the midpoint of one of :math:`2^{18}` equally likely cells, independent of the pair (the bits
    of a hash are), never 0 or 1.  (With :math:`k 2^{-18}`, 0.2.10's, a draw of exactly 0, one step in
    :math:`2^{18}`, took any crossing chance above 0 as a crossing: a stuck particle far from the threshold then
    reversed.)"""
    ut, s = np.uint32, 9
    low = ut((1 << s) - 1)
    k = ((bits_u & low) << ut(s + 1)) | ((bits_t & low) << ut(1)) | ut(1)  # 2k + 1, exact
    return k.astype(dtype) * np.array(2.0 ** (-2 * s - 1), dtype)


def _spare64(w):
    r"""float64: the uniform :math:`(k + \tfrac12)\,2^{-52}` of a 64-bit number's top 52 bits k, the midpoint of
    one of :math:`2^{52}` equally likely cells, never 0 or 1.  (A float64 pair reads all 64 bits of its hash,
    so its spare is another hash's: :func:`normal_pair_and_spare`.)"""
    k = ((w >> np.uint64(12)) << np.uint64(1)) | np.uint64(1)  # 2k + 1 < 2^53, exact
    return k.astype(jnp.float64) * np.array(2.0 ** -53, np.float64)


def normal_pair_and_spare(key, block: int, dtype):
    """One key's ``(block, 3)``: columns 0, 1 are :func:`normal` ``(key, (block, 2), dtype)`` and column 2 a
    uniform in (0, 1) independent of them: in float32 :func:`_spare` of the pair's own bits (no extra hash), in
    float64 :func:`_spare64` of number ``block + r`` of ``jax.random.bits(key, (2 block,), uint64)`` for row r
    (the pairs are numbers 0 to block - 1).  The per-key definition that :func:`normals_and_spare` computes for
    every lane at once."""
    _check_dtype(dtype)
    if np.dtype(dtype).itemsize == 8:
        w = jax.random.bits(key, (2 * block,), jnp.uint64)
        return jnp.stack(_normal(*_halves(w[:block]), dtype) + (_spare64(w[block:]),), -1)
    u, t = _pair_bits(key, (block,), dtype)
    return jnp.stack(_normal(u, t, dtype) + (_spare(u, t, dtype),), -1)


def normals_and_spare(keys, block: int, dtype):
    """Every lane's :func:`normal_pair_and_spare` as 3 arrays of shape (block, lanes): the two normals are
    exactly :func:`normals` ``(keys, block, 2, dtype)``'s."""
    if np.dtype(dtype).itemsize == 8:
        def bits(kd, s, m):
            both = lambda: _bits(kd, block, 2, dtype, 0, False, pairs=True) + _bits(kd, block, 1, dtype, block, False)
            return materialised(both, kd) if m else both()

        return _draw(keys, block, 2, dtype, lambda k: normal_pair_and_spare(k, block, dtype),
                     lambda bs: _normal(bs[0], bs[1], dtype) + (_spare64(bs[2]),), n_out=3, bits=bits)
    return _draw(keys, block, 2, dtype, lambda k: normal_pair_and_spare(k, block, dtype),
                 lambda bs: _normal(bs[0], bs[1], dtype) + (_spare(bs[0], bs[1], dtype),), n_out=3)


def uniforms(keys, block: int, n: int, dtype, minval: float = 0.0, maxval: float = 1.0):
    """Every lane's ``jax.random.uniform(key, (block, n), dtype, minval, maxval)``, laid out as
    :func:`normals`."""
    return _draw(keys, block, n, dtype, lambda k: jax.random.uniform(k, (block, n), dtype, minval, maxval),
                 lambda bs: tuple(_unit(b, dtype, minval, maxval) for b in bs))
