r"""Mutation audit of :mod:`dryfric_jax.rng` (the engine's blocked random numbers) and :mod:`dryfric_jax.noise`
(the PDMP's jump-noise grid): what the bit-for-bit tests (tests/test_rng.py) and the exact law tests
(tests/test_noise.py, tests/test_internals_audit.py) left open.

Expected values come from independent oracles: ``jax.random`` itself where the module promises its numbers
(also under ``jax_threefry_partitionable = False``, for keys of another generator and for ranges other than the
engine's), hand arithmetic for the grid (``delta_max = 4/(tau L + sqrt((tau L)^2 + 16 tau))``, the point count
2N + 1 = 2n + 3 for an integer n = L_req/delta) and the module docstring for the platform split (on a CPU the
unrolled hash, materialised by a ``lax.cond``; elsewhere ``jax.random`` itself, or the plain hash for rows of a
longer stream).  Each test's docstring names the mutants (edits of rng.py: R.., noise.py: N..) it kills.

71 mutants were tried (46 of rng.py, 25 of noise.py); the targeted tests (tests/test_rng.py, tests/test_noise.py
and the rng/noise tests of tests/test_internals_audit.py) killed 46 of them, 8 are equivalent, these tests kill 16
more.  Six of those (R15, R21, R38, R39, R54, R55) leave every number unchanged and only move the work between
the hand-compiled hash and jax.random's rolled loop (the module's speed, or a GPU's host round trip).  The last,
N13 (``n <= 2**30 - 2`` for ``n < 2**30 - 2`` in grid_size), was the correct bound: an integer n = 2^30 - 2
gives N = 2^30 - 1 and 2^31 - 1 points, which the message allows and a non-integer n just below already got.
grid_size now takes it; test_the_largest_grid_the_message_allows_is_accepted pins the edge on both sides.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import rng
from dryfric_jax.noise import check_delta, delta_max, grid_size

F32, F64 = jnp.float32, jnp.float64


def _keys(n=6, seed=31):
    return jax.random.split(jax.random.key(seed), n)


def _same_columns(got, ref):
    """The module's (block, lanes) columns against the per-lane draws ``ref`` (lanes, block, n), bit for bit."""
    for c, col in enumerate(got):
        np.testing.assert_array_equal(np.asarray(col), np.asarray(ref[:, :, c]).T)


def _same_keys(a, b):
    np.testing.assert_array_equal(np.asarray(jax.random.key_data(a)), np.asarray(jax.random.key_data(b)))


# ------------------------------------------------------------------------------------------------ rng.py
@pytest.mark.parametrize("dtype", [F32, F64])
def test_a_reversed_range_is_clamped_to_minval_as_in_jax_random(dtype):
    """``jax.random.uniform`` returns ``max(minval, f (maxval - minval) + minval)``: with minval = 3 > maxval =
    0.25 every number is 3 (by hand: 3 - 2.75 f <= 3).  Kills R25 (the ``lax.max`` dropped from ``_unit``: its
    numbers spread over (0.25, 3] instead), which every test with minval < maxval let through."""
    keys = _keys()
    ref = jax.vmap(lambda k: jax.random.uniform(k, (5, 2), dtype, 3.0, 0.25))(keys)
    assert np.all(np.asarray(ref) == 3.0)
    _same_columns(rng.uniforms(keys, 5, 2, dtype, 3.0, 0.25), ref)
    np.testing.assert_array_equal(np.asarray(rng.uniform(keys, dtype, 3.0, 0.25)),
                                  np.asarray(jax.vmap(lambda k: jax.random.uniform(k, (), dtype, 3.0, 0.25))(keys)))


