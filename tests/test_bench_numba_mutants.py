r"""Mutation audit of :mod:`dryfric_jax.bench_numba` (the benchmark's compiled numba baseline), second round.

Mutated: dryfric_jax/bench_numba.py, one exact one-line replacement per mutant (runner and log: .mut/ of the
audit's clone), across the whole module: the sums of ``_add``, SUMS/TAIL indices, the phase labels, ``generators``,
``_on_threads``, ``_work_each``, ``_finished``, ``sums``, the DI worker (the OU pair, the DI step, the release, the
coin and its set, the phase transitions, the trapezoid, the truncation, the counts), ``run_numba``'s arguments, the
PDMP worker (force, T*, clock, p1/p2 and the series cut, flow, jump rule, grid edges, s_+/s_- detection, phases,
counts) and ``run_numba_pdmp``.

Mutants tried: 114.  Killed by the existing tests: 84 (70 by the bench_numba part of test_bruteforce_mutants.py,
14 more only by test_bench_numba.py; test_bench_mutants.py and test_cli.py run a fake baseline, not this code).
Equivalent: 6 -- the phase labels (0, 2, 1) for (0, 1, 2) (only compared with each other); ``sums`` slicing one
column more (``zip`` stops at SUMS); the trapezoid h V_{n+1} for h (V_n + V_{n+1})/2 (equal over a complete
excursion: it starts and ends at V = 0; truncated ones are not summed); U kept at a truncation (the worker seeks,
and the seek's regeneration resets U before it is used); the stuck branch's velocity v for 0 (a stuck lane's v
is 0 already: it was set so by the stop that stuck it); the PDMP clock ``e <= T*`` for ``e < T*`` (a tie of a
continuous clock with a finite T*, probability 0 but for float64 ties; T* = 0 would need v = 0 against
the force, which no event leaves).
Killed only here: 24 (below, each test names its own).  Alive: 0.  Defects found: none.

What the existing tests missed: ``_finished``'s checks for one worker short by one, the first short worker named,
truncations of workers other than 0 and the warning's stacklevel; ``_work_each``'s ceiling and the 2^62 edge;
max_steps' range; the coin's a2 term and the set's closed upper edge / strict ``<`` (conventions of
``regeneration.SplitSet``); m1 for m2 in the force (invisible at tau' = 1e-5, where m1 and m2 are both ~0); the
PDMP start in the plus phase, an aligned grid (r_+ = 0: a = 0 must not stop the velocity), the closed form of
p2 (the existing scripts keep |kappa dt| < 0.01, the series), the velocity set to 0 at a stop that turns the
slide (s_+ from mode -1), a jump to k_+ inside a stuck band of two sites, and a second arrival at s_- in the minus
phase.

Oracles: the docstrings (``_finished``, ``_work_each``, run_numba's bounds, plan.MAX_STEPS, the series cut of
float64 in pdmp's docstring); regeneration.SplitSet.log_coin / contains and pdmp's event / hitting_time
(a = 0: +inf) as the rules to reproduce; hand arithmetic on scripted generators (a trivial OU pair, h = 1/2,
binary fractions; the PDMP without drag); the closed-form drag flow of appendices B and E in 50-digit decimals.  Every
test runs the workers' plain Python (``py_func``) or fake rows: the file takes ~3 s.
"""
import math

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.di import make_di_model
from dryfric_jax.params import FIG3
from dryfric_jax.plan import default_h
from test_bruteforce_mutants import _Script  # a scripted Generator: the numbers given, in order

nb = pytest.importorskip("dryfric_jax.bench_numba", reason="numba not installed: pip install -e '.[bench]'")
NS = len(nb.SUMS)


def _rows(*rows):
    """Workers' rows from (excursions, steps, truncated, work): the other sums 0."""
    return np.array([[n] + [0.0] * (NS - 1) + [s, t, w] for n, s, t, w in rows])


# ---------------------------------------------------------------- _finished: the run's checks of the rows
def test_one_worker_one_excursion_short_stops_the_run_naming_it():
    """7 excursions on 3 workers: each owes ceil(7/3) = 3.  Worker 1 ran 2 (one short, the others 3): the run
    raises ``BaselineIncomplete`` naming worker 1, its 2 of 3 and "1 of 3 workers", the rows kept.  Kills the
    short test ``< n_each - 1``, a run stopped only when more than one worker is short, and the floor share
    (7 // 3 = 2) in ``_finished``."""
    out = _rows((3, 10, 0, 100), (2, 9, 0, 100), (3, 11, 0, 100))
    with pytest.raises(nb.BaselineIncomplete, match=r"worker 1 reached its work bound of 100 steps after 2 of its 3 "
                       r"excursions \(1 of 3 workers stopped short") as e:
        nb._finished(out, 7, 3, 100, "DI", "steps")
    assert e.value.rows is out


