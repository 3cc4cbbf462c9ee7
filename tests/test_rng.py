"""The engine's random numbers (dryfric_jax.rng): the bits, uniforms and keys are jax.random's bit
for bit, the normals Box-Muller pairs of the bits' uniforms (float64: one 64-bit number's two words; the
formula in long double, to rounding); every lane draws exactly its per-key numbers, on the CPU path
(unrolled threefry) and through the lane engine's draws."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import rng
from dryfric_jax.di import make_di_model
from dryfric_jax.excursions import draw_block
from dryfric_jax.pdmp import make_pdmp_model


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
@pytest.mark.parametrize("block,n", [(128, 2), (7, 4), (1, 2), (5, 3)])
def test_normals_are_the_per_key_normal_and_uniforms_jax_random_bit_for_bit(key, dtype, block, n):
    """(Normals come in pairs, so n = 3 is drawn for the uniforms only.)"""
    keys = jax.random.split(key, 37)
    ref_u = jax.vmap(lambda k: jax.random.uniform(k, (block, n), dtype, 0.25, 3.0))(keys)
    got_u = jax.jit(lambda ks: rng.uniforms(ks, block, n, dtype, 0.25, 3.0))(keys)
    if n % 2 == 0:
        ref_n = jax.vmap(lambda k: rng.normal(k, (block, n), dtype))(keys)  # (lanes, block, n)
        got_n = jax.jit(lambda ks: rng.normals(ks, block, n, dtype))(keys)
    for c in range(n):
        np.testing.assert_array_equal(np.asarray(got_u[c]), np.asarray(ref_u[:, :, c]).T)
        if n % 2 == 0:
            assert got_n[c].shape == (block, 37) and got_n[c].dtype == dtype
            np.testing.assert_array_equal(np.asarray(got_n[c]), np.asarray(ref_n[:, :, c]).T)
    # the CPU path is the hand-compiled one: the hash itself against JAX's primitive
    kd = jax.random.key_data(keys)
    i = jnp.arange(5, dtype=jnp.uint32)
    ours = rng.threefry2x32(kd[:, 0, None], kd[:, 1, None], i[None] * 0, i[None])
    theirs = jax.vmap(lambda k: jax.random.bits(k, (5,), jnp.uint64))(keys)
    joined = (np.asarray(ours[0], np.uint64) << np.uint64(32)) | np.asarray(ours[1], np.uint64)
    np.testing.assert_array_equal(joined, np.asarray(theirs))
    np.testing.assert_array_equal(np.asarray(ours[0] ^ ours[1]),
                                  np.asarray(jax.vmap(lambda k: jax.random.bits(k, (5,), jnp.uint32))(keys)))


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_normal_is_box_muller_of_the_bits(key, dtype):
    """The definition, computed independently in long double: pair j (numbers 2j, 2j + 1 of the last axis) has
    u = (k + 1/2) 2^-m, t = k' 2^-m and Z = sqrt(-2 ln u) (cos 2 pi t, sin 2 pi t), where (k, k') are, in
    float32, the top m = 23 bits of numbers 2j and 2j + 1 of ``jax.random.bits`` (uint32) and, in float64,
    the high and low 32-bit words (m = 32) of number j of ``jax.random.bits`` (uint64): within 6 ulp plus the
    long double angle's own rounding (2 pi t ~ 1e-18 absolute; tests/test_boxmuller.py checks the zeros)."""
    if dtype == jnp.float64:
        m, w = 32, np.asarray(jax.random.bits(key, (100_000,), jnp.uint64))
        k = np.stack([w >> np.uint64(32), w & np.uint64(0xFFFFFFFF)], -1).astype(np.longdouble)
    else:
        m, bits = 23, np.asarray(jax.random.bits(key, (100_000, 2), jnp.uint32))
        k = (bits >> np.uint32(9)).astype(np.longdouble)
    u, t = (k[:, 0] + 0.5) * np.longdouble(2.0) ** -m, k[:, 1] * np.longdouble(2.0) ** -m
    assert u.min() > 0 and u.max() < 1 and t.min() >= 0 and t.max() < 1
    two_pi = 8 * np.arctan(np.longdouble(1))
    r = np.sqrt(-2 * np.log(u))
    ref = np.stack([r * np.cos(two_pi * t), r * np.sin(two_pi * t)], -1)
    got = np.asarray(rng.normal(key, (100_000, 2), dtype))
    assert got.dtype == dtype
    err = np.abs(got.astype(np.longdouble) - ref)
    assert np.all(err <= 6 * np.spacing(np.abs(ref).astype(dtype)).astype(np.longdouble) + 1e-17)
    # a flat shape pairs neighbours the same way
    np.testing.assert_array_equal(np.asarray(rng.normal(key, (200_000,), dtype)), got.reshape(-1))
    with pytest.raises(ValueError, match="last dimension must be even"):
        rng.normal(key, (4, 3), dtype)
    with pytest.raises(ValueError, match="last dimension must be even"):
        rng.normals(jax.random.split(key, 2), 4, 3, dtype)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_chains_draw_every_lane_as_one_lane_at_a_time(key, dtype):
    """``draw_lanes`` (what the engine uses) gives each lane exactly its ``draw``: the engine's
    streams are those of the per-lane definition."""
    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    keys = jax.random.split(key, 16)
    for chain in (make_di_model(p, 0.02, dtype), make_pdmp_model(p, 0.3, dtype)):
        got = jax.jit(lambda ks: draw_block(chain, ks, 3, 64))(keys)
        ref = jax.vmap(lambda k: chain.draw(jax.random.fold_in(k, 3), 64), out_axes=1)(keys)
        for g, r in zip(got, ref):
            np.testing.assert_array_equal(np.asarray(g), np.asarray(r))


