r"""Mutation audit of :mod:`dryfric_jax.bruteforce` (fixed-horizon paths) and :mod:`dryfric_jax.bench_numba`
(the benchmark's numba baseline).

Oracles: brute-force paths rebuilt by hand from their documented keys and the DI step of MODEL_NOTES
section 3.1 (the OU pair from the 60-digit ``ou_moments_reference``); the baseline's DI worker run as plain
Python (``_worker.py_func``) on a scripted generator whose normals and uniforms make every step a hand
calculation (below); the sums :math:`\sum U^p t^q` written out by hand; numpy's own ``Generator`` recipe;
a fake ``_on_threads`` / ``over_lanes`` that records what it is given.

Each test's docstring names the mutants it kills. Mutants tried: 94 (36 of bruteforce.py, 58 of bench_numba.py); the
other tests (the brute-force tests of test_di_step, test_stopping_rule, test_cli, test_reproducibility; all of
test_bench_numba) killed 55 (27 and 28; 7 of those only by hanging test_bench_numba past a time limit: the tests here
kill each of the 7 in seconds, and since the workers' work bound test_bench_numba stops them too); 5 are equivalent:
one block more than needed (its steps are not counted), the redundant ``[:n_paths]`` and ``np.asarray`` of the
concatenated U, ``sums`` slicing one column more (``zip`` stops at SUMS), and the baseline's displacement ``h
V_{n+1}`` for the trapezoid (equal: every cycle starts and ends at V = 0). A few killed here change no distribution
but the stream or an edge of probability 0 (the draw order, the clock from u for 1 - u, the closed edge of C_+, u = 0,
the start at -x_Delta): they pin what the same seed gives and the engine's conventions.
"""
import inspect
import math
import threading

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import bruteforce, rng
from dryfric_jax.di import make_di_model
from dryfric_jax.excursions import BLOCK
from dryfric_jax.limits import MAX_WORK
from dryfric_jax.ou import ou_moments_reference
from dryfric_jax.pdmp import make_pdmp_model
from dryfric_jax.plan import default_delta, default_h

TAU, TAU_L, GBAR, H = 0.5, 2.0, 0.2, 0.05  # nondimensional (Gamma = Delta = 1: physical = nondimensional)


def _model(dtype=jnp.float64):
    return make_di_model(dj.Params.from_nondim(TAU, TAU_L, GBAR), H, dtype)


def _ou_factors():
    """The OU pair's mean factors and lower Cholesky factor, from the closed-form moments (float64)."""
    m1, m2, S11, S12, S22 = ou_moments_reference(H, TAU)
    L11 = math.sqrt(S11)
    L21 = S12 / L11
    return m1, m2, L11, L21, math.sqrt(S22 - L21 * L21)


def _path_by_hand(x0, z, burn, n):
    r"""U over steps [burn, burn + n) of the DI chain from (x0, 0) with normals z (float64): the OU pair, then
    :math:`w = v + h(\bar\gamma - v/\tau_L + \Xi)`, :math:`V' = \mathrm{sign}(w)\max(|w| - h, 0)`, trapezoid."""
    m1, m2, L11, L21, L22 = _ou_factors()
    x, v, u, scale = x0, 0.0, 0.0, 0.0
    for i in range(burn + n):
        z1, z2 = float(z[i, 0]), float(z[i, 1])
        xi, x = x * m1 + L11 * z1, x * m2 + L21 * z1 + L22 * z2
        w = v + H * (GBAR - v / TAU_L + xi)
        vn = math.copysign(max(abs(w) - H, 0.0), w)
        if i >= burn:
            u, scale = u + 0.5 * H * (v + vn), scale + abs(0.5 * H * (v + vn))
        v = vn
    return u, scale