def test_the_first_short_worker_is_named():
    """Workers 1 and 2 short: the message names the first (worker 1) and says 2 of 3 stopped.  Kills
    ``short[-1]``."""
    out = _rows((3, 10, 0, 50), (1, 9, 0, 50), (0, 11, 0, 50))
    with pytest.raises(nb.BaselineIncomplete, match=r"worker 1 .* after 1 of its 3 .*\(2 of 3 workers"):
        nb._finished(out, 7, 3, 50, "PDMP", "events")


def test_a_truncation_in_any_worker_is_reported_with_the_total_count():
    """One excursion truncated, in worker 1 only (worker 0 none): a ``DryfricWarning`` says "1 excursions
    reached max_steps"; the useful steps returned are the STEPS column's sum (40 + 2).  Kills the count read
    from worker 0 only, a warning only for more than one, and the count read from the steps column."""
    out = _rows((2, 40, 0, 60), (2, 2, 1, 60))
    with pytest.warns(dj.DryfricWarning, match=r"^numba DI baseline: 1 excursions reached max_steps"):
        got, steps = nb._finished(out, 4, 2, 60, "DI", "steps")
    assert got is out and steps == 42


def test_the_truncation_warning_points_at_the_caller_of_run_numba(monkeypatch):
    """``stacklevel=3``: the warning is attributed to the code that called ``run_numba`` (this file), not to
    the package.  The workers are faked (one truncation).  Kills ``stacklevel=2``."""
    monkeypatch.setattr(nb, "_on_threads", lambda worker, seed, threads, n, args: _rows((1, 5, 1, 9), (1, 5, 0, 9)))
    p = dj.Params(**FIG3)
    with pytest.warns(dj.DryfricWarning, match="1 excursions reached max_steps") as rec:
        nb.run_numba(make_di_model(p, default_h(p)), 2, 2, 0)
    assert [r.filename for r in rec] == [__file__]


# ---------------------------------------------------------------- bounds
def test_the_work_bound_is_split_by_ceiling_and_2_62_itself_is_allowed():
    """``ceil(max_work / threads)``, at most 2^62 (the docstring): 1001 on 2 threads gives 501 each, 1000 on 3
    gives 334; 2^62 is accepted (2^61 each), the next float above is refused.  Kills the floor share and
    ``max_work >= 2^62``."""
    assert nb._work_each(2, 1001) == 501 and nb._work_each(3, 1000) == 334 and nb._work_each(1, 1000) == 1000
    assert nb._work_each(2, 2.0**62) == 2**61
    with pytest.raises(ValueError, match="max_work"):
        nb._work_each(2, math.nextafter(2.0**62, math.inf))


@pytest.mark.parametrize("max_steps", [0, -1, 2**62 + 1])
def test_max_steps_out_of_range_is_named(max_steps):
    """max_steps must be an integer in [1, 2^62] (plan.MAX_STEPS), refused before a worker starts.  The work bound
    is small, so a mutant that lets 0 through stops in milliseconds (``BaselineIncomplete``, not the
    ``ValueError``).  Kills the lower bound 0 and the upper bound dropped."""
    p = dj.Params(**FIG3)
    with pytest.raises(ValueError, match="max_steps"):
        nb.run_numba(make_di_model(p, default_h(p)), 10, 2, 0, max_steps=max_steps, max_work=1e3)


# ---------------------------------------------------------------- the DI worker's splitting coin, one step
def _first_step_regenerates(x0, z1, z2, u, P):
    r"""One step of the DI worker (max_work = 1) from (x0, V = 0), seeking: h = 1/2, no bias, no viscous term, the
    OU pair trivial (m1 = m2 = 0, L = I), so Xi = z1 and w = z1/2.  With z1 > 1, V' > 0: released upwards, so
    the coin of C_+ = P = (c1, c2, a1, a2, a_sq) is flipped when x0 is in [c1, c2]:
    :math:`\log r = \min(-d_1 z_a - d_1^2 a_{sq}/2, -d_2 z_a - d_2^2 a_{sq}/2)`, :math:`z_a = a_1 z_1 + a_2 z_2`,
    d = x0 - c (regeneration.SplitSet.log_coin), heads when log u < log r.  Heads starts an excursion with this
    step: 1 useful step; tails (or no coin) leaves the worker seeking: 0.  Every number given must be drawn."""
    g = _Script([z1, z2], [] if u is None else [u])
    acc = nb._worker.py_func(g, 1, 100, 1, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, np.array(P, float),
                             np.array([-1.5, -0.5, 1.0, 1.0, 2.0]), float(x0))
    assert g.z == [] and g.u == [] and acc[nb.WORK] == 1 and acc[0] == 0
    return {1.0: True, 0.0: False}[acc[nb.STEPS]]


