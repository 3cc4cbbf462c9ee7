"""The generator's inverse normal CDF (dryfric_jax.icdf) against scipy's ndtri (Cephes, an
independent implementation), and its logarithm against numpy's, on every argument the generator
can give in float32 and on random ones and every branch edge in float64."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import ndtri as scipy_ndtri

from dryfric_jax import icdf

_ndtri = jax.jit(icdf.ndtri)
_log = jax.jit(icdf.log)


def _ulps(got, ref, dtype):
    """|got - ref| in units of the last place of ``ref`` rounded to ``dtype``."""
    ref = np.asarray(ref, np.float64)
    return np.abs(np.asarray(got, np.float64) - ref) / np.spacing(np.abs(ref).astype(dtype)).astype(np.float64)


def _float64_arguments():
    rng = np.random.default_rng(11)
    k = rng.integers(0, 2**52, 10**6, dtype=np.int64)
    cells = (k.astype(np.float64) + 0.5) * 2.0**-52  # the generator's arguments, exact
    edges = [2.0**-53, 1 - 2.0**-53, 0.5, 0.5 + 2.0**-53, 0.075, 0.925, np.exp(-25.0), 1 - np.exp(-25.0)]
    near = [np.nextafter(e, d) for e in (0.075, 0.925, np.exp(-25.0)) for d in (0.0, 1.0)]
    dyadic = np.ldexp(1.0, -np.arange(1, 54))  # the tail, octave by octave
    return np.concatenate([cells, edges, near, dyadic, 1 - dyadic[:-1]])


def test_float64_ndtri_is_scipys_to_8_ulp():
    u = _float64_arguments()
    got = np.asarray(_ndtri(jnp.asarray(u)))
    ref = scipy_ndtri(u)
    assert got.dtype == np.float64
    assert _ulps(got, ref, np.float64).max() <= 8
    assert np.all(np.sign(got) == np.sign(u - 0.5))


def test_float32_ndtri_is_scipys_to_6_ulp_at_every_generator_argument():
    """All 2^23 arguments (k + 1/2) 2^-23 of the float32 generator, through the same jitted
    function: within 6 float32 ulp of the float64 reference, and non-decreasing in k."""
    k = np.arange(2**23, dtype=np.int64)
    u = ((k + 0.5) * 2.0**-23).astype(np.float32)
    assert np.all(u.astype(np.float64) == (k + 0.5) * 2.0**-23)  # exact
    got = np.asarray(_ndtri(jnp.asarray(u)))
    assert got.dtype == np.float32
    assert _ulps(got, scipy_ndtri(u.astype(np.float64)), np.float32).max() <= 6
    assert np.all(np.diff(got) >= 0)
    assert got[0] == -got[-1] and -5.30 < got[0] < -5.29  # the float32 range: |Z| <= -Phi^-1(2^-24)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_ndtri_is_exactly_antisymmetric_on_the_cells(dtype):
    m = np.finfo(dtype).nmant
    k = np.random.default_rng(3).integers(0, 2**m, 10**5, dtype=np.int64)
    u = ((k + 0.5) * 2.0**-m).astype(dtype)
    np.testing.assert_array_equal(np.asarray(_ndtri(jnp.asarray(1 - u))), -np.asarray(_ndtri(jnp.asarray(u))))


def test_float64_ndtri_is_monotone_to_rounding_across_branch_edges():
    """4001 consecutive float64 numbers around each switch between rational functions: no step
    back of more than 2 ulp (rounding; exact monotonicity is not claimed in float64) and no jump."""
    for e in (0.075, 0.925, np.exp(-25.0)):
        u = e + np.arange(-2000, 2001) * np.spacing(e)
        z = np.asarray(_ndtri(jnp.asarray(u)))
        steps = np.diff(z) / np.spacing(np.abs(z[:-1]))
        assert steps.min() >= -2 and steps.max() <= 8, e


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
        icdf.ndtri(jnp.ones(3, jnp.float16) * 0.5)
    with pytest.raises(ValueError, match="dtype must be float32 or float64"):
        icdf.log(jnp.ones(3, jnp.int32))
