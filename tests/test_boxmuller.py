"""The generator's Box-Muller transform (dryfric_jax.boxmuller) against extended-precision
references (numpy's long double trigonometry and logarithm, an independent implementation): the
turn's cosine and sine at every argument the float32 generator can give and on random ones and
every quadrant edge in float64, the logarithm against numpy's, the pair against the formula, its
exact symmetries, and the law of 2^20 pairs."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from dryfric_jax import boxmuller

_cos_sin = jax.jit(boxmuller.cos_sin_turns)
_pair = jax.jit(boxmuller.pair)
_log = jax.jit(boxmuller.log)
LD = np.longdouble
_PI_LD = 4 * np.arctan(LD(1))

pytestmark = pytest.mark.skipif(np.finfo(LD).nmant < 63, reason="needs an 80-bit (or wider) long double reference")


def _ulps(got, ref, dtype):
    """|got - ref| in units of the last place of ``ref`` rounded to ``dtype`` (0 where both are 0)."""
    ref = np.asarray(ref, LD)
    err = np.abs(np.asarray(got, LD) - ref)
    return np.where(err == 0, 0, err / np.spacing(np.abs(ref).astype(dtype)).astype(LD)).astype(np.float64)


def _turn_reference(t):
    """(cos 2 pi t, sin 2 pi t) in long double, with its own exact reduction: n the integer nearest
    4t, 2 pi t = (pi/2) n + (pi/2) d with d = 4t - n exact, combined by the angle-addition
    formulas with cos, sin of (pi/2) n rounded to the integers they are.  So the reference is
    accurate relative to itself near the zeros too (2 pi t itself rounded in long double is not)."""
    t = np.asarray(t, np.float64)
    n = np.rint(4 * t)
    th = _PI_LD / 2 * (4 * t - n).astype(LD)
    cn, sn = np.rint(np.cos(np.pi / 2 * n)), np.rint(np.sin(np.pi / 2 * n))
    c, s = np.cos(th), np.sin(th)
    return cn * c - sn * s, sn * c + cn * s


def _float64_turns():
    rng = np.random.default_rng(13)
    k = rng.integers(0, 2**52, 10**6, dtype=np.int64)
    quarters = np.arange(9) / 8  # every quadrant edge (r = 0) and every switch of q (r = +-1/2)
    near = np.concatenate([quarters + j * 2.0**-52 for j in range(-3, 4)])
    return np.concatenate([k * 2.0**-52, near[(near >= 0) & (near < 1)]])


def test_float64_turn_is_within_2_ulp_everywhere():
    t = _float64_turns()
    c, s = (np.asarray(a) for a in _cos_sin(jnp.asarray(t)))
    rc, rs = _turn_reference(t)
    assert c.dtype == np.float64
    assert _ulps(c, rc, np.float64).max() <= 2 and _ulps(s, rs, np.float64).max() <= 2
    assert c[t == 0][0] == 1.0 and s[t == 0][0] == 0.0


def test_float32_turn_is_within_2_ulp_at_every_generator_argument():
    """All 2^23 angles k 2^-23 of the float32 generator, through the same jitted function."""
    t = (np.arange(2**23) * 2.0**-23).astype(np.float32)
    c, s = (np.asarray(a) for a in _cos_sin(jnp.asarray(t)))
    rc, rs = _turn_reference(t)
    assert c.dtype == np.float32
    assert _ulps(c, rc, np.float32).max() <= 2 and _ulps(s, rs, np.float32).max() <= 2


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_turn_symmetries_are_exact(dtype):
    """t -> 1 - t flips the sine and keeps the cosine; t -> t + 1/2 flips both; t -> 1/4 - t swaps
    them (bit for bit, on generator arguments)."""
    m = np.finfo(dtype).nmant
    k = np.random.default_rng(4).integers(1, 2**(m - 2), 10**5, dtype=np.int64)
    t = (k * 2.0**-m).astype(dtype)
    c, s = (np.asarray(a) for a in _cos_sin(jnp.asarray(t)))
    c1, s1 = (np.asarray(a) for a in _cos_sin(jnp.asarray((1 - t.astype(np.float64)).astype(dtype))))
    c2, s2 = (np.asarray(a) for a in _cos_sin(jnp.asarray(t + dtype(0.5))))
    c3, s3 = (np.asarray(a) for a in _cos_sin(jnp.asarray((0.25 - t.astype(np.float64)).astype(dtype))))
    np.testing.assert_array_equal(c1, c)
    np.testing.assert_array_equal(s1, -s)
    np.testing.assert_array_equal(c2, -c)
    np.testing.assert_array_equal(s2, -s)
    np.testing.assert_array_equal(c3, s)
    np.testing.assert_array_equal(s3, c)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_pair_is_the_formula_to_6_ulp(dtype):
    """sqrt(-2 ln u) (cos 2 pi t, sin 2 pi t) at u = (k + 1/2) 2^-m down to the smallest cell, m the mantissa
    (the float32 generator's cells; the float64 generator's are coarser, m = 32, and reach only 2^-33), against
    the long double formula: within 6 ulp (4 measured)."""
    m = np.finfo(dtype).nmant
    g = np.random.default_rng(8)
    ku = np.concatenate([g.integers(0, 2**m, 10**6), [0, 1, 2**m - 1, 2**(m - 1)]])
    kt = np.concatenate([g.integers(0, 2**m, 10**6), [0, 2**(m - 2), 3, 2**m - 1]])
    u, t = ((ku + 0.5) * 2.0**-m).astype(dtype), (kt * 2.0**-m).astype(dtype)
    assert np.all(u.astype(np.float64) == (ku + 0.5) * 2.0**-m)  # exact
    z1, z2 = (np.asarray(a) for a in _pair(jnp.asarray(u), jnp.asarray(t)))
    assert z1.dtype == dtype
    radius = np.sqrt(-2 * np.log(u.astype(LD)))
    rc, rs = _turn_reference(t)
    assert _ulps(z1, radius * rc, dtype).max() <= 6 and _ulps(z2, radius * rs, dtype).max() <= 6
    rmax = np.sqrt(2 * (m + 1) * np.log(2.0))  # the largest radius, at the smallest cell
    assert np.isclose(z1[10**6], rmax, rtol=1e-6) and z2[10**6] == 0


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_pairs_have_the_normal_law(dtype):
    """2^20 pairs from independent uniforms on the generator's cells (numpy's PCG64): each
    coordinate passes Kolmogorov-Smirnov against Phi (p > 1e-3, fixed seed), the radius squared
    against the exponential law of mean 2, and the two coordinates, and their squares, are
    uncorrelated (5 SE); the tail P(|Z| > 4) is within 5 SE of 2 Phi(-4).  The cells are m = 23 bits (float32)
    or 32 (float64, a hash's word: dryfric_jax.rng)."""
    m = 32 if dtype == np.float64 else np.finfo(dtype).nmant
    n = 2**20
    g = np.random.default_rng(21)
    u = ((g.integers(0, 2**m, n) + 0.5) * 2.0**-m).astype(dtype)
    t = (g.integers(0, 2**m, n) * 2.0**-m).astype(dtype)
    z1, z2 = (np.asarray(a, np.float64) for a in _pair(jnp.asarray(u), jnp.asarray(t)))
    for z in (z1, z2):
        assert stats.kstest(z, "norm").pvalue > 1e-3
        p = 2 * stats.norm.sf(4)
        assert abs(np.mean(np.abs(z) > 4) - p) < 5 * np.sqrt(p / n)
    assert stats.kstest(z1**2 + z2**2, "expon", args=(0, 2)).pvalue > 1e-3
    se = 5 / np.sqrt(n)
    assert abs(np.corrcoef(z1, z2)[0, 1]) < se and abs(np.corrcoef(z1**2, z2**2)[0, 1]) < se


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_log_is_numpys_to_4_ulp(dtype):
    """Over the whole normal range down to the generator's smallest argument and at the
    mantissa's sqrt(2) switch, where the series' argument is largest."""
    rng = np.random.default_rng(5)
    lo = -53 if dtype == np.float64 else -24
    x = np.ldexp(1.0 + rng.random(10**6), rng.integers(lo, 60, 10**6)).astype(dtype)
    s2 = np.array(np.sqrt(2.0), dtype)
    edges = np.array([1.0, np.nextafter(dtype(1), dtype(0)), s2, np.nextafter(s2, dtype(2)), 2.0**lo, 0.5], dtype)
    x = np.concatenate([x, edges, edges * dtype(2.0**-20)])
    got = np.asarray(_log(jnp.asarray(x)))
    ref = np.log(x.astype(np.float64))
    assert got.dtype == dtype
    # at x = 1 - ulp the log is -ulp: absolute error of the dtype's epsilon there
    assert np.all(np.abs(got - ref) <= 4 * np.spacing(np.abs(ref).astype(dtype)) + 4 * np.finfo(dtype).eps * (np.abs(ref) < 1))
    assert got[np.flatnonzero(x == 1.0)[0]] == 0.0


def test_other_dtypes_are_refused():
    with pytest.raises(ValueError, match="dtype must be float32 or float64"):
        boxmuller.cos_sin_turns(jnp.ones(3, jnp.float16) * 0.5)
    with pytest.raises(ValueError, match="dtype must be float32 or float64"):
        boxmuller.log(jnp.ones(3, jnp.int32))
    with pytest.raises(ValueError, match="one dtype"):
        boxmuller.pair(jnp.ones(3, jnp.float64) * 0.5, jnp.zeros(3, jnp.float32))


def test_the_float32_generators_law_by_enumeration():
    r"""The float32 generator's law, exactly, over all 2^46 equally likely (u, t) cells: its 2^23
    radii R_k = sqrt(-2 ln u_k) and 2^23 cosines c_j as the generator computes them, so
    P(|Z_1| > a) = 2^-46 sum_j #{k : R_k |c_j| > a} (the product's rounding aside).  Each angle's count
    of u cells is within one cell of the continuous measure and the sum over the angles is a
    Riemann sum of a smooth periodic function, so every tail mass must be within 2^-23 of the
    normal law's; E[Z_1^2] = mean(R^2) mean(c^2) within 1e-6 of 1 (the midpoint rule at the log's
    singularity errs by 0.6 2^-23; float32 rounding of R^2 adds ~1e-7)."""
    m = 23
    k = np.arange(2**m)
    u = ((k + 0.5) * 2.0**-m).astype(np.float32)
    t = (k * 2.0**-m).astype(np.float32)
    R = np.sort(np.asarray(_pair(jnp.asarray(u), jnp.zeros_like(jnp.asarray(u)))[0], np.float64))
    c = np.abs(np.asarray(_cos_sin(jnp.asarray(t))[0], np.float64))
    assert abs(np.mean(R**2) * np.mean(c**2) - 1) < 1e-6
    for a in (1.0, 2.0, 3.0, 4.0, 5.0):
        above = np.zeros(c.shape, np.int64)
        nz = c > 0
        above[nz] = R.size - np.searchsorted(R, a / c[nz], side="right")
        p = above.sum() / (R.size * c.size)
        assert abs(p - 2 * stats.norm.sf(a)) < 2.0**-23, (a, p, 2 * stats.norm.sf(a))
    assert np.isclose(R[-1], np.sqrt(48 * np.log(2.0)), rtol=1e-6)  # the range: |Z| <= sqrt(-2 ln 2^-24)