CP = [0.5, 1.5, 1.0, 1.0, 2.0]  # C_+ = [0.5, 1.5], a = (1, 1), a_sq = 2


def test_the_coin_uses_both_normals_with_their_own_weights():
    """x0 = 1 (d = +-1/2), z = (4, -1): z_a = 3, log r = min(-1.5 - 0.25, 1.5 - 0.25) = -1.75: log u = -2.25
    heads, -1.5 tails.  Kills ``z1 a1 - z2 a2`` (log r = -2.75: tails), z2 for z1 in z_a (z_a = -2, log r =
    -1.25: heads at -1.5), d1's sign flipped (log r = 1.25) and the quadratic term's sign flipped (-1.25)."""
    assert _first_step_regenerates(1.0, 4.0, -1.0, math.exp(-2.25), CP)
    assert not _first_step_regenerates(1.0, 4.0, -1.0, math.exp(-1.5), CP)


def test_the_coin_takes_the_smaller_of_the_two_edges_terms():
    """x0 = 1, z = (4, -6): z_a = -2, the c1 term 1 - 0.25 = 0.75, the c2 term -1 - 0.25 = -1.25 (the min):
    log u = -1 tails, -1.5 heads.  Kills the c2 term's square written d1 d2 (-1 + 0.25 = -0.75: heads at -1)."""
    assert not _first_step_regenerates(1.0, 4.0, -6.0, math.exp(-1.0), CP)
    assert _first_step_regenerates(1.0, 4.0, -6.0, math.exp(-1.5), CP)


def test_the_set_is_closed_at_its_upper_edge_as_the_engines():
    """x0 = c2 = 1.5 is in C_+ (``SplitSet.contains``: c1 <= x <= c2): d = (1, 0), z = (4, -4), z_a = 0, log r =
    min(-1, 0) = -1; log u = -2: heads.  Kills ``S[0] <= X < S[1]`` (no coin: the uniform is not drawn; an edge
    of probability 0 for the real normals, but the engine's convention)."""
    assert _first_step_regenerates(1.5, 4.0, -4.0, math.exp(-2.0), CP)


def test_heads_is_strictly_log_u_below_log_r():
    """log r made exactly log(1/4): x0 = c2 = 1.5 (d = (1, 0)), a = (1, 0), a_sq = 0, z1 = -log(1/4) (w = 0.69:
    released upwards), so the c1 term is -z1 = log(1/4) and the c2 term 0.  u = 1/4: log u = log r, tails
    (the engine: ``log u < log r``), u a little smaller: heads.  Kills ``<=`` (an equality of probability ~0 for
    real draws: the engine's convention)."""
    L = math.log(0.25)
    P = [0.5, 1.5, 1.0, 0.0, 0.0]
    assert not _first_step_regenerates(1.5, -L, 0.5, 0.25, P)
    assert _first_step_regenerates(1.5, -L, 0.5, math.nextafter(0.25, 0.0), P)


# ---------------------------------------------------------------- the PDMP worker, scripted
def _uniforms(events):
    """The (clock, step) uniforms of events given as (exponential time, step uniform), rate 2: the clock
    time is -log(1 - r)/2, so r = 1 - exp(-2 e)."""
    return [x for e, u2 in events for x in (-math.expm1(-2.0 * e), u2)]


