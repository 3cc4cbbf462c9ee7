r"""One DI step, one candidate test and one brute-force path against their definitions, with fixed numbers.

The reference is written here from the paper (section 6 with MODEL_NOTES section 3.1: the proximal step of
the fresh predictor) and the OU pair's closed-form moments (section 6.2, 60-digit ``ou_moments_reference``,
factored by hand), never from the code under test.  The other fast DI tests compare the chain with itself
(step-by-step rebuilds call ``DIModel.move``) or with theory at a few points (``test_di_exact`` is slow).
Mutants that passed them (mutation audit): a doubled viscous rate, the bias left in physical units
(:math:`\bar\gamma` for :math:`\bar\gamma/\Delta`), the velocity's sign taken from :math:`V_n + w`, a
right-point displacement; in brute force, a window of counted steps one step early, every chunk of paths on the first
chunk's keys, and the two normals of a step swapped; the splitting coin's key equal to the normals' key.  Each
fails here.
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import rng
from dryfric_jax.di import make_di_model
from dryfric_jax.ou import ou_moments_reference

TAU, TAU_L, GBAR, H = 0.5, 2.0, 0.2, 0.05  # nondimensional: tau', tau_L', gamma_bar', h' (r = h/tau = 0.1)
GAMMA, DELTA = 2.0, 0.5  # physical units other than 1: tau0 = 8, u0 = 32


def _reference_step(x, v, z1, z2, tau=TAU, tau_L=TAU_L, gbar=GBAR, h=H):
    r"""``(Xi, X_next, V_next, dU)`` from the definitions, float64: the OU pair's mean x m and covariance
    Sigma (closed forms), its lower Cholesky factor, then :math:`w = v + h(\bar\gamma - v/\tau_L + \Xi)`,
    :math:`V_{n+1} = \mathrm{sign}(w) \max(|w| - h, 0)` and the trapezoid :math:`h (v + V_{n+1})/2`."""
    m1, m2, S11, S12, S22 = ou_moments_reference(h, tau)
    L11 = math.sqrt(S11)
    L21 = S12 / L11
    L22 = math.sqrt(S22 - L21 * L21)  # 1 - rho^2 ~ 0.02 at r = 0.1: ~1e-14 relative
    xi = x * m1 + L11 * z1
    xn = x * m2 + L21 * z1 + L22 * z2
    w = v + h * (gbar - v / tau_L + xi)
    vn = math.copysign(max(abs(w) - h, 0.0), w) if abs(w) > h else 0.0
    return xi, xn, vn, 0.5 * h * (v + vn)


# (x, v, z1, z2): stuck, released up, released down, sliding on, stuck on reversal, reversal through 0 (twice;
# the second one with |V_{n+1}| < |V_n|: the sign is w's, not that of V_n + w)
CASES = [(0.1, 0.0, 0.0, 0.0), (2.0, 0.0, 0.5, -0.7), (-2.5, 0.0, -0.3, 1.1), (0.0, 0.3, 0.2, -1.0),
         (-1.0, 0.02, -1.0, 0.4), (5.0, -0.01, 2.0, 0.3), (-14.0, 0.5, -3.0, 0.0)]


def _model(dtype="float64"):
    p = dj.Params.from_nondim(TAU, TAU_L, GBAR, Gamma=GAMMA, Delta=DELTA)
    return make_di_model(p, H * p.tau0, dtype)


def test_one_di_step_matches_the_definition_by_hand():
    r"""``DIModel.move`` for fixed states and normals against the definitions (module docstring), in
    physical units with :math:`\Gamma, \Delta \ne 1` (the model is nondimensional: h' = h/tau0,
    :math:`\bar\gamma' = \bar\gamma/\Delta`, :math:`1/\tau_L' = \tau_0/\tau_L`), to 1e-12 in float64
    and 1e-5 in float32; the cases cover sticking, release both ways, sliding and a velocity reversal."""
    m = _model()
    assert (float(m.h), float(m.gamma_bar), float(m.inv_tau_L)) == pytest.approx((H, GBAR, 1 / TAU_L), rel=1e-14)
    vns = []
    for x, v, z1, z2 in CASES:
        want = _reference_step(x, v, z1, z2)
        got = [float(a) for a in m.move(jnp.float64(x), jnp.float64(v), jnp.float64(z1), jnp.float64(z2))]
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15, err_msg=str((x, v, z1, z2)))
        vns.append(want[2])
    # the cases are what they claim: stuck, up, down, on, stuck, through 0 (twice)
    assert [np.sign(a) for a in vns] == [0, 1, -1, 1, 0, 1, -1] and vns[3] < 0.3 and -0.5 < vns[6]
    m32 = _model("float32")
    for x, v, z1, z2 in CASES:
        want = _reference_step(x, v, z1, z2)
        got = [float(a) for a in m32.move(*(jnp.float32(a) for a in (x, v, z1, z2)), dtype=jnp.float32)]
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6, err_msg=str((x, v, z1, z2)))


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_the_soft_threshold_is_the_definition_to_the_last_bit(dtype):
    r"""``DIModel.step`` computes :math:`\operatorname{sign}(w)\max(|w| - h, 0)` as
    :math:`w - \operatorname{clip}(w, -h, h)` (3 operations instead of ~6).  The two must be the same
    number in every rounding, not close: the estimates are kept bit for bit.  Checked against the
    definition evaluated here, on the predictors w where a rounding could differ (one ulp either side
    of +-h, +-h itself, tiny, huge, signed zeros and 10^5 random ones), with :math:`\Xi` solved
    from w so that the model's own predictor is exactly w; equal as numbers (only the sign of a zero
    may differ: -0 == 0)."""
    dt = jnp.dtype(dtype)
    p = dj.Params.from_nondim(TAU, math.inf, 0.0)
    m = make_di_model(p, H * p.tau0, dtype)
    assert float(m.inv_tau_L) == 0.0 and float(m.gamma_bar) == 0.0  # w = V + h Xi
    # numpy scalars of dt throughout: under numpy 1.x a 0-d float32 array times 2, or its
    # nextafter, came out float64, so the "neighbours of h" rounded back to h in the float32 array
    h = dt.type(m.h)
    lo, hi = np.nextafter(h, dt.type(0)), np.nextafter(h, dt.type(2) * h)
    assert lo.dtype == hi.dtype == dt
    edge = np.array([h, -h, lo, hi, -lo, -hi, 0.0, -0.0, np.finfo(dt).tiny, -np.finfo(dt).tiny, 1e30, -1e30,
                     2 * h, -2 * h, h / 2], dt)
    assert edge[2] < h < edge[3] and np.array_equal(edge[2:4], [lo, hi])  # one ulp either side, in dt
    rand = (np.random.default_rng(7).standard_normal(100_000) * 3 * h).astype(dt)
    w = np.concatenate([edge, rand])
    got = np.asarray(m.step(jnp.asarray(w), jnp.zeros_like(jnp.asarray(w))))  # V = w, Xi = 0: w is the predictor
    want = np.sign(w) * np.maximum(np.abs(w) - h, dt.type(0))
    assert got.dtype == dt and np.array_equal(got, want)
    assert np.array_equal(got[:6], [0, 0, 0, hi - h, 0, h - hi])


def test_advance_flags_a_candidate_only_for_a_stuck_lane_released_out_of_its_set():
    r"""``advance``'s candidate: stuck (V = 0), X in the watched set (:math:`C_+` when ``watch_plus``,
    else :math:`C_-`) and released towards it (V' > 0, resp. < 0), from the definition; its state
    and increment are :meth:`move`'s."""
    m = _model()
    xp, xm = float(m.plus.center), float(m.minus.center)
    assert float(m.minus.c2) < float(m.plus.c1)  # disjoint sets
    out_p = float(m.plus.c2) + 0.5  # outside C_+ (and C_-)
    # (x, v, z1, watch_plus, candidate): big |z1| releases the velocity with the sign of z1
    cases = [(xp, 0.0, 40.0, True, True), (xp, 0.0, -40.0, True, False), (xp, 1e-3, 40.0, True, False),
             (out_p, 0.0, 40.0, True, False), (xm, 0.0, 40.0, True, False), (xp, 0.0, 0.0, True, False),
             (xm, 0.0, -40.0, False, True), (xm, 0.0, 40.0, False, False), (xm, -1e-3, -40.0, False, False),
             (xp, 0.0, -40.0, False, False)]
    for x, v, z1, wp, cand in cases:
        X, V, Z1, Z2 = (jnp.float64(a) for a in (x, v, z1, 0.0))
        (Xn, Vn), dU, _, c = m.advance((X, V), (Z1, Z2), jnp.bool_(wp))
        _, Xn2, Vn2, dU2 = m.move(X, V, Z1, Z2)
        assert bool(c) == cand, (x, v, z1, wp)
        assert (float(Xn), float(Vn), float(dU)) == (float(Xn2), float(Vn2), float(dU2))


def test_a_bruteforce_path_is_the_chain_by_hand():
    r"""``simulate_bruteforce``'s U of each path, rebuilt here from its documented numbers (path l's
    key ``split(fold_in(key, l // 4096), 4096)[l % 4096]``, whatever its chunk; block b's normals
    ``rng.normal(fold_in(path_key, b), (block, 2))``) and the by-hand step: from
    :math:`(x_\Delta, 0)`, steps ``[burn, burn + n)`` counted, with a burn-in and horizon that end
    inside blocks and two chunks, the last one short.  float64, to 1e-12 of the sum of :math:`|dU|`."""
    from dryfric_jax.bruteforce import simulate_bruteforce

    m = _model()
    key, n_paths, n_steps, burn, block, chunk = jax.random.key(11), 3, 29, 5, 8, 2
    U, t = simulate_bruteforce(m, key, n_paths, n_steps, burn_in_steps=burn, block=block, chunk_lanes=chunk)
    assert U.shape == (n_paths,) and t == pytest.approx(n_steps * H, rel=1e-14)
    for p in range(n_paths):
        pkey = jax.random.split(jax.random.fold_in(key, p // 4096), 4096)[p % 4096]
        z = np.concatenate([np.asarray(rng.normal(jax.random.fold_in(pkey, b), (block, 2), jnp.float64))
                            for b in range(-(-(burn + n_steps) // block))])
        x, v, u, scale = float(m.x_plus), 0.0, 0.0, 0.0
        for i in range(burn + n_steps):
            _, x, vn, du = _reference_step(x, v, z[i, 0], z[i, 1])
            v = vn
            if i >= burn:
                u, scale = u + du, scale + abs(du)
        assert scale > 0 and abs(U[p] - u) <= 1e-12 * scale, (p, U[p], u)


@pytest.mark.parametrize("dtype", [jnp.float64, jnp.float32])
def test_the_coin_and_the_normals_come_from_the_two_halves_of_the_block_key(dtype):
    """A block key k gives the step's normals from ``jax.random.split(k)[0]`` and the splitting coin's key from
    ``split(k)[1]`` (``DIModel.draw`` and ``coin_key``; regeneration's coin must be independent of the step's
    y).  The engine's own rebuild (test_engine) calls ``coin_key`` itself, so a coin key equal to the normals'
    key (the "wait" layout then draws the coin's uniform from the bits of the block's first normal) passed
    every other test (mutation audit).  The expected keys are ``jax.random``'s own, the normals :func:`rng.normal`'s."""
    m = make_di_model(dj.Params.from_nondim(TAU, TAU_L, GBAR, Gamma=GAMMA, Delta=DELTA), H * GAMMA / DELTA**2,
                      dtype)
    k = jax.random.fold_in(jax.random.key(7), 3)
    k0, k1 = jax.random.split(k)
    data = jax.random.key_data
    assert np.array_equal(data(m.coin_key(k)), data(k1))
    assert not np.array_equal(data(m.coin_key(k)), data(k0))
    z1, z2 = m.draw(k, 4)
    zs = rng.normal(k0, (4, 2), dtype)
    assert np.array_equal(np.asarray(z1), np.asarray(zs[:, 0])) and np.array_equal(np.asarray(z2), np.asarray(zs[:, 1]))