@pytest.mark.parametrize("dtype", [F32, F64])
def test_non_partitionable_threefry_is_left_to_jax_random(dtype):
    """With ``jax_threefry_partitionable`` off, jax.random counts threefry's counters differently: the module's
    own hash (partitionable layout) is then wrong, and it must hand every draw and key to jax.random, and refuse
    row offsets.  Kills R35 (``is_threefry`` without the partitionable check: other numbers entirely)."""
    keys = _keys()
    with jax.threefry_partitionable(False):
        ref_n = jax.vmap(lambda k: rng.normal(k, (4, 2), dtype))(keys)
        ref_u = jax.vmap(lambda k: jax.random.uniform(k, (4, 2), dtype, 0.25, 3.0))(keys)
        _same_columns(rng.normals(keys, 4, 2, dtype), ref_n)
        _same_columns(rng.uniforms(keys, 4, 2, dtype, 0.25, 3.0), ref_u)
        _same_keys(rng.fold_in(keys, 7), jax.vmap(jax.random.fold_in, (0, None))(keys, 7))
        _same_keys(rng.split_at(keys, 1), jax.vmap(lambda k: jax.random.split(k)[1])(keys))
        np.testing.assert_array_equal(np.asarray(rng.uniform(keys, dtype)),
                                      np.asarray(jax.vmap(lambda k: jax.random.uniform(k, (), dtype))(keys)))
        with pytest.raises(ValueError, match="threefry"):
            rng.normals(keys, 4, 2, dtype, start=3)


def test_keys_of_another_generator_keep_their_shape_and_range():
    """rbg keys go through ``_each`` (vmap over the flattened keys): a (2, 3) array of keys gives a (2, 3)
    array of keys, each ``jax.random.fold_in``'s (nested vmap), and ``uniform`` honours maxval there too.  Kills
    R49 (the rbg path of ``uniform`` dropped maxval; the engine's (tiny, 1) hid it) and R41 (the result not
    reshaped back: shape (6,); test_rng's vmapped split_at caught it only as a shape (1,) for shape ())."""
    keys = jax.random.split(jax.random.key(5, impl="rbg"), 6).reshape(2, 3)
    got = rng.fold_in(keys, 5)
    assert got.shape == (2, 3)
    _same_keys(got, jax.vmap(jax.vmap(lambda k: jax.random.fold_in(k, 5)))(keys))
    for dtype in (F32, F64):
        u = np.asarray(rng.uniform(keys[0], dtype, 0.25, 3.0))
        ref = jax.vmap(lambda k: jax.random.uniform(k, (), dtype, 0.25, 3.0))(keys[0])
        np.testing.assert_array_equal(u, np.asarray(ref))
        assert np.all((u >= 0.25) & (u < 3.0)) and u.dtype == dtype


@pytest.mark.parametrize("dtype", [jnp.int32, jnp.uint32, jnp.int64, jnp.complex64])
def test_only_float32_and_float64_are_accepted(dtype):
    """Other dtypes of 4 or 8 bytes are refused by name, not only float16.  Kills R60 (the check by item
    size: int32 then failed in np.finfo with another message, complex64 went through)."""
    keys = _keys(2)
    for draw in (rng.normals, rng.uniforms):
        with pytest.raises(ValueError, match="^dtype must be float32 or float64"):
            draw(keys, 4, 2, dtype)


@pytest.mark.parametrize("dtype", [jnp.float16, jnp.int32, jnp.complex64])
def test_one_uniform_per_key_refuses_other_dtypes_by_name(dtype):
    """``rng.uniform`` (one number per key, the DI's event-time draw) had no dtype check: float16 failed
    inside numpy ("Changing the dtype of a 0d array is only supported if the itemsize is unchanged")."""
    with pytest.raises(ValueError, match="^dtype must be float32 or float64"):
        rng.uniform(_keys(2), dtype)


def _branches(monkeypatch, call):
    """The (cpu, default) branches ``call`` hands to ``lax.platform_dependent``, one pair per call."""
    seen, real = [], jax.lax.platform_dependent

    def spy(*args, **branches):
        seen.append((branches["cpu"], branches["default"]))
        return real(*args, **branches)

    monkeypatch.setattr(rng.lax, "platform_dependent", spy)
    call()
    monkeypatch.setattr(rng.lax, "platform_dependent", real)
    return seen