def test_the_pdmp_worker_starts_in_the_plus_phase():
    """Grid x_k = k, k_+ = k_- = 0, r_+ = -1/2, r_- = 1/2, c_alpha = 0.1, rate 2, no viscous term.  From s_+ =
    (k 1, y 1, v 0): E1 a = 1/2, the clock (0.5) first, u2 = 0.5 >= alpha_1 = 0.4: down to k = 0, still sliding;
    E2 a = -1/2, v = 1/4 reaches 0 at T* = 1/2 (the clock 10 later): stuck at k = 0; E3 stuck, clock 0.25, u2 =
    0.3 < alpha_0 = 0.5: up to k = 1 = k_+ + 1, s_+ again, without passing s_-: no excursion ends (the long
    excursion is s_+ -> s_- -> s_+).  3 events, 0 excursions.  Kills the start in the minus phase (one excursion
    counted here)."""
    g = _Script([], _uniforms([(0.5, 0.5), (10.0, 0.3), (0.25, 0.3)]))
    acc = nb._pdmp_worker.py_func(g, 1, 3, 2, 0, 0, 1.0, 0.1, 2.0, 0.0, -0.5, 0.5)
    assert g.u == [] and acc[0] == 0 and acc[nb.STEPS] == acc[nb.WORK] == 3


def test_the_pdmp_worker_on_an_aligned_grid_slides_on_with_no_force():
    """A threshold on the grid (``grid_offsets``: r_+ = 0): k_+ = k_- = 0, r_+ = r_- = 0.  E1 from s_+ (a = 1),
    clock 0.5, down to k = 0 with v = 1/2, still in mode +1: there a = 0 (``hitting_time``: never stops, +inf),
    so E2 is the clock's (0.25), v unchanged, u2 = 0.7 >= 0.5: down to k = -1; E3 a = -1: v = 1/2 stops at
    T* = 1/2, k = -1 = k_- - 1 in mode +1: s_-.  No excursion closes; 3 events.  Kills ``a <= 0`` for the
    velocity's stop (-v/0 at a = 0: ZeroDivisionError)."""
    g = _Script([], _uniforms([(0.5, 0.5), (0.25, 0.7), (10.0, 0.3)]))
    acc = nb._pdmp_worker.py_func(g, 1, 3, 2, 0, 0, 1.0, 0.1, 2.0, 0.0, 0.0, 0.0)
    assert g.u == [] and acc[0] == 0 and acc[nb.STEPS] == acc[nb.WORK] == 3


# A whole long excursion of the PDMP worker with the viscous term kappa = 0.1 (the grid and rates as above):
#  E1 s_+ (k 1, y 1, v 0), a = 1/2: clock 0.5, u2 = 0.5 >= alpha_1 = 0.4: down to k = 0, sliding
#  E2 (0, 1, v1), a = -1/2: v reaches 0 at T* (clock 10): stuck at k = 0
#  E3 stuck: clock 0.25, u2 = 0.7 >= alpha_0: down to k = -1 = k_- - 1: s_-, the minus phase
#  E4 (-1, -1, 0), a = -1/2: clock 0.75, u2 = 0.55 < alpha_-1 = 0.6: up to k = 0, sliding
#  E5 (0, -1, v4), a = 1/2: v reaches 0 at T* (clock 10): stuck
#  E6 stuck: clock 0.3, u2 = 0.2 < alpha_0: up to k = 1: s_+, the excursion (U, T) closes.
# kappa dt is 0.05, 0.075 and ~0.02-0.04 at the flows: above the float64 series cut 0.01 (pdmp's docstring), where the
# worker's p2 is its closed form; the series there (7 terms) is off by ~z^6/8! ~ 1e-11 relative.
_EXC = [(0.5, 0.5), (10.0, 0.3), (0.25, 0.7), (0.75, 0.55), (10.0, 0.3), (0.3, 0.2)]


def _excursion_by_hand(kappa):
    """(U, T) of the script above from the closed-form flow with drag kappa and constant force a (paper appendix
    C): v(s) = v0 E + a (1 - E)/kappa, x(s) = v0 (1 - E)/kappa + a (kappa s - 1 + E)/kappa^2, E = exp(-kappa s);
    T* = ln(1 - kappa v0/a)/kappa; in 50-digit decimals, the clock times from the very uniforms the worker gets."""
    import decimal

    decimal.getcontext().prec = 50
    D, k = decimal.Decimal, decimal.Decimal(kappa)
    e = [-(1 - D(r)).ln() / 2 for r in _uniforms(_EXC)[::2]]

    def flow(v0, a, s):
        E = (-k * s).exp()
        return v0 * E + a * (1 - E) / k, v0 * (1 - E) / k + a * (k * s - 1 + E) / (k * k)

    half = D("0.5")
    v1, x1 = flow(D(0), half, e[0])
    t2 = (1 - k * v1 / -half).ln() / k
    _, x2 = flow(v1, -half, t2)
    v4, x4 = flow(D(0), -half, e[3])
    t5 = (1 - k * v4 / half).ln() / k
    _, x5 = flow(v4, half, t5)
    return float(x1 + x2 + x4 + x5), float(e[0] + t2 + e[2] + e[3] + t5 + e[5])


