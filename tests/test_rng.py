"""The engine's random numbers (dryfric_jax.rng): the bits, uniforms and keys are jax.random's bit
for bit, the normals the inverse normal CDF of the bits' cells (scipy's, to rounding) and close to
jax.random.normal's; every lane draws exactly its per-key numbers, on the CPU path (unrolled
threefry) and through the lane engine's draws."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import ndtri as scipy_ndtri

import dryfric_jax as dj
from dryfric_jax import rng
from dryfric_jax.di import make_di_model
from dryfric_jax.excursions import draw_block
from dryfric_jax.pdmp import make_pdmp_model


def _uint(dtype):
    return np.uint64 if np.dtype(dtype).itemsize == 8 else np.uint32


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
@pytest.mark.parametrize("block,n", [(128, 2), (7, 3), (1, 1)])
def test_normals_are_the_per_key_normal_and_uniforms_jax_random_bit_for_bit(key, dtype, block, n):
    keys = jax.random.split(key, 37)
    ref_n = jax.vmap(lambda k: rng.normal(k, (block, n), dtype))(keys)  # (lanes, block, n)
    ref_u = jax.vmap(lambda k: jax.random.uniform(k, (block, n), dtype, 0.25, 3.0))(keys)
    got_n = jax.jit(lambda ks: rng.normals(ks, block, n, dtype))(keys)
    got_u = jax.jit(lambda ks: rng.uniforms(ks, block, n, dtype, 0.25, 3.0))(keys)
    for c in range(n):
        assert got_n[c].shape == (block, 37) and got_n[c].dtype == dtype
        np.testing.assert_array_equal(np.asarray(got_n[c]), np.asarray(ref_n[:, :, c]).T)
        np.testing.assert_array_equal(np.asarray(got_u[c]), np.asarray(ref_u[:, :, c]).T)
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
def test_normal_is_the_inverse_cdf_of_the_bits_cell_midpoints(key, dtype):
    """The definition, computed independently: k = the top m bits of ``jax.random.bits`` (m = 52
    or 23), u = (k + 1/2) 2^-m exactly, Z = scipy's ndtri(u), to 8 (float64) or 6 (float32) ulp."""
    m = np.finfo(dtype).nmant
    bits = np.asarray(jax.random.bits(key, (200_000,), _uint(dtype)))
    k = (bits >> _uint(dtype)(8 * np.dtype(dtype).itemsize - m)).astype(np.float64)
    ref = scipy_ndtri((k + 0.5) * 2.0**-m)
    got = np.asarray(rng.normal(key, (200_000,), dtype))
    assert got.dtype == dtype
    ulps = np.abs(got.astype(np.float64) - ref) / np.spacing(np.abs(ref).astype(dtype))
    assert ulps.max() <= (8 if dtype == jnp.float64 else 6)
    assert abs(got.mean()) < 5 / np.sqrt(got.size) and abs(got.var() - 1) < 5 * np.sqrt(2 / got.size)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_normal_is_jax_random_normal_to_a_quarter_cell(key, dtype):
    r"""``jax.random.normal`` of the same key takes :math:`\sqrt2\operatorname{erf}^{-1}` of the
    cell point (k + 1/4) 2^-m (its uniform on (-1, 1)), ours the midpoint: in u = Phi(z) the two
    numbers lie a quarter cell apart (measured where z in (-5, -3), where scipy's ndtr resolves a
    cell), and everywhere within a few cells, jax's erf_inv being a few cells off in float64's
    tails and both transforms rounding at the cell's scale in float32.  So a run's paths are
    jax.random.normal's, to rounding."""
    from scipy.special import ndtr

    m = np.finfo(dtype).nmant
    z = np.asarray(rng.normal(key, (200_000,), dtype)).astype(np.float64)
    zj = np.asarray(jax.random.normal(key, (200_000,), dtype)).astype(np.float64)
    cells = (ndtr(z) - ndtr(zj)) * 2.0**m
    tail = (z > -5) & (z < -3)
    assert tail.sum() > 150 and 0.2 < np.median(cells[tail]) < 0.3
    phi = np.exp(-np.minimum(np.abs(z), np.abs(zj)) ** 2 / 2) / np.sqrt(2 * np.pi)
    ulp = np.spacing(np.abs(z).astype(dtype)).astype(np.float64)
    assert np.all(np.abs(z - zj) <= 5 * 2.0**-m / phi + (16 if dtype == jnp.float64 else 160) * ulp)


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
    plain = jax.jit(lambda kd, s: rng._bits(kd, 50, 2, dtype, s, materialise=False))
    for s in (0, 7, 128, 250):
        got = draw(keys, s)
        bits = plain(jax.random.key_data(keys), s)
        for c in range(2):
            np.testing.assert_array_equal(np.asarray(got[c]), np.asarray(ref[:, s:s + 50, c]).T)
            np.testing.assert_array_equal(np.asarray(rng._normal(bits[c], dtype)), np.asarray(ref[:, s:s + 50, c]).T)
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