def _traced(monkeypatch, branch, keys):
    """(calls of the module's own hash, ``cond`` primitives) when ``branch(keys)`` is traced (through a fresh
    lambda: make_jaxpr caches by function, and the branches may be one function)."""
    calls, real = [], rng.threefry2x32
    monkeypatch.setattr(rng, "threefry2x32", lambda *a: calls.append(1) or real(*a))
    jaxpr = str(jax.make_jaxpr(lambda ks: branch(ks))(keys))
    monkeypatch.setattr(rng, "threefry2x32", real)
    return len(calls), jaxpr.count("cond[")


def test_each_platform_gets_the_path_the_module_docstring_gives(monkeypatch):
    """Module docstring: on a CPU the unrolled hash (the point of the module: 2-6x faster), materialised by
    one ``lax.cond``; on other platforms jax.random itself, except for rows of a longer stream (the plain hash,
    no ``lax.cond``, whose predicate a GPU would read back); the per-key derivations likewise.  The numbers are
    the same either way, so only the traced branches tell.  Kills R15 and R21 (no materialising cond), R54
    (the CPU branch unmaterialised), R56 and R38 (jax.random's rolled loop on the CPU), R55 and R39 (the hand
    hash on a GPU instead of jax.random)."""
    keys = _keys(4)
    draws = ((lambda: rng.normals(keys, 8, 2, F64), 1), (lambda: rng.uniforms(keys, 8, 2, F32, 0.5, 2.0), 2))
    for draw, hashes in draws:
        (cpu, default), = _branches(monkeypatch, draw)
        assert _traced(monkeypatch, cpu, keys) == (hashes, 1)  # one hash per float64 pair or column, one cond
        assert _traced(monkeypatch, default, keys)[0] == 0
    (cpu, default), = _branches(monkeypatch, lambda: rng.normals(keys, 8, 2, F32, start=16))
    assert _traced(monkeypatch, cpu, keys) == (2, 1)
    assert _traced(monkeypatch, default, keys) == (2, 0)
    for derive in (lambda: rng.fold_in(keys, 3), lambda: rng.split_at(keys, 1), lambda: rng.uniform(keys, F64)):
        (cpu, default), = _branches(monkeypatch, derive)
        assert _traced(monkeypatch, cpu, keys)[0] == 1 and _traced(monkeypatch, default, keys)[0] == 0


# ---------------------------------------------------------------------------------------------- noise.py
def test_delta_max_and_the_refusal_use_the_thresholds_when_they_set_the_reach():
    """tau = 100, gamma_bar = +-0.5: L_req = max(8/10, 1.5) = 1.5, so by hand delta_max = 4/(150 + sqrt(150^2 +
    1600)) = 0.01310 (0.0236 if the noise alone set L = 0.8).  delta = 0.02 must be refused (it would give
    tau delta L_X > 2, up-probabilities below 0), 0.013 accepted.  Kills N29 (delta_max without gamma_bar) and
    N30 (check_delta asking delta_max without gamma_bar): both accepted 0.02 and hit grid_size's assert; also
    N17 (grid_size without check_delta: the assert, not the refusal)."""
    dm = 4 / (150 + np.hypot(150.0, 40.0))
    for gb in (0.5, -0.5):
        assert delta_max(100.0, gb) == pytest.approx(dm, rel=1e-15)
        with pytest.raises(ValueError, match=rf"^delta must be in \(0, {dm:.4g}\) .*\(got 0\.02\)"):
            check_delta(0.02, 100.0, gb)
        with pytest.raises(ValueError, match=r"^delta must be in \(0, 0\.0131\)"):
            grid_size(0.02, 100.0, gb)
        check_delta(0.013, 100.0, gb)
        assert grid_size(0.013, 100.0, gb) == int(np.ceil(1.5 / 0.013)) + 1  # 117