def test_the_pdmp_worker_above_the_series_cut_is_the_closed_form_flow():
    """The scripted excursion above at kappa = 0.1 against the 50-digit closed form: U and T to 1e-13 (the
    worker's float64 rounding is ~1e-15 there), 6 events.  Kills the series used up to |z| < 0.1 (U off by
    ~1e-11; float64's cut is 0.01, pdmp's docstring)."""
    U, T = _excursion_by_hand(0.1)
    g = _Script([], _uniforms(_EXC))
    acc = nb._pdmp_worker.py_func(g, 1, 100, 2, 0, 0, 1.0, 0.1, 2.0, 0.1, -0.5, 0.5)
    assert g.u == [] and acc[0] == 1 and acc[nb.STEPS] == acc[nb.WORK] == 6
    assert abs(acc[1] - U) <= 1e-13 * abs(U) and abs(acc[5] - T) <= 1e-13 * T, (acc[1], U, acc[5], T)


def _two_steps(z, u):
    """Two steps of the DI worker from (1, 0), seeking, as :func:`_first_step_regenerates` but with the OU pair's
    mean factors m1 = 0.3 (the force: Xi = 0.3 X + z1) and m2 = 0.6 (the next X = 0.6 X + z2).  Step 1 with z =
    (0, 0): Xi = 0.3, w = 0.15 < h: stuck, no coin, the next X = 0.6 (in C_+ = [0.5, 1.5]).  Returns the useful
    steps (1: step 2 regenerated); every number given must be drawn."""
    g = _Script([0.0, 0.0, *z], u)
    acc = nb._worker.py_func(g, 1, 100, 2, 0.5, 0.0, 0.0, 0.3, 0.6, 1.0, 0.0, 1.0, np.array(CP),
                             np.array([-1.5, -0.5, 1.0, 1.0, 2.0]), 1.0)
    assert g.z == [] and g.u == [] and acc[nb.WORK] == 2
    return acc[nb.STEPS]


def test_the_ou_pair_uses_m1_for_the_force_and_m2_for_the_next_x():
    """Step 2 from X = 0.6: z = (4, 0): Xi = 4.18, V' = 1.59 released upwards in C_+: z_a = 4, d = (0.1, -0.9),
    log r = min(-0.41, 2.79) = -0.41; log u = -1: heads.  z = (0.75, 0): Xi = 0.93, w = 0.465 < h: stuck, no
    coin.  Kills m1 for m2 in the next X (X = 0.3, outside C_+: no coin) and m2 for m1 in the force (Xi =
    1.11: released, a coin the script has no uniform for)."""
    assert _two_steps((4.0, 0.0), [math.exp(-1.0)]) == 1
    assert _two_steps((0.75, 0.0), []) == 0


# Two long excursions of the PDMP worker, no viscous term (kappa = 0: v' = v + a s, dU = v s + a s^2/2, T* = -v/a;
# hand arithmetic in binary fractions), the grid and rates as above.  (k, y, v) at the start; U after the event.
#  E1  (1, 1, 0)       a = 1/2, clock 1/2, u2 = .5: down to 0, v = 1/4              U = 1/16
#  E2  (0, 1, 1/4)     a = -1/2: stops at T* = 1/2 (clock 10): stuck                  U = 1/8
#  E3  stuck           clock 1/4, u2 = .7: down to -1: s_-                             U = 1/8
#  E4  (-1, -1, 0)     a = -1/2, clock 1/2, u2 = .3 < .6: up to 0, v = -1/4            U = 1/16
#  E5  (0, -1, -1/4)   a = 1/2, clock 1/4 < T* = 1/2, u2 = .3: up to 1, v = -1/8        U = 1/64
#  E6  (1, -1, -1/8)   a = 3/2: stops at T* = 1/12 at k = k_+ + 1 in mode -1: s_+ (v = 0) U = 1/96: closes, T = 25/12
#  E7  (1, 1, 0)       a = 1/2, clock 1, u2 = .5: down to 0, v = 1/2                   U = 1/4
#  E8  (0, 1, 1/2)     a = -1/2: stops at T* = 1: stuck                               U = 1/2
#  E9  stuck           clock 1/4, u2 = .7: down to -1: s_-
#  E10 (-1, -1, 0)     a = -1/2, clock 1/2, u2 = .3: up to 0, v = -1/4                 U = 7/16
#  E11 (0, -1, -1/4)   a = 1/2: stops at T* = 1/2: stuck                              U = 3/8
#  E12 stuck           clock 0.3, u2 = .2: up to 1: s_+, closes (3/8, 3.55).
_TWO = [(0.5, 0.5), (10.0, 0.3), (0.25, 0.7), (0.5, 0.3), (0.25, 0.3), (10.0, 0.3),
        (1.0, 0.5), (10.0, 0.3), (0.25, 0.7), (0.5, 0.3), (10.0, 0.3), (0.3, 0.2)]


