r"""Mutation audit of :mod:`dryfric_jax.pdmp` (the jump-noise PDMP): what tests/test_pdmp.py and the PDMP tests of
tests/test_internals_audit.py left open.

Oracles: single events worked by hand in 60-digit ``decimal`` from the paper's appendix B and the module docstring
(nondimensional, Gamma = Delta = 1): the force at v = 0, :math:`a = x_k + \bar\gamma - y`; the flow with drag
:math:`\kappa = 1/\tau_L` and constant a, :math:`v(s) = v_0 E + a (1 - E)/\kappa` and
:math:`x(s) = v_0 (1 - E)/\kappa + a (\kappa s - 1 + E)/\kappa^2`, :math:`E = e^{-\kappa s}`; the stop time
:math:`T^\star = \log(1 + \kappa\sigma)/\kappa`, :math:`\sigma = -v_0/a`; the noise clock
:math:`e = -\log(u_1)/\Lambda`, :math:`\Lambda = 2/(\tau\delta)^2`; the up probability
:math:`\alpha_k = 1/2 - \tau\delta^2 k/4`; the mode only changes at a stop or when stuck, and only a lane
that was stuck (or stops) on :math:`x_{k_\pm \pm 1}` is at :math:`s_\pm` (kernel Q of appendix B).
Here :math:`\tau = 0.5`, :math:`\tau_L = 2`, :math:`\bar\gamma = 0.13`, :math:`\delta = 0.1`: the thresholds
0.87 and -1.13 are off the grid, :math:`k_+ = 8`, :math:`k_- = -11` (by hand: floor(8.7), ceil(-11.3)).

Mutants (edits of pdmp.py, P01-P74) tried: 74.  The targeted tests (tests/test_pdmp.py without its two slow tests,
and the phi/hitting-time/grid/force/draw tests of tests/test_internals_audit.py) killed 49.  15 are equivalent:
ties of probability 0 (|z| = cut in phi, e = T*, T = t_end twice), the force of a stuck lane (no caller reads it),
the y == -1 / y == 1 of a stop at x_{k_+ +1} / x_{k_- -1} (T* is infinite there in the other mode), floor(q) for
ceil(q) - 1 and the min/max clamps of r_+- off the grid (q is >= 1e-9 steps from an integer there), int64 model
integers (k stays int32), the flow at e for the flow at dt (read only where equal), the brute force's ``live``
guard (the window clips to 0 after t_end), and ``|kappa| > 0`` for ``>= tiny`` in T* (XLA flushes subnormals
to 0).  The tests here kill the other 10 (P33, P36, P42, P48, P55, P69-P73) and re-kill 16 of the 49.  P42 and
P48 (the snap tolerance of grid_offsets without its max(1, |q|) scale, or with |q_+| for |q_-|) were first left
open: the docstrings said "within 1e-9 grid steps", the code 1e-9 max(1, |q|); the docstrings now say what the
code does (a tolerance relative beyond one step, as q's own rounding), and the last test pins it.  The audit also
found the brute force counting a last chunk's discarded lanes (events and unfinished paths; fixed, pinned below).
"""
from decimal import Decimal, getcontext

import jax
import jax.numpy as jnp
import numpy as np

import dryfric_jax as dj
from dryfric_jax.pdmp import make_pdmp_model

getcontext().prec = 60

TAU, TAU_L, GBAR, DELTA = 0.5, 2.0, 0.13, 0.1
KP, KM = 8, -11  # floor((1 - 0.13)/0.1) = floor(8.7), ceil((-1 - 0.13)/0.1) = ceil(-11.3)
F64 = jnp.float64


def _model():
    m = make_pdmp_model(dj.Params.from_nondim(TAU, TAU_L, GBAR), DELTA)
    assert (int(m.kp), int(m.km)) == (KP, KM)
    return m


def _D(x):
    return Decimal(float(x))


def _force(k, y):
    """a = x_k + gamma_bar - y, by hand."""
    return Decimal(k) * _D(DELTA) + _D(GBAR) - Decimal(y)


def _clock(u1):
    """e = -log(u1)/Lambda, Lambda = 2/(tau delta)^2."""
    return -_D(u1).ln() * (_D(TAU) * _D(DELTA)) ** 2 / 2


def _slide(v0, a, s):
    """(v(s), x(s)) of dv/dt = a - kappa v from v0, kappa = 1/tau_L: the closed forms of the docstring."""
    kap = 1 / _D(TAU_L)
    E = (-kap * s).exp()
    return v0 * E + a * (1 - E) / kap, v0 * (1 - E) / kap + a * (kap * s - 1 + E) / kap**2


def _alpha(k):
    return Decimal("0.5") - _D(TAU) * _D(DELTA) ** 2 * k / 4


def _step(m, k, y, v, u1, u2, watch_plus):
    state = (jnp.int32(k), jnp.int32(y), F64(v))
    r = (F64(u1), F64(u2))
    _, _, _, to_plus, to_minus = m.event(state, r)
    (kn, yn, vn), dU, dt, heads = m.advance(state, r, watch_plus)
    return (int(kn), int(yn), float(vn)), float(dU), float(dt), bool(to_plus), bool(to_minus), bool(heads)