def test_other_dtypes_are_refused(key):
    with pytest.raises(ValueError, match="dtype must be float32 or float64"):
        rng.normals(jax.random.split(key, 2), 4, 2, jnp.float16)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_the_jax_random_path_has_the_same_layout(dtype):
    """The path a GPU takes (``jax.random.bits`` through :func:`rng.normal` under ``vmap``) is also
    the one for keys of another generator: run it here with rbg keys and check its (block, lanes)
    layout against the per-lane draws."""
    keys = jax.random.split(jax.random.key(5, impl="rbg"), 9)
    ref = jax.vmap(lambda k: rng.normal(k, (6, 2), dtype))(keys)
    ref_u = jax.vmap(lambda k: jax.random.uniform(k, (6, 2), dtype, 0.5, 2.0))(keys)
    got, got_u = rng.normals(keys, 6, 2, dtype), rng.uniforms(keys, 6, 2, dtype, 0.5, 2.0)
    for c in range(2):
        np.testing.assert_array_equal(np.asarray(got[c]), np.asarray(ref[:, :, c]).T)
        np.testing.assert_array_equal(np.asarray(got_u[c]), np.asarray(ref_u[:, :, c]).T)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_rows_of_a_long_stream_are_the_stream(key, dtype):
    """``start``: rows [start, start + block) of every lane's ``normal(key, (rows, 2))``, the same
    numbers as the stream drawn at once, on the CPU path and on the plain hash (no ``lax.cond``)
    that other platforms compile."""
    keys = jax.random.split(key, 5)
    ref = jax.vmap(lambda k: rng.normal(k, (300, 2), dtype))(keys)
    draw = jax.jit(lambda ks, s: rng.normals(ks, 50, 2, dtype, start=s))
    plain = jax.jit(lambda kd, s: rng._bits(kd, 50, 2, dtype, s, materialise=False, pairs=True))
    for s in (0, 7, 128, 250):
        got = draw(keys, s)
        bits = plain(jax.random.key_data(keys), s)
        for c in range(2):
            np.testing.assert_array_equal(np.asarray(got[c]), np.asarray(ref[:, s:s + 50, c]).T)
            np.testing.assert_array_equal(np.asarray(rng._normal(*bits, dtype)[c]), np.asarray(ref[:, s:s + 50, c]).T)
    with pytest.raises(ValueError, match="threefry"):
        rng.normals(jax.random.split(jax.random.key(1, impl="rbg"), 2), 4, 2, dtype, start=3)