def _normals(key, path, n_blocks, block, dtype):
    """The documented numbers of path ``path``, whatever its chunk: block b draws
    ``rng.normal(fold_in(split(fold_in(key, path // 4096), 4096)[path % 4096], b), (block, 2), dtype)``."""
    pkey = jax.random.split(jax.random.fold_in(key, path // 4096), 4096)[path % 4096]
    return np.concatenate([np.asarray(rng.normal(jax.random.fold_in(pkey, b), (block, 2), dtype), np.float64)
                           for b in range(n_blocks)])


# ---------------------------------------------------------------- bruteforce.py
def test_a_float32_path_is_the_float32_chain_and_its_U_is_float64():
    """A float32 model runs in float32 (its normals are float32 draws) and sums U in float64.  Kills the
    state and draws in float64 whatever the model (``dt = jnp.float64``: other normals, another path) and
    U summed in the model's dtype (a float32 carry that the float64 increments do not fit: an error)."""
    m = _model(jnp.float32)
    key, n_paths, n_steps, burn, block, chunk = jax.random.key(5), 3, 21, 3, 8, 2
    U, t = bruteforce.simulate_bruteforce(m, key, n_paths, n_steps, burn_in_steps=burn, block=block, chunk_lanes=chunk)
    assert U.dtype == np.float64 and U.shape == (n_paths,)
    assert t == pytest.approx(n_steps * float(np.float32(H)), rel=1e-12)
    for p in range(n_paths):
        z = _normals(key, p, -(-(burn + n_steps) // block), block, jnp.float32)
        u, scale = _path_by_hand(float(m.x_plus), z, burn, n_steps)
        # float32 rounding of the state: ~1e-7 relative per step, 24 steps of a damped chain
        assert scale > 0 and abs(U[p] - u) <= 1e-4 * scale, (p, U[p], u)


def test_the_defaults_are_no_burn_in_blocks_of_BLOCK_and_chunks_of_4096_paths():
    """``simulate_bruteforce(model, key, n_paths, n_steps)`` is the call with burn_in_steps=0, block=BLOCK,
    chunk_lanes=4096 (the signature's defaults, which the API passes explicitly): 4097 paths, two chunks.
    Kills a default burn-in of 1 step.  Since 0.2.6 a path's key does not depend on the chunk, so a default
    chunk of 1024 paths (which gave other keys to every path after the first 1024) is equivalent here; the
    chunk-independence test in test_bruteforce_horizon pins that instead."""
    m, key = _model(), jax.random.key(9)
    a, ta = bruteforce.simulate_bruteforce(m, key, 4097, 3)
    b, tb = bruteforce.simulate_bruteforce(m, key, 4097, 3, burn_in_steps=0, block=BLOCK, chunk_lanes=4096)
    assert ta == tb == 3 * H and a.shape == (4097,) and np.abs(a).max() > 0
    assert np.array_equal(a, b)


def test_the_smallest_counts_are_accepted_one_path_one_step_one_lane():
    """n_paths = 1, n_steps = 1, chunk_lanes = 1 are valid (the checks are ``>= 1``): U is one trapezoid
    from (x_Delta, 0), by hand.  Kills ``check_count("n_paths", n_paths, 2)`` and
    ``check_count("chunk_lanes", chunk_lanes, 2)``."""
    m = _model()
    for seed in range(64):  # the first key whose first step leaves the stuck state (most stay stuck)
        key = jax.random.key(seed)
        u, scale = _path_by_hand(float(m.x_plus), _normals(key, 0, 1, BLOCK, jnp.float64), 0, 1)
        if scale > 0:
            break
    assert scale > 0
    U, t = bruteforce.simulate_bruteforce(m, key, 1, 1, chunk_lanes=1)
    assert t == H and U.shape == (1,)
    assert U[0] != 0 and U[0] == pytest.approx(u, rel=1e-12)


def test_counts_above_2_31_steps_reach_the_kernel_exactly_as_int64(monkeypatch):
    """The API allows up to 2^62 steps per path; the burn-in and horizon must reach the compiled loop as
    int64 (as int32 they overflow: 2^40 is refused, or wraps).  A fake ``over_lanes`` records them.
    Kills ``jnp.asarray(burn_in_steps, jnp.int32)`` and ``jnp.asarray(n_steps, jnp.int32)``."""
    seen = []

    def fake(fn, args, lane_args, **static):
        seen.append((fn, args, lane_args, static))
        return np.zeros(len(args[1]))

    monkeypatch.setattr(bruteforce, "over_lanes", fake)
    U, t = bruteforce.simulate_bruteforce(_model(), jax.random.key(0), 3, 2**40 + 3, burn_in_steps=2**41 + 1,
                                          block=16)
    assert t == (2**40 + 3) * H and U.shape == (3,)
    (fn, args, lane_args, static), = seen
    assert fn is bruteforce._run_paths and lane_args == (False, True, False, False) and static == {"block": 16}
    assert args[2].dtype == jnp.int64 and int(args[2]) == 2**41 + 1
    assert args[3].dtype == jnp.int64 and int(args[3]) == 2**40 + 3


# ---------------------------------------------------------------- bench_numba.py
nb = pytest.importorskip("dryfric_jax.bench_numba", reason="numba not installed: pip install -e '.[bench]'")

#: the powers (p, q) of U^p t^q of each sum, by name (read off the names)
POWERS = {"n": (0, 0), "U": (1, 0), "U2": (2, 0), "U3": (3, 0), "U4": (4, 0), "t": (0, 1), "t2": (0, 2),
          "t3": (0, 3), "t4": (0, 4), "Ut": (1, 1), "U2t": (2, 1), "U3t": (3, 1), "Ut2": (1, 2), "U2t2": (2, 2),
          "Ut3": (1, 3)}


def _sums_by_hand(excursions):
    return {k: sum(U**p * t**q for U, t in excursions) for k, (p, q) in POWERS.items()}


def test_add_and_sums_are_the_power_sums_by_name():
    """Two workers' rows, one excursion each, (U, t) = (2, 3) and (-1, 0.5), then the steps: ``sums`` gives
    every :math:`\\sum U^p t^q` under its name (exact in binary), ``t_half`` = 0, and not the steps.  Kills
    wrong powers in ``_add`` (U^4 for U^3, U^3 for U^4, t^3 for t^4, U^2 t for U t^2, U t^2 for U t^3), the
    names U2t and Ut2 swapped in SUMS, and the ``t_half`` entry dropped."""
    rows = np.zeros((2, len(nb.SUMS) + len(nb.TAIL)))
    nb._add(rows[0], 2.0, 3.0)
    nb._add(rows[1], -1.0, 0.5)
    rows[:, len(nb.SUMS):] = [[11.0, 2.0, 13.0], [7.0, 1.0, 9.0]]
    got = nb.sums(rows)
    assert got == {**_sums_by_hand([(2.0, 3.0), (-1.0, 0.5)]), "t_half": 0.0}
    assert set(nb.SUMS) == set(POWERS)


def test_generators_are_pcg64_streams_spawned_from_the_seed():
    """Worker i draws from ``Generator(PCG64(SeedSequence(seed).spawn(threads)[i]))`` (the module says so).
    Kills ``SeedSequence(seed + 1)``, Philox for PCG64, and every worker on the parent seed (equal streams)."""
    for seed, threads in ((5, 2), (0, 3)):
        got = [g.standard_normal(4) for g in nb.generators(seed, threads)]
        want = [np.random.Generator(np.random.PCG64(s)).standard_normal(4)
                for s in np.random.SeedSequence(seed).spawn(threads)]
        assert len(got) == threads and all(np.array_equal(a, b) for a, b in zip(got, want))
        assert not np.array_equal(got[0], got[1])


def test_on_threads_runs_the_workers_at_once_each_on_the_ceiling_share():
    """3 workers, 7 excursions: each gets ceil(7/3) = 3, its own generator (in order) and the args, and all
    three run at the same time (a barrier of 3 that a serial pool would never pass: the bench's 2-thread rate
    would be a 1-thread one).  Kills ``ThreadPoolExecutor(1)``, a floor share (2) and the whole count (7)."""
    barrier = threading.Barrier(3, timeout=5)

    def worker(g, n_each, a, b):
        barrier.wait()
        return np.array([n_each, a, b, g.random()])

    rows = nb._on_threads(worker, 4, 3, 7, (1.5, -2.0))
    firsts = [g.random() for g in nb.generators(4, 3)]
    assert np.array_equal(rows, np.array([[3, 1.5, -2.0, f] for f in firsts]))


def _recorded(monkeypatch, run, model):
    rec = []

    def fake(worker, seed, threads, n, args):
        rec.append((worker, seed, threads, n, args))
        # each of the 2 workers ran its 5 excursions; the steps, then no truncation, then the work
        return np.array([[5.0] + [0.0] * (len(nb.SUMS) - 1) + [7.0, 0.0, 8.0],
                         [5.0] + [0.0] * (len(nb.SUMS) - 1) + [5.0, 0.0, 9.0]])

    monkeypatch.setattr(nb, "_on_threads", fake)
    out, steps = run(model, 10, 2, 3)
    assert steps == 12 and out.shape == (2, len(nb.SUMS) + 3)  # the steps: their column's sum (not the work's)
    (worker, seed, threads, n, args), = rec
    assert (seed, threads, n) == (3, 2, 10)
    return worker, dict(zip(list(inspect.signature(worker.py_func).parameters)[2:], args))


def test_run_numba_passes_the_models_numbers_to_the_worker_by_name(monkeypatch):
    """``run_numba`` hands ``_worker`` the model's numbers in the worker's parameter order (its signature is
    the oracle: P, M are (c1, c2, a1, a2, a_sq) of C_+ and C_-), max_steps 1e9 unless told, and each of the 2
    workers half the engine's default work bound (limits.MAX_WORK).  Kills m1 and m2 swapped, L21 and L22
    swapped, C_+ and C_- swapped, gamma_bar and 1/tau_L swapped, -x_Delta for the start, a default max_steps
    of 1e3, each worker given the whole work bound."""
    p = dj.Params(**dj.FIG3)
    m = make_di_model(p, default_h(p))
    worker, got = _recorded(monkeypatch, nb.run_numba, m)
    assert worker is nb._worker
    f = lambda a: float(np.asarray(a))
    sset = lambda s: [f(s.c1), f(s.c2), f(s.a1), f(s.a2), f(s.a_sq)]
    o = m.ou
    want = dict(max_steps=10**9, max_work=MAX_WORK / 2, h=f(m.h), gb=f(m.gamma_bar), itl=f(m.inv_tau_L),
                m1=f(o.m1), m2=f(o.m2), L11=f(o.L11), L21=f(o.L21), L22=f(o.L22), P=sset(m.plus), M=sset(m.minus),
                x0=f(m.x_plus))
    assert set(got) == set(want)
    for k in want:
        assert np.array_equal(got[k], want[k]), k
    # the numbers differ pairwise, so a swap shows
    assert len({want["m1"], want["m2"]}) == 2 and want["L21"] != want["L22"] and want["gb"] != want["itl"]


def test_run_numba_pdmp_passes_the_models_numbers_to_the_worker_by_name(monkeypatch):
    """The same for ``run_numba_pdmp`` and ``_pdmp_worker`` (kappa is 1/tau_L).  Kills r_+ and r_- swapped."""
    p = dj.Params(**dj.FIG3)
    m = make_pdmp_model(p, default_delta(p))
    worker, got = _recorded(monkeypatch, nb.run_numba_pdmp, m)
    assert worker is nb._pdmp_worker
    f = lambda a: float(np.asarray(a))
    i = lambda a: int(np.asarray(a))
    want = dict(max_work=MAX_WORK / 2, N=i(m.N), kp=i(m.kp), km=i(m.km), delta=f(m.delta), c_alpha=f(m.c_alpha),
                rate=f(m.rate), kappa=f(m.inv_tau_L), r_p=f(m.r_p), r_m=f(m.r_m))
    assert got == want and type(got["N"]) is int and type(got["max_work"]) is int and want["r_p"] != want["r_m"]


class _Script:
    """A stand-in for numpy's Generator: the normals and uniforms given, in order; running out is an error
    (IndexError), and the test checks that none is left over."""

    def __init__(self, z, u):
        self.z, self.u = list(z), list(u)

    def standard_normal(self):
        return self.z.pop(0)

    def random(self):
        return self.u.pop(0)


# The scripted DI worker.  h = 1/2, no bias, no viscous term, the OU pair made trivial (m1 = m2 = 0, L = I):
# Xi = z1 and the next X = z2, so w = V + z1/2 and V' = sign(w) max(|w| - 1/2, 0).  C_+ = [0.5, 1.5],
# C_- = [-1.5, -0.5], a = (1, 0), a_sq = 4: log r = min(-d1 z1 - 2 d1^2, -d2 z1 - 2 d2^2), d = X - c1, X - c2.
# Heads when log u < log r.  Step by step (X, V at the start; U, n after the step):
#  s0  X=1   V=0    z1=-4: V'=-1.5, not released up: no coin, seeking (not counted)
#  s0b X=1   V=-1.5 z1=4: V'=0 (seeking)
#  s1  X=1   V=0    z1=4: V'=1.5, released up in C_+: log r = min(-2.5, 1.5) = -2.5, u=.05 (log -3.0): heads,
#                   a cycle starts with this step: U = (0 + 1.5)/4 = .375, n = 1
#  s2  X=-1  V=1.5  z1=-4: V'=-0 (stuck): U = .75, n = 2
#  s3  X=-1  V=-0   z1=-4: V'=-1.5, released down in C_-: log r = min(1.5, -2.5) = -2.5, u=.25 (log -1.39): tails,
#                   U = .375, n = 3
#  s4  X=1   V=-1.5 z1=4: V'=0: U = 0, n = 4
#  s5  X=-1  V=0    z1=-4: V'=-1.5 in C_-: log r = -2.5, u=.05: heads (now watching C_+), U = -.375, n = 5
#  s6  X=1   V=-1.5 z1=4: V'=0: U = -.75, n = 6
#  s7  X=.5  V=0    z1=4: V'=1.5, X on the edge of C_+ (closed): log r = min(0, 2) = 0, u=0: heads (log 0 = -inf);
#                   the excursion (U, t) = (-.75, 6 h = 3) closes; the next starts with this step: U = .375, n = 1
#  s8  X=0   V=1.5  z1=-4: V'=-0: U = .75, n = 2
#  s9  X=-1  V=-0   z1=-5: V'=-2 in C_-: log r = min(2.5 - .5, -2.5 - .5) = -3, u=.04 (log -3.22): heads, U = .25, n = 3
#  s10 X=1   V=-2   z1=5: V'=0: U = -.25, n = 4
#  s11 X=1   V=0    z1=4: V'=1.5 in C_+: log r = -2.5, u=.05: heads: (U, t) = (-.25, 4 h = 2) closes.
# Useful steps (in a cycle): s1..s11 = 11.
_Z = [(-4, 1.0), (4, 1.0), (4, -1.0), (-4, -1.0), (-4, 1.0), (4, -1.0), (-4, 1.0), (4, 0.5), (4, 0.0), (-4, -1.0),
      (-5, 1.0), (5, 1.0), (4, 0.0)]
_U = [0.05, 0.25, 0.05, 0.0, 0.04, 0.05]
_DI = dict(h=0.5, gb=0.0, itl=0.0, m1=0.0, m2=0.0, L11=1.0, L21=0.0, L22=1.0,
           P=np.array([0.5, 1.5, 1.0, 0.0, 4.0]), M=np.array([-1.5, -0.5, 1.0, 0.0, 4.0]), x0=1.0)


def _scripted(n_exc, max_steps, max_work=100):
    g = _Script([float(z) for zz in _Z for z in zz], _U)
    acc = nb._worker.py_func(g, n_exc, max_steps, max_work, **_DI)
    assert g.z == [] and g.u == []  # every number drawn, no more
    return dict(zip(nb.SUMS, acc[:len(nb.SUMS)])), dict(zip(nb.TAIL, acc[len(nb.SUMS):]))


def test_the_di_worker_runs_two_excursions_by_hand():
    """The scripted run above (max_steps 7: the 6-step excursion is not truncated): the sums of (-0.75, 3) and
    (-0.25, 2), 11 useful steps.  Kills: threshold 2h; release directions swapped; the open set
    ``S[0] < X < S[1]``; ``d1^2 a_sq`` without 1/2; ``log u > log r``; ``min`` -> ``max`` in log r; a1 and a2
    swapped; u = 0 taken as tails; t = (n + 1) h; U not reset at a regeneration in the minus phase
    (``phase == SEEK``); the seek's regeneration counted as an excursion; U doubled; ``useful += 2``; the
    count of excursions for the steps; seek steps counted as useful; the coin asked when V' = 0 (not V); C_+
    and C_- swapped; the two normals drawn in the other order; L21 z2 + L22 z1 for the next X."""
    got, tail = _scripted(2, 7)
    want = _sums_by_hand([(-0.75, 3.0), (-0.25, 2.0)])
    assert got == pytest.approx(want, rel=1e-15, abs=1e-15) and got["n"] == 2
    assert tail == {"steps": 11, "n_truncated": 0, "work": 13}  # the work: the 2 seek steps too


def test_the_di_worker_stops_at_its_work_bound():
    """The scripted run needs 13 steps in all: a bound of 13 lets it finish, 12 stops it before s11 (one
    excursion of the two, every number but s11's drawn), 5 after s3 (none; 3 useful steps).  Kills the bound
    dropped (a run that never ends on a broken chain), ``work <= max_work`` (12 finishes) and the work
    counted only in excursions (seeks are work: 12 finishes)."""
    assert _scripted(2, 7, max_work=13)[1]["work"] == 13
    for bound, n, steps, left in ((12, 1, 10, 2), (5, 0, 3, 16)):
        g = _Script([float(z) for zz in _Z for z in zz], _U)
        acc = nb._worker.py_func(g, 2, 7, bound, **_DI)
        tail = dict(zip(nb.TAIL, acc[len(nb.SUMS):]))
        assert acc[0] == n and tail == {"steps": steps, "n_truncated": 0, "work": bound}, (bound, acc)
        assert len(g.z) == left


# The scripted DI worker with the viscous term 1/tau_L = 1 (the script above has none): the same trivial OU pair
# and sets, h = 1/2, so w = V + (z1 - V)/2.  (X, V at the start; U, n after the step; U += (V + V')/4.)
#  s1 X=1  V=0     z1=4: V'=1.5 in C_+: log r = -2.5, u=.05: heads, a cycle starts: U = .375, n = 1
#  s2 X=1  V=1.5   z1=0: w = .75, V'=.25 (the damping; without it w = 1.5: V' = 1): U = .8125, n = 2
#  s3 X=1  V=.25   z1=0: w = .125, V'=0 (stuck): U = .875, n = 3
#  s4 X=-1 V=0     z1=-5: V'=-2 in C_-: log r = min(2, -3) = -3, u=.04 (log -3.22): heads: U = .375, n = 4
#  s5 X=-1 V=-2    z1=0: w = -1, V'=-.5: U = -.25, n = 5
#  s6 X=-1 V=-.5   z1=0: w = -.25, V'=-0 (stuck): U = -.375, n = 6
#  s7 X=1  V=-0    z1=4: V'=1.5 in C_+: log r = -2.5, u=.05: heads: (U, t) = (-.375, 6 h = 3) closes; 7 useful.
# With the damping's sign flipped (w = V + (z1 + V)/2) the velocity grows (1.5, 1.75, 2.125, ...), never sticks,
# and the script runs out (IndexError) where the real baseline ran for ever.
_Z_VISCOUS = [(4, 1.0), (0, 1.0), (0, -1.0), (-5, -1.0), (0, -1.0), (0, 1.0), (4, 1.0)]


def test_the_di_worker_damps_the_velocity_by_hand():
    """The scripted run above with 1/tau_L = 1: one excursion (-0.375, 3), 7 useful steps, every number drawn.
    Kills the viscous term's sign flipped (``gb + V itl``), which the other tests saw only as test_bench_numba
    hanging, and the term dropped."""
    g = _Script([float(z) for zz in _Z_VISCOUS for z in zz], [0.05, 0.04, 0.05])
    acc = nb._worker.py_func(g, 1, 100, 100, **dict(_DI, itl=1.0))
    assert g.z == [] and g.u == []
    got = dict(zip(nb.SUMS, acc[:len(nb.SUMS)]))
    assert got == pytest.approx(_sums_by_hand([(-0.375, 3.0)]), rel=1e-15, abs=1e-15) and got["n"] == 1
    assert acc[nb.STEPS] == 7


def test_the_di_worker_closes_an_excursion_at_max_steps_counts_it_and_seeks_again():
    """The same script with max_steps = 6: the first excursion reaches n = 6 at s6, is closed without entering
    the sums and counted as truncated, the lane seeks, s7 regenerates (not an excursion end), and the second
    one, 4 steps, is the only one in the sums; its 6 truncated steps were useful work.  Kills ``n > max_steps``
    (the first one closes, numbers left over), a truncation that keeps the minus phase (a (0, 0) excursion at
    s7) and a truncation not counted (the rule of the engine: reported, never silently dropped)."""
    got, tail = _scripted(1, 6)
    assert got == pytest.approx(_sums_by_hand([(-0.25, 2.0)]), rel=1e-15, abs=1e-15)
    assert tail == {"steps": 11, "n_truncated": 1, "work": 13}


# The scripted PDMP worker: grid x_k = k (delta = 1), k_+ = k_- = 0 (stuck only at k = 0), r_+ = -1/2, r_- = 1/2,
# so a = k - 1/2 in mode y = +1 and k + 1/2 in mode y = -1; c_alpha = 0.1 (alpha_k = 0.4, 0.5, 0.6 at k = 1, 0, -1),
# rate 2.  Six events, each drawing (clock uniform, step uniform); the clock's exponential time is -ln(1 - r)/2:
#  E1 s_+ = (k=1, y=1, v=0), a = 1/2: flow e1 = 0.5, jump down to k = 0 (u2 >= alpha_1)
#  E2 (0, 1, v1), a = -1/2: the velocity reaches 0 first (clock e = 10): flow T*, stuck, y = 0
#  E3 stuck at k = 0: wait e3 = 0.25, jump down to k = -1 = k_- - 1: s_-, the minus phase
#  E4 (-1, -1, 0), a = -1/2: flow e4 = 0.75, jump up to k = 0 (u2 < alpha_-1)
#  E5 (0, -1, v4), a = 1/2: flow T* to v = 0, stuck (clock e = 10)
#  E6 stuck: wait e6 = 0.3, jump up to k = 1: s_+, the excursion closes.
# The flow with drag kappa and constant a (paper appendices B and E, by hand): v(s) = v0 E + a (1 - E)/kappa,
# x(s) = v0 (1 - E)/kappa + a (kappa s - 1 + E)/kappa^2, E = exp(-kappa s); T* = ln(1 - kappa v0/a)/kappa;
# kappa = 0: v0 + a s, v0 s + a s^2/2, -v0/a.  Evaluated with 60-digit decimals.
_E = [0.5, 10.0, 0.25, 0.75, 10.0, 0.3]
_U2 = {2: [0.5, 0.3, 0.7, 0.55, 0.3, 0.2],  # alpha from 1/2 - c_alpha k: 0.5 >= 0.4 down, 0.55 < 0.6 up
       1: [0.1, 0.3, 0.7, 0.9, 0.3, 0.2]}  # the grid's edges |k| = N = 1: alpha_1 = 0 (down), alpha_-1 = 1 (up)


def _pdmp_by_hand(kappa, rate=2):
    import decimal

    decimal.getcontext().prec = 60
    D, k = decimal.Decimal, decimal.Decimal(kappa)
    r = [-math.expm1(-rate * e) for e in _E]  # the clock uniforms that give the times _E
    e = [-(1 - D(x)).ln() / rate for x in r]

    def flow(v0, a, s):
        if k == 0:
            return v0 + a * s, v0 * s + a * s * s / 2
        E = (-k * s).exp()
        return v0 * E + a * (1 - E) / k, v0 * (1 - E) / k + a * (k * s - 1 + E) / (k * k)

    def t_star(v0, a):
        return -v0 / a if k == 0 else (1 - k * v0 / a).ln() / k

    half = D("0.5")
    v1, x1 = flow(D(0), half, e[0])
    ts2 = t_star(v1, -half)
    _, x2 = flow(v1, -half, ts2)
    v4, x4 = flow(D(0), -half, e[3])
    ts5 = t_star(v4, half)
    _, x5 = flow(v4, half, ts5)
    return r, float(x1 + x2 + x4 + x5), float(e[0] + ts2 + e[2] + e[3] + ts5 + e[5])


@pytest.mark.parametrize("kappa,N", [(0.01, 2), (1e-9, 2), (0.0, 1)])
def test_the_pdmp_worker_runs_one_excursion_by_hand(kappa, N):
    """The scripted PDMP run above against the closed-form flow: U and T of the one excursion to 1e-12, 6
    events, every number drawn.  kappa = 0.01 keeps every |kappa dt| < 0.01 (the series of p2), 1e-9 makes the
    closed form of p2 cancel (which the series avoids), 0 is no viscous term (T* = -v0/a).  Kills: the
    start s_+ with y = 0 (Algorithm 2's erratum); the clock -ln(u)/rate drawn from u (not 1 - u) and
    -ln(u) rate; alpha = 1/2 + c_alpha k; ``u2 > alpha``; the series' z^2 coefficient 1/12; p2 never by its
    series; the displacement's drag term dropped; T* = sig/2 without drag; the events counted as excursions;
    the grid's upper edge ``k > N``; the last event's time added twice.  (Swapping r_+ and r_- in
    ``run_numba_pdmp`` is killed above.)"""
    r, U, T = _pdmp_by_hand(kappa)
    g = _Script([], [x for pair in zip(r, _U2[N]) for x in pair])
    acc = nb._pdmp_worker.py_func(g, 1, 100, N, 0, 0, 1.0, 0.1, 2.0, kappa, -0.5, 0.5)
    assert g.u == []
    got = dict(zip(nb.SUMS, acc[:len(nb.SUMS)]))
    assert got["n"] == 1 and dict(zip(nb.TAIL, acc[len(nb.SUMS):])) == {"steps": 6, "n_truncated": 0, "work": 6}
    assert got["U"] == pytest.approx(U, rel=1e-12) and got["t"] == pytest.approx(T, rel=1e-12)
    assert abs(U) > 0.01 and got["Ut3"] == pytest.approx(U * T**3, rel=1e-12)


def test_the_pdmp_worker_stops_at_its_work_bound():
    """The scripted PDMP run (kappa = 0.01, N = 2) needs 6 events: a bound of 6 lets it finish, 5 stops it
    before E6 (no excursion, E6's two uniforms not drawn).  Kills the bound dropped and ``events <= max_work``."""
    r, _, _ = _pdmp_by_hand(0.01)
    for bound, n, left in ((6, 1, 0), (5, 0, 2)):
        g = _Script([], [x for pair in zip(r, _U2[2]) for x in pair])
        acc = nb._pdmp_worker.py_func(g, 1, bound, 2, 0, 0, 1.0, 0.1, 2.0, 0.01, -0.5, 0.5)
        assert acc[0] == n and acc[nb.STEPS] == acc[nb.WORK] == bound and len(g.u) == left, (bound, acc)