def _close(got, want, rel=1e-13):
    assert abs(got - float(want)) <= rel * abs(float(want)), (got, float(want))


def test_a_sliding_segment_cut_by_a_noise_jump_by_hand():
    """Sliding up at k = 12 > k_+ (a = 0.33 > 0: no stop) from v0 = 0.4, u1 = 0.3: the event is the noise jump at
    e = -log(0.3)/800 = 1.505e-3, the lane keeps its mode, v and U follow the closed-form flow, and k steps by
    u2 against alpha_12 = 0.485: u2 = 0.48 up, u2 = 0.4925 (below 1 - alpha_12 = 0.515) down.  Kills P20 (the
    clock -log1p(-u1): the same law, another waiting time for the same u1, as the engine's seeds promise),
    P26 (alpha_k = 1/2 + c k: 0.4925 steps up), P28 (u2 > alpha), P19 and P51 (the rate)."""
    m = _model()
    v0, u1 = Decimal("0.4"), 0.3
    a = _force(12, 1)
    e = _clock(u1)
    v_e, x_e = _slide(v0, a, e)
    assert a > 0 and Decimal("0.48") < _alpha(12) < Decimal("0.4925") < 1 - _alpha(12)
    for u2, kn in ((0.48, 13), (0.4925, 11)):
        (k1, y1, v1), dU, dt, tp, tm, heads = _step(m, 12, 1, 0.4, u1, u2, True)
        assert (k1, y1) == (kn, 1) and not (tp or tm or heads), u2
        _close(dt, e)
        _close(v1, v_e)
        _close(dU, x_e)


def test_a_lane_sliding_onto_the_release_point_is_not_regenerated():
    """A noise jump that lands on x_{k_+ +1} while sliding down (v < 0, mode -1) is not s_+ = (x_{k_+ +1}, 1, 0):
    the lane keeps sliding, with the flow's velocity; mirrored for x_{k_- -1} while sliding up.  (The stop at T*
    far later: T* = log(1 + kappa sigma)/kappa = 0.22 > e.)  tests/test_pdmp.py checks only the stop there.
    Kills P33 and P36 (the ``stuck &`` dropped from the jump branch of to_plus / to_minus: a regeneration in the
    middle of a slide, which breaks the i.i.d. cycles), P31 (the mode of a sliding lane reset at a noise jump)."""
    m = _model()
    u1 = 0.3
    e = _clock(u1)
    for k, y, v0, u2, kn, watch in ((KP + 2, -1, "-0.5", 0.9, KP + 1, True), (KM - 2, 1, "0.5", 0.1, KM - 1, False)):
        a = _force(k, y)
        sigma, kap = -Decimal(v0) / a, 1 / _D(TAU_L)
        assert sigma > 0 and (1 + kap * sigma).ln() / kap > e
        v_e, x_e = _slide(Decimal(v0), a, e)
        (k1, y1, v1), dU, dt, tp, tm, heads = _step(m, k, y, float(v0), u1, u2, watch)
        assert (k1, y1) == (kn, y) and not (tp or tm or heads), (k, y)
        _close(dt, e)
        _close(v1, v_e)
        _close(dU, x_e)


def test_a_stop_at_t_star_by_hand():
    """u1 = 1e-300 puts the noise jump at e = 0.86, after the stop.  Sliding up at k = 3 (a = 0.3 + 0.13 - 1 =
    -0.57) from v0 = 0.2 the lane stops at T* = log(1 + kappa sigma)/kappa = 0.323, sigma = 0.2/0.57, with v
    exactly 0, stuck (k_- <= 3 <= k_+), the noise not moved, and U = x(T*) of the closed form.  Sliding down at
    k = 10 (a = 1 + 0.13 + 1 = 2.13) from v0 = -0.2 it stops in mode +1 (x_10 + gamma_bar = 1.13 > 1), not at
    s_+ (k = 10 != k_+ + 1); at k = 9 = k_+ + 1 the same stop is s_+.  Kills P14 (T* = sigma), P23 (the flow's
    rounding for the exact 0), P61 (sigma of the wrong sign), P32 (the mode after a stop always 0), P37 (s_+ at
    k_+)."""
    m = _model()
    u1, kap = 1e-300, 1 / _D(TAU_L)
    down = Decimal("-0.2")
    for k, y, v0, mode in ((3, 1, Decimal("0.2"), 0), (KP + 2, -1, down, 1), (KP + 1, -1, down, 1)):
        a = _force(k, y)
        sigma = -v0 / a
        t_star = (1 + kap * sigma).ln() / kap
        assert 0 < sigma and t_star < _clock(u1)
        (k1, y1, v1), dU, dt, tp, tm, heads = _step(m, k, y, float(v0), u1, 0.5, True)
        assert (k1, y1, v1) == (k, mode, 0.0) and tp == heads == (k == KP + 1) and not tm, k
        _close(dt, t_star)
        _close(dU, _slide(v0, a, t_star)[1])


