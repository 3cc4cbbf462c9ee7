"""The GPU layout of a block ("wait", ``excursions._block``) run on the CPU against exact values.

CI has no GPU, so the layout a GPU runs by default is forced here (``DEFAULT_EVENTS``): a lane
waits at its first event of the block and the event runs once per block.  It uses the block's
random numbers differently from the CPU layout, so its estimates are checked against the same
exact values as the CPU's: white-noise closed forms for the DI (MODEL_NOTES section 2) and the
exact stationary law of the jump chain for the PDMP.  Tolerance: the 95% CI, fixed seeds.
"""
import math
import warnings

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import excursions

TAU_WHITE = 1e-5


@pytest.fixture(autouse=True)
def _wait_layout(monkeypatch):
    monkeypatch.setattr(excursions, "DEFAULT_EVENTS", "wait")


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        return fn(*a, **kw)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_di_matches_white_noise_exact_values(dtype):
    G, Dl = 5.0, 3.84
    p = dj.Params(G, Dl, TAU_WHITE * G / Dl**2, 0.067, 0.342)
    r = _quiet(dj.estimate_diffusivity, p, 15, n_excursions=30_000, dtype=dtype)
    assert r.n_truncated == 0 and r.dtype == dtype
    assert r.D_ci <= 0.05 * r.D
    D, M = dj.theory.exact_D(p), dj.theory.exact_M0(p)
    assert abs(r.D - D) <= r.D_ci, (r.D, r.D_ci, D)
    assert abs(r.M0 - M) <= r.M0_ci, (r.M0, r.M0_ci, M)
    # the idle rest of a block after each event is paid for, and reported
    assert 0.5 < r.lane_utilization < 1.0


def test_pdmp_stiff_viscous_mobility_matches_the_exact_stationary_law():
    """As ``test_pdmp.test_stiff_viscous_limit_mobility_is_exact``: v = tau_L S(x + gamma_bar).
    Seeds 40-47, z of M0 against the exact value: wait +0.73 +0.76 -2.55 +0.79 -0.10 +0.80 -0.64
    +1.85, branch +0.59 +0.77 -2.64 +0.91 -0.58 +0.03 -1.31 +0.88 (seed 42 is a 2.6-sigma draw
    in both layouts: their lanes share keys and differ only after each lane's first event)."""
    from dryfric_jax.noise import grid_size, stationary_law

    tau, tau_L, gb, d = 1.0, 1e-4, 0.3, 0.1
    p = dj.Params.from_nondim(tau, tau_L, gb)
    r = _quiet(dj.estimate_diffusivity, p, 41, method="pdmp", delta=d, n_excursions=10_000)
    x, pi = stationary_law(grid_size(d, tau, gb), d, tau)
    f = x + gb
    exact = tau_L * (pi * np.sign(f) * np.maximum(np.abs(f) - 1.0, 0.0)).sum()
    assert r.n_truncated == 0 and math.isfinite(r.D) and r.D > 0
    assert r.M0_ci < 0.1 * exact and abs(r.M0 - exact) <= r.M0_ci, (r.M0, r.M0_ci, exact)
