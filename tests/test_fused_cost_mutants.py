"""Audit of ``dryfric_jax.fused`` (the "fused" event layout's Pallas kernel) and ``dryfric_jax.cost``
(default delta, threshold depth, the default-delta note, events per tau0, ``choose_method``) by
mutation testing: each test below failed on at least one mutant that the older tests let pass.

fused.py: 46 one-line mutants run against tests/test_engine.py -k fused; 38 killed there (the
round-level, bit-for-bit comparison with the "wait" layout is strong), 7 equivalent on a CPU
(Triton's warp count and the GPU branch of ``platform_dependent`` never run here; ``at``'s output
dtype taken from ``U0``, which the caller gives ``at``; ``n`` read from z1's second axis; ``at >=
block`` for ``at == block``, ``at`` never exceeding ``block``; the step index cast to float32, exact
below 2^24; the chain's constants read as (1,) blocks, which broadcast to the same values), 1 killed
only here: a lane whose steps do not count (SEEK) adding its dU to U.  The engine discards a SEEK
lane's U when it opens an excursion, so the round-level comparison cannot see it; the kernel's
contract (and the "wait" loop's lane state) can, tested below on the kernel itself.

cost.py: 47 mutants run against test_plan_audit.py, test_pdmp.py's two default-delta tests,
test_cli.py::test_pdmp_and_auto_json, test_stress.py's plan matrix and test_api_rest_mutants.py; 37
killed there, 4 equivalent (EVENT_COST = 1.0 makes ``*`` and ``/`` by it, and ``pdmp / EVENT_COST``
and ``pdmp``, the same; ``f"{4.2:g}" == str(4.2)``; ``delta_max`` takes ``|gamma_bar|`` itself), 5
killed only here, and 1 (``pdmp <= di`` for ``pdmp < di``: it differs only at an exact tie of the two
costs) killed since by test_choose_method_keeps_the_di_at_an_exact_tie, after choose_method's docstring
gave the rule (the DI: the default method, with no grid to choose).
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.cost import choose_method, default_delta_note, threshold_depth
from dryfric_jax.di import make_di_model

# ---------------------------------------------------------------- cost.py


def test_threshold_depth_uses_the_deeper_threshold_for_a_negative_bias():
    """README "The PDMP", bullet "Default δ": depth (Delta + |gamma_bar|) sqrt(tau / Gamma).  Gamma = 2, Delta = 4,
    tau = 2, gamma_bar = -0.8: (4 + 0.8) sqrt(1) = 4.8 > 4.2, so the note is given; with the bias
    taken signed (1 - 0.2) it was 3.2 and the note was lost.  Kills: ``abs`` dropped."""
    p = dj.Params(2.0, 4.0, 2.0, 1.0, -0.8)
    assert threshold_depth(p) == pytest.approx(4.8, rel=1e-14)
    note = default_delta_note(p)
    assert note is not None and "here one lies 4.8 SD out" in note


def test_default_delta_note_only_beyond_4_2_sd_not_at_it():
    """README: a run whose deeper threshold lies *more than* 4.2 SD out gets the note.  Gamma = Delta
    = 1 (units exact), tau = 16, gamma_bar = -0.05: (1 + 0.05) 4 = 4.2 exactly in float64, no note;
    tau = 16.0001 just beyond, a note.  Kills: ``depth < 4.2`` for ``depth <= 4.2``; "" for None."""
    at = dj.Params(1.0, 1.0, 16.0, 1.0, -0.05)
    assert threshold_depth(at) == 4.2
    assert default_delta_note(at) is None
    assert default_delta_note(dj.Params(1.0, 1.0, 16.0001, 1.0, -0.05)) is not None


def test_default_delta_note_gives_both_remedies():
    """The caveat tells the user what to do: compare with the DI or with half the delta.
    Kills: the advice shortened to the DI alone."""
    note = default_delta_note(dj.Params(1.0, 1.0, 25.0, 1.0, 0.0))  # depth 5
    assert note.endswith("compare with method 'di' or with half this delta")
    assert "up to stick thresholds 4.2 SD out" in note and "here one lies 5 SD out" in note


@pytest.mark.parametrize("h,delta,expected", [
    # Gamma = Delta = 1, tau = 1: tau0 = 1, tau' = 1, delta' = delta; PDMP 2/(1 delta)^2, DI 1/h
    (0.1, 0.5, "cost per tau0: PDMP 8 step-equivalents (2/(tau' delta')^2 = 8 events x 1) vs DI 10 steps (1/h'); "
               "chose pdmp"),
    (0.1, 0.25, "cost per tau0: PDMP 32 step-equivalents (2/(tau' delta')^2 = 32 events x 1) vs DI 10 steps "
                "(1/h'); chose di"),
])
def test_choose_method_reason_written_out(h, delta, expected):
    """The reason, written out from hand arithmetic (EVENT_COST = 1 shown as "1", ``:g``).
    Kills: ``{EVENT_COST}`` for ``{EVENT_COST:g}`` ("x 1.0")."""
    p = dj.Params(1.0, 1.0, 1.0, 10.0, 0.0)
    method, why = choose_method(p, h, delta)
    assert why == expected and method == expected.rsplit(" ", 1)[1]


def test_choose_method_keeps_the_di_at_an_exact_tie():
    """choose_method: 'the PDMP only if it is strictly cheaper'.  Gamma = Delta = tau = 1: PDMP 2/(2^-3)^2 =
    128 events x 1, DI 1/2^-7 = 128 steps, an exact tie in binary; one ulp of h either way breaks it.
    Kills ``pdmp <= di`` for ``pdmp < di``."""
    p = dj.Params(1.0, 1.0, 1.0, 10.0, 0.0)
    assert choose_method(p, 2.0**-7, 2.0**-3)[0] == "di"
    assert choose_method(p, math.nextafter(2.0**-7, 0), 2.0**-3)[0] == "pdmp"  # a shorter h: the DI dearer
    assert choose_method(p, math.nextafter(2.0**-7, 1), 2.0**-3)[0] == "di"


# ---------------------------------------------------------------- fused.py

K = 8  # steps in the block
N = 12  # lanes: fused.tile_for(12) = 4, so the kernel runs 3 tiles


def _inputs(m):
    """12 lanes in every situation the kernel distinguishes: stuck on C_+ or C_- (candidates of the
    splitting coin), sliding, done (at = -1), counters stopping at steps 0, 1, 3, 5 and 7, lanes whose
    steps do not count (SEEK), each watching C_+ or C_-."""
    r = np.random.default_rng(20261129)
    cp, cm = float(m.plus.center), float(m.minus.center)
    X = np.array([cp, cp, cm, cm, 0.1, -0.4, cp, cm, 0.9, -1.2, cp, 0.3])
    V = np.array([0.0, 0.0, 0.0, 0.0, 0.5, -0.3, 0.0, 0.0, 0.2, 0.0, 0.0, -0.1])
    U0 = 0.1 * np.arange(N) - 0.3
    at0 = np.array([K, K, K, K, K, -1, K, K, K, K, -1, K], float)
    first = np.array([K, K, K, K, 3, K, 0, 5, 1, K, K, 7], float)
    watch = np.array([1, 1, 0, 0, 1, 0, 1, 0, 1, 0, 1, 0], bool)
    counted = np.array([1, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1], bool)
    z1, z2 = r.standard_normal((K, N)), r.standard_normal((K, N))
    return X, V, U0, at0, first, watch, counted, z1, z2


def _oracle(m, X, V, U, at, first, watch, counted, z1, z2):
    """The kernel's documented step (fused module docstring) in numpy: for i = 0..K-1 a lane with
    ``at == K`` takes the DI step (DIModel.advance, one step, unfused) unless the step is an event
    (a coin candidate, or i >= first), where it stops and records at = i; U adds dU only where the
    lane's steps count.  Also returns which lanes stopped at a candidate and which added a dU
    while not counted (would have)."""
    X, V, U, at = X.copy(), V.copy(), U.copy(), at.copy()
    by_coin, uncounted_moves = np.zeros(N, bool), np.zeros(N, bool)
    for i in range(K):
        (Xn, Vn), dU, _, cand = m.advance((jnp.asarray(X), jnp.asarray(V)), (jnp.asarray(z1[i]), jnp.asarray(z2[i])),
                                          jnp.asarray(watch))
        Xn, Vn, dU, cand = map(np.asarray, (Xn, Vn, dU, cand))
        free = at == K
        event = free & (cand | (i >= first))
        by_coin |= free & cand & (i < first)
        go = free & ~event
        uncounted_moves |= go & ~counted & (dU != 0)
        X, V = np.where(go, Xn, X), np.where(go, Vn, V)
        U = U + np.where(go & counted, dU, 0.0)
        at = np.where(event, float(i), at)
    return X, V, U, at, by_coin, uncounted_moves


def test_fused_kernel_against_the_documented_step_lane_by_lane():
    """fused.quiet_steps called directly (Pallas interpreter, 12 lanes in 3 tiles of 4, K = 8, float64)
    against :func:`_oracle`: the same pending step ``at`` for every lane, and X, V, U to 1e-12.
    The inputs reach coin candidates, a budget stop at step 0, a done lane, moves that do not count,
    and lanes that run through the whole block.  Kills: ``go`` for ``go & counted`` in U's sum (let
    pass by the round-level comparison with "wait"); also, checked, the step index i + 1, ``fi >
    first``, the candidate test dropped, watch or counted flags inverted or swapped, z1 and z2
    swapped, one tile's normals for all, a grid of one tile."""
    from dryfric_jax.fused import quiet_steps, tile_for

    assert tile_for(N) == 4
    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    X, V, U0, at0, first, watch, counted, z1, z2 = _inputs(m)
    eX, eV, eU, eat, by_coin, uncounted_moves = _oracle(m, X, V, U0, at0, first, watch, counted, z1, z2)
    # the inputs reach what they are meant to
    assert by_coin.any() and uncounted_moves.any() and (eat == K).sum() >= 2 and eat[6] == 0.0
    run = jax.jit(lambda *a: quiet_steps(m, K, (a[0], a[1]), *a[2:7], (a[7], a[8])))
    (gX, gV), gU, gat = run(*map(jnp.asarray, (X, V, U0, at0, first, watch, counted, z1, z2)))
    np.testing.assert_array_equal(np.asarray(gat), eat)
    np.testing.assert_allclose(np.asarray(gX), eX, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(gV), eV, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(gU), eU, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("tile", [1, 2, 8])
def test_fused_kernel_tile_changes_no_number(monkeypatch, tile):
    """``scripts/device_check.py --kernel-tiles`` times the kernel at other Triton tiles (lanes per
    program, ``fused.TILE``) and reruns the layouts at the fastest: a tile only splits the lanes
    between programs, each lane's arithmetic and numbers are its own.  Here 12 lanes in 12, 6 or 3
    tiles (8 does not divide 12: ``tile_for`` takes 4) against the 3 tiles of the default (Pallas
    interpreter, float64): the same pending steps, and X, V, U to rounding (XLA:CPU compiles each
    tile shape apart: at tiles of 1 and 2 one lane's U moved by an ulp)."""
    from dryfric_jax import fused

    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    args = list(map(jnp.asarray, _inputs(m)))
    run = lambda: jax.jit(lambda *a: fused.quiet_steps(m, K, (a[0], a[1]), *a[2:7], (a[7], a[8])))(*args)
    ref = run()
    monkeypatch.setattr(fused, "TILE", tile)
    assert fused.tile_for(N) == min(tile, 4)
    (X, V), U, at = run()
    np.testing.assert_array_equal(np.asarray(at), np.asarray(ref[2]))
    for a, b in ((X, ref[0][0]), (V, ref[0][1]), (U, ref[1])):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-14, atol=1e-16)
