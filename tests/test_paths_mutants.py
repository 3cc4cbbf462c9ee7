"""Mutation audit of paths.py: tests that kill the mutants test_paths.py let through (29 tried,
24 killed there; these kill v0 ignored, v0's sign lost, an empty last chunk, and the stationary
sd in the model's dtype; a float32 rounding of V in the autocovariance, ~1e-7, is left alive).
The oracles are independent of paths.py: the documented per-path
random numbers stepped by a plain numpy loop of the DI chain (MODEL_NOTES section 3.1, the
soft threshold of the fresh predictor), the exact stationary law of the OU noise and of its
discrete AR(1) chain, computed in numpy."""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import rng
from dryfric_jax.di import make_di_model
from dryfric_jax.params import Params
from dryfric_jax.paths import di_transient

TAU = 0.05  # tau' (pure dry friction: Gamma = Delta = 1, b = 0)
H = 2e-3  # h'


def _numpy_run(model, x, v, z):
    """(X, V, U) after the steps of the rows of z, in numpy float64: X -> (Xi, X') from the OU
    coefficients, w = V + h Xi, V' = sign(w) max(|w| - h, 0), U += h (V + V') / 2 (trapezoid)."""
    ou = model.ou
    m1, l11, m2, l21, l22 = (float(a) for a in (ou.m1, ou.L11, ou.m2, ou.L21, ou.L22))
    h, u = float(model.h), 0.0
    for z1, z2 in np.asarray(z):
        xi, x = x * m1 + l11 * z1, x * m2 + l21 * z1 + l22 * z2
        w = v + h * xi
        vn = math.copysign(max(abs(w) - h, 0.0), w)
        u, v = u + 0.5 * h * (v + vn), vn
    return x, v, u


def _numpy_paths(model, x0, v0, keys, segments):
    """V after each segment, every path stepped on its own (:func:`_numpy_run`): segment i of the
    path with key k uses ``rng.normal(fold_in(k, i), (n_i, 2))`` (the documented numbers)."""
    out = np.empty((len(keys), len(segments)))
    for p, k in enumerate(keys):
        x, v = float(x0[p]), v0
        for i, n in enumerate(segments):
            z = np.asarray(rng.normal(jax.random.fold_in(k, i), (n, 2), jnp.float64)) if n else []
            x, v, _ = _numpy_run(model, x, v, z)
            out[p, i] = v
    return out


@pytest.mark.parametrize("v0", [-0.7, 0.0])
def test_di_transient_starts_at_v0_and_chunks_that_divide_n_paths(v0):
    """Kills: v0 ignored (V0 = 1 always), v0's sign lost (abs), and the chunk count
    ``n_paths // chunk + 1`` (an empty last chunk when chunk divides n_paths: an IndexError).
    All existing tests start at v0 = 1 with n_paths not a multiple of chunk.  4 paths in 2 chunks of
    2, recorded after 0, 3, 3 and 40 steps, against the numpy loop of the documented numbers from
    X0 = N(0, 1/tau') (exact law) and V0 = v0; V after 0 steps is v0 exactly."""
    model = make_di_model(Params.from_nondim(TAU), H)
    key = jax.random.key(21)
    steps = [0, 3, 3, 40]
    V = di_transient(model, key, 4, steps, v0=v0, chunk=2)
    assert V.shape == (4, 4)
    assert np.all(V[:, 0] == v0)
    segments = np.diff([0] + steps)
    for c in range(2):
        kx, kp = jax.random.split(jax.random.fold_in(key, c))
        x0 = np.asarray(jax.random.normal(kx, (2,), jnp.float64)) / math.sqrt(TAU)
        ref = _numpy_paths(model, x0, v0, jax.random.split(kp, 2), segments)
        np.testing.assert_allclose(V[2 * c: 2 * c + 2], ref, rtol=1e-12, atol=1e-13)
    assert np.all(V[:, 3] != V[:, 2]) and np.any(V[:, 3] != 0)  # the paths moved: the check has teeth


def test_stationary_sd_of_a_float32_model_is_that_of_its_rounded_chain():
    """Kills: OUStep.stationary_sd computed in the model's dtype instead of float64 (2.5e-5 relative off
    at h/tau = 1e-4 in float32; immaterial to any figure, which all run float64, but the docstring
    promises float64).  Oracle: the exact stationary sd of the AR(1) chain X' = m2 X + L21 z1 +
    L22 z2 with the model's float32 coefficients, sqrt((L21^2 + L22^2) / (1 - m2^2)) in numpy
    float64; the result is its float32 rounding (6e-8 relative)."""
    p = Params.from_nondim(10.0)
    m = make_di_model(p, 1e-3 * p.tau0, "float32")
    l21, l22, m2 = (np.float64(np.asarray(a)) for a in (m.ou.L21, m.ou.L22, m.ou.m2))
    exact = math.sqrt((l21**2 + l22**2) / (1.0 - m2**2))
    sd = m.ou.stationary_sd()
    assert sd.dtype == jnp.float32
    assert float(sd) == pytest.approx(exact, rel=1e-6)
    # near the OU law 1/sqrt(tau'): m2's float32 rounding (6e-8) moves 1 - m2^2 = 2e-4 by up to 3e-4
    assert float(sd) == pytest.approx(1 / math.sqrt(10.0), rel=1e-3)
