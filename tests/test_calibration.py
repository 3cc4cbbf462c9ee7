"""Calibration of the 95% CI for D: empirical coverage over independent replicates, white noise,
against the exact D' = 10 (MODEL_NOTES section 2).  Slow, but it runs in CI.

Replicates are groups of lanes (each lane holds i.i.d. excursions).  h' = 0.02 has a measured
bias of about -0.7% on D, a twentieth of the replicate half-width (~10% at 2e4), so it cannot move the
coverage by more than ~0.005.
"""
import math

import pytest

import dryfric_jax as dj
from dryfric_jax.di import make_di_model
from dryfric_jax.estimators import MIN_RELIABLE_N, replicate_coverage
from dryfric_jax.excursions import STAT_NAMES, simulate_long_excursions

PER_LANE = 100
REPLICATES = 120


@pytest.mark.slow
def test_coverage_of_D_ci_at_the_reliable_size():
    p = dj.Params.from_nondim(1e-5)
    n = MIN_RELIABLE_N
    sim = simulate_long_excursions(make_di_model(p, 0.02), dj.api._key(2026)[0], REPLICATES * n, per_lane=PER_LANE)
    assert sim.n_truncated == 0
    c = replicate_coverage(sim.stats, STAT_NAMES, n // PER_LANE, 10.0, 0.0)
    assert c["replicates"] == REPLICATES
    se = math.sqrt(0.95 * 0.05 / REPLICATES)
    print(f"coverage(D) = {c['coverage_D']:.3f} ± {se:.3f}, coverage(M0) = {c['coverage_M0']:.3f}")
    assert 0.90 <= c["coverage_D"] <= 0.99
    assert 0.90 <= c["coverage_M0"] <= 0.99