def test_the_pdmp_worker_stops_to_zero_velocity_where_the_slide_turns():
    """The script above: E6 stops a downward slide at k_+ + 1, where the force turns it upwards: the state is s_+
    with v = 0 (pdmp's event: the velocity is 0 after a stop), so E7 starts from rest.  The sums of (1/96, 25/12)
    and (3/8, 3.55) to 1e-12, 12 events.  Kills the velocity kept (not 0) after a stop (E7 from v = -1/8:
    the second excursion's U = 0.140625)."""
    g = _Script([], _uniforms(_TWO))
    acc = nb._pdmp_worker.py_func(g, 2, 100, 2, 0, 0, 1.0, 0.1, 2.0, 0.0, -0.5, 0.5)
    assert g.u == [] and acc[nb.STEPS] == acc[nb.WORK] == 12
    exc = [(1 / 96, 25 / 12), (3 / 8, 3.55)]
    want = [2, sum(U for U, _ in exc), sum(U * U for U, _ in exc), sum(t for _, t in exc), sum(U * t for U, t in exc)]
    assert [acc[i] for i in (0, 1, 2, 5, 9)] == pytest.approx(want, rel=1e-12)


def test_the_minus_phase_ends_only_at_s_plus():
    """The first script's E1-E3 (s_+ -> stuck -> s_-, the minus phase), then E4 from s_- up to k = 0 sliding
    (clock 1/2, u2 = .3 < alpha_-1), E5 stops there (T* = 1/2): stuck, E6 down to s_- again (u2 = .7): a second
    arrival at s_- ends nothing.  6 events, 0 excursions.  Kills an excursion closed at s_- in the minus phase."""
    g = _Script([], _uniforms([(0.5, 0.5), (10.0, 0.3), (0.25, 0.7), (0.5, 0.3), (10.0, 0.3), (0.3, 0.7)]))
    acc = nb._pdmp_worker.py_func(g, 1, 6, 2, 0, 0, 1.0, 0.1, 2.0, 0.0, -0.5, 0.5)
    assert g.u == [] and acc[0] == 0 and acc[nb.STEPS] == acc[nb.WORK] == 6


def test_a_jump_within_the_stuck_band_stays_stuck():
    """A band of two stuck sites: k_+ = 1, k_- = 0 (r_+ = -1/2, r_- = 1/2, N = 3: alpha_k = 1/2 - k/10).  E1 from
    s_+ = (2, 1, 0), a = 1/2, clock 1/2, u2 = .7: down to 1, sliding; E2 a = -1/2: stops at 1 (in [k_-, k_+]):
    stuck; E3 (u2 = .7) down to 0, E4 (u2 = .3) up to 1 = k_+: still stuck (theta(k_+) = 0); E5 down to 0, E6 down
    to -1: s_-; E7 from s_- (a = -1/2) up to 0 sliding, E8 stops there: stuck; E9 up to 1, E10 up to 2: s_+, the
    excursion closes: 1 excursion in 10 events.  Kills ``kn >= k_+`` for sliding up after a jump (at E4 the lane
    slides from k_+ against the force, stops at once, and never reaches s_- in the 10 events)."""
    ev = [(0.5, 0.7), (10.0, 0.3), (0.25, 0.7), (0.25, 0.3), (0.25, 0.7), (0.25, 0.7), (0.5, 0.3), (10.0, 0.3),
          (0.25, 0.3), (0.25, 0.3)]
    g = _Script([], _uniforms(ev))
    acc = nb._pdmp_worker.py_func(g, 1, 10, 3, 1, 0, 1.0, 0.1, 2.0, 0.0, -0.5, 0.5)
    assert g.u == [] and acc[0] == 1 and acc[nb.STEPS] == acc[nb.WORK] == 10