@pytest.mark.parametrize("bad,shown", [("x", "'x'"), (None, "None"), (True, "True"), (b"1", "b'1'"),
                                       (10**400, "1" + "0" * 23 + r"\.\.\. \(401 characters\)")])
def test_a_delta_that_is_no_real_number_is_refused_by_name(bad, shown):
    """Strings, None, bools and an int too large for a float are refused with delta's range and the value as
    ``shown`` prints it (a 400-digit int as its first 24 characters and its length), also by grid_size itself.
    Kills N10 (``v is not None`` dropped: a TypeError from math.isfinite), N37 (the value printed raw: 401
    digits) and N17 (grid_size without check_delta: a TypeError, or for 10**400 a grid refused as too small)."""
    for call in (lambda: check_delta(bad, 1.0), lambda: grid_size(bad, 1.0)):
        with pytest.raises(ValueError, match=rf"^delta must be in \(0, 0\.236\) for these parameters \(got {shown}\)"):
            call()


@pytest.mark.parametrize("d", [0.0, -0.1, 0.2361, 0.3, float("nan"), float("inf")])
def test_grid_size_refuses_every_delta_check_delta_refuses(d):
    """tau = 1: delta_max = 4/(8 + sqrt 80) = 0.23607 by hand, so 0.2361 is just out.  Kills N17 (grid_size
    without check_delta: 0.3 and 0.2361 reached its assert, 0 and -0.1 gave grids of 1 and -78 points)."""
    assert 0.2360 < 4 / (8 + 80**0.5) < 0.2361
    with pytest.raises(ValueError, match=r"^delta must be in \(0, 0\.236\)"):
        grid_size(d, 1.0)


def test_a_too_fine_grid_is_refused_with_its_point_count():
    """n = L_req/delta = 1077499999 exactly (delta = 2^-30, L_req = 1 + |gamma_bar| = n 2^-30, tau = 100 so the
    thresholds set the reach): N = n + 1 and the grid would have 2N + 1 = 2155000001 points, "2.16e+09" to
    three digits (hand arithmetic); n is above the limit 2^30 - 2.  Kills N18 (2n + 1 = 2154999999 printed as
    "2.15e+09"; every other refused count rounds the same)."""
    n = 1077499999
    assert n >= 2**30 - 2 and f"{2 * (n + 1) + 1:.3g}" == "2.16e+09"
    gb = n * 2.0**-30 - 1.0  # exact: 31 significant bits
    assert 1.0 + gb == n * 2.0**-30
    with pytest.raises(ValueError, match=r"^delta' = .* too small: the noise grid would have 2\.16e\+09 points "
                                         r"\(at most 2147483647\)"):
        grid_size(2.0**-30, 100.0, gb)


def test_the_largest_grid_the_message_allows_is_accepted():
    """The refusal says "at most 2147483647" points: delta = 2^-29, tau = 100 and L_req = 1 + |gamma_bar| = 2 -
    2^-28 give n = 2^30 - 2 exactly, N = n + 1 = 2^30 - 1 and 2N + 1 = 2^31 - 1 points: accepted (it was refused
    while n = 2^30 - 2.5 just below got the same N).  One grid step further (gamma_bar = 1 - 2^-29: n = 2^30 - 1,
    2^31 + 1 points) is refused.  Kills the old bound ``n < 2**30 - 2`` (N13 of the audit, now the code)."""
    assert 2 * (2**30 - 1) + 1 == 2**31 - 1
    assert grid_size(2.0**-29, 100.0, 1 - 2.0**-28) == 2**30 - 1
    assert grid_size(2.0**-29, 100.0, -(1 - 2.0**-28)) == 2**30 - 1
    msg = r"too small: the noise grid would have 2\.15e\+09 points \(at most 2147483647\)"
    with pytest.raises(ValueError, match=msg):
        grid_size(2.0**-29, 100.0, 1 - 2.0**-29)