def test_a_stuck_lane_moves_nothing_until_the_noise_frees_it():
    """Stuck at k_+ = 8 (y = 0, v = 0), u1 = 0.3, u2 = 0.2 < alpha_8 = 0.49: the event is the noise jump at
    e, onto x_{k_+ +1} = 0.9 with mode +1 and v = 0 (s_+, heads when watched), and the lane moved 0 (U adds
    nothing while stuck).  Stuck at 0 with u2 = 0.9: a jump to -1, still stuck, nothing moved.  Kills P40 (the
    displacement of a stuck lane not zeroed: a 'force' (k - k_-) delta + r_- = 1.93 acts over e), P22 (the
    velocity of a stuck lane not zeroed)."""
    m = _model()
    u1 = 0.3
    e = _clock(u1)
    for k, u2, kn, yn, tp_want in ((KP, 0.2, KP + 1, 1, True), (0, 0.9, -1, 0, False)):
        (k1, y1, v1), dU, dt, tp, tm, heads = _step(m, k, 0, 0.0, u1, u2, True)
        assert (k1, y1, v1) == (kn, yn, 0.0) and dU == 0.0, k
        assert tp == heads == tp_want and not tm
        _close(dt, e)


def test_draw_maps_all_zero_bits_to_the_smallest_uniform(monkeypatch):
    """The waiting time is -log(u1)/Lambda: ``draw`` must ask jax.random.uniform for minval = tiny (so u1 > 0 even
    when the bits are all zero, as ``draw_lanes`` does: tests/test_internals_audit.py), or -log 0 makes an
    infinite event.  jax.random.uniform returns max(minval, f (maxval - minval) + minval), f = 0 for zero bits:
    a stand-in with f = 0 (the documented formula).  Kills P55 (minval dropped from ``draw``)."""
    def zero_bits(key, shape, dtype=F64, minval=0.0, maxval=1.0):
        f = jnp.zeros(shape, dtype)
        return jnp.maximum(jnp.asarray(minval, dtype), f * (maxval - minval) + minval)

    monkeypatch.setattr(jax.random, "uniform", zero_bits)
    for dtype in (jnp.float32, F64):
        m = make_pdmp_model(dj.Params.from_nondim(TAU, TAU_L, GBAR), DELTA, dtype)
        u1, u2 = m.draw(jax.random.key(0), 4)
        assert u1.dtype == dtype and np.all(np.asarray(u1) == np.finfo(dtype).tiny) and np.all(np.asarray(u2) > 0)


def test_bruteforce_chunks_and_work_bound_by_hand():
    """4 paths in chunks of 2 lanes, ``max_events = 1`` checked between blocks of 4 events, over t = 1 tau0 (about
    Lambda = 800 noise jumps, so no path gets there in 4 events): every path runs exactly one block, 4 x 4 = 16
    events, all 4 unfinished (reported, never hidden), and the chunks draw from their own keys (fold_in(key,
    chunk)), so no two paths are equal.  5 paths (the last chunk partly used) give 5 displacements, 5 x 4 = 20
    events and 5 unfinished: the last chunk runs only its path, and no padding lane is counted.  Kills P69 (the partial
    last chunk dropped: 4 paths), P70 (unfinished paths not counted), P71 (lanes counted for events), P72 (every
    chunk on the same keys: path 2 = path 0), P73 (the work bound ignored: ~800 events, all finished), and the
    defect the audit found: the padding lane counted (24 events, 6 of 5 paths unfinished)."""
    from dryfric_jax.pdmp import simulate_pdmp_bruteforce

    m = _model()
    run = lambda n: simulate_pdmp_bruteforce(m, jax.random.key(11), n, 1.0, max_events=1, block=4, chunk_lanes=2)
    U, events, unfinished = run(4)
    assert U.shape == (4,) and events == 16 and unfinished == 4
    assert len(set(U.tolist())) == 4 and np.all(np.isfinite(U))
    U5, events5, unfinished5 = run(5)
    assert U5.shape == (5,) and np.array_equal(U5[:4], U) and (events5, unfinished5) == (20, 5)


def test_the_on_grid_tolerance_is_relative_beyond_one_step():
    """``grid_offsets`` (docstring): a threshold q grid steps from 0 within 1e-9 max(1, |q|) steps of a grid point
    is on it.  gamma_bar = 0.5 and delta = 1.5 / (3e7 + 0.01) put q_- = -1.5/delta = -(3e7 + 0.01), 0.01 steps off
    (tolerance 0.03: on), and q_+ = 0.5/delta = 1e7 + 0.0033 (tolerance 0.01: on); q_+ = 1e7 + 0.02 (delta =
    0.5 / (1e7 + 0.02)) is beyond its 0.01: off, k_+ = floor(q_+) and r_+ < 0.  Kills P42 (the max(1, |q|) scale
    dropped: both off) and P48 (|q_+| for |q_-|: tolerance 0.01 for q_-, off)."""
    from dryfric_jax.pdmp import grid_offsets

    assert grid_offsets(1.5 / (3e7 + 0.01), 0.5) == (10_000_000, -30_000_000, 0.0, 0.0)
    kp, _, r_p, _ = grid_offsets(0.5 / (1e7 + 0.02), 0.5)
    assert kp == 10_000_000 and r_p < 0.0