@pytest.mark.parametrize("impl", ["threefry2x32", "rbg"])
def test_key_derivations_are_jax_random_bit_for_bit(impl):
    """The engine derives its block keys (fold_in), draw and coin keys (split) and coin uniforms
    through rng, elementwise (also under vmap): the same keys and numbers as jax.random."""
    keys = jax.random.split(jax.random.key(7, impl=impl), 6)
    same = lambda a, b: np.testing.assert_array_equal(jax.random.key_data(a), jax.random.key_data(b))  # noqa: E731
    d = jnp.array([0, 1, 5, 2**31 + 3, 2**32 + 4, 77], jnp.int64)
    same(jax.jit(rng.fold_in)(keys, d), jax.vmap(jax.random.fold_in)(keys, d))
    same(jax.jit(rng.fold_in)(keys, 9), jax.vmap(jax.random.fold_in, (0, None))(keys, 9))
    for i in (0, 1):
        ref = jax.vmap(lambda k: jax.random.split(k)[i])(keys)
        same(jax.jit(lambda k: rng.split_at(k, i))(keys), ref)
        same(jax.jit(jax.vmap(lambda k: rng.split_at(k, i)))(keys), ref)
    for dtype in (jnp.float32, jnp.float64):
        tiny = float(jnp.finfo(dtype).tiny)
        ref = jax.vmap(lambda k: jax.random.uniform(k, (), dtype, minval=tiny))(keys)
        np.testing.assert_array_equal(jax.jit(lambda k: rng.uniform(k, dtype, tiny))(keys), ref)
        np.testing.assert_array_equal(jax.jit(jax.vmap(lambda k: rng.uniform(k, dtype, tiny)))(keys), ref)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_the_spare_uniform_is_the_unused_low_bits(key, dtype):
    """normals_and_spare: the two normals are normals(keys, block, 2)'s bit for bit, and the third number is, in
    float32, made of the low bits the Box-Muller transform does not read, (l_u 2^9 + l_t + 1/2) 2^-18, and in
    float64 (whose pair reads all 64 bits of its hash) the midpoint (k + 1/2) 2^-52 of the top 52 bits of number
    block + r of jax.random.bits(key, (2 block,), uint64); computed here from jax.random.bits; the CPU path, the
    per-key definition and the path a GPU takes (rbg keys through vmap) agree bit for bit."""
    keys = jax.random.split(key, 19)
    got = jax.jit(lambda ks: rng.normals_and_spare(ks, 64, dtype))(keys)
    plain = rng.normals(keys, 64, 2, dtype)
    if dtype == jnp.float64:
        w = np.asarray(jax.vmap(lambda k: jax.random.bits(k, (128,), jnp.uint64))(keys))[:, 64:]  # (lanes, block)
        k, cells = (w >> np.uint64(12)).astype(np.float64), 52
    else:
        bits = np.asarray(jax.vmap(lambda k: jax.random.bits(k, (64, 2), jnp.uint32))(keys))  # (lanes, block, 2)
        k = ((bits[:, :, 0] & 511).astype(np.int64) << 9) | (bits[:, :, 1] & 511).astype(np.int64)
        cells = 18
    for c in range(2):
        np.testing.assert_array_equal(np.asarray(got[c]), np.asarray(plain[c]))
    np.testing.assert_array_equal(np.asarray(got[2]), ((k + 0.5) * 2.0 ** -cells).astype(dtype).T)
    # the midpoints of 2^cells cells: never 0 (a 0 would take any crossing chance > 0 as a crossing), never 1
    u = np.asarray(got[2])
    assert u.min() >= 2.0 ** (-cells - 1) and u.max() <= 1 - 2.0 ** (-cells - 1)
    ref = jax.vmap(lambda kk: rng.normal_pair_and_spare(kk, 64, dtype))(keys)
    for c in range(3):
        np.testing.assert_array_equal(np.asarray(got[c]), np.asarray(ref[:, :, c]).T)
    rbg = jax.random.split(jax.random.key(5, impl="rbg"), 9)
    via = rng.normals_and_spare(rbg, 6, dtype)
    ref = jax.vmap(lambda kk: rng.normal_pair_and_spare(kk, 6, dtype))(rbg)
    for c in range(3):
        np.testing.assert_array_equal(np.asarray(via[c]), np.asarray(ref[:, :, c]).T)


def test_the_spare_uniform_is_uniform_and_independent_of_its_normals(key):
    """2^20 float64 draws (fixed key): the spare uniform's 64 equal bins and its 8 bins crossed with the pair's
    8 angle sectors (the normals' t) and with 4 radius classes (their u) pass a chi^2 test at the 99.9% level
    (Wilson-Hilferty): the bits of a hash are independent, so the bridge's coin is independent of its step."""
    z1, z2, u = (np.asarray(a).ravel() for a in rng.normals_and_spare(jax.random.split(key, 1024), 1024,
                                                                      jnp.float64))
    assert u.min() >= 0.0 and u.max() < 1.0

    def chi2_ok(counts):
        counts = np.asarray(counts, float)
        exp = counts.sum(1, keepdims=True) * counts.sum(0, keepdims=True) / counts.sum() if counts.ndim == 2 \
            else np.full_like(counts, counts.mean())
        df = counts.size - 1 if counts.ndim == 1 else (counts.shape[0] - 1) * (counts.shape[1] - 1)
        stat = ((counts - exp) ** 2 / exp).sum()
        hi = df * (1 - 2 / (9 * df) + 3.09 * np.sqrt(2 / (9 * df))) ** 3
        return stat < hi, (stat, hi)

    ok, why = chi2_ok(np.bincount((u * 64).astype(int), minlength=64))
    assert ok, why
    sector = ((np.arctan2(z2, z1) + np.pi) / (2 * np.pi) * 8).astype(int) % 8
    radius = np.digitize(z1**2 + z2**2, [0.575, 1.386, 2.773])  # chi^2_2 quartiles
    for cls, n in ((sector, 8), (radius, 4)):
        table = np.zeros((8, n))
        np.add.at(table, ((u * 8).astype(int), cls), 1)
        ok, why = chi2_ok(table)
        assert ok, why
