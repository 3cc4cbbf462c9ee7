r"""Second mutation audit of :mod:`dryfric_jax.pdmp` (after tests/test_pdmp_mutants.py): what the first pass left open.

Mutants (one-line edits of pdmp.py, Q01-Q60, none of the first pass's P01-P74 repeated on purpose; runner and log
in the untracked .mut/ of the audit clone): 60 tried, covering the float32 series cut, the stop time's hit test and
viscous test, the clock, the up probabilities at the reflecting ends and beyond float32 integers, the mode map
Theta, the s_+- flags of both branches, the force's cast, ``advance`` (its displacement, widening, watched set),
``s_plus`` / ``init_state``, ``random_dtype`` / ``draw`` / ``draw_lanes``, the engine flags, ``grid_offsets``
(round / floor / ceil, tolerance), ``pdmp_grid_info``, ``make_pdmp_model``, the brute force and the skeleton.

Killed by the existing tests: 35.  31 by the fast tier (tests/test_pdmp_mutants.py, tests/test_pdmp.py without its
slow and stiff tests, the PDMP tests of tests/test_internals_audit.py); of the 29 left, the 10 a statistical or
paired test could see were run against the slow tier (tests/test_pdmp.py's slow and stiff tests,
tests/test_engine.py::test_pdmp_float32_matches_float64_paired), which killed 4: Q29 (lanes start at s_-: the
stiff test), Q31 (draw's u2 = u1) and Q48 (the brute force moves stuck lanes), both by the brute-force comparison,
and Q32 (draw_lanes' u1 and u2 swapped: the float32/float64 pairing decouples).

Equivalent: 10.  Q07, Q11, Q21 (a cast dropped: flow's operands are already in v's dtype, int32 + a Python int
stays int32, int32 * float promotes to that float with the same int->float rounding); Q14 (the mode after a stop
from kn: kn == k when no jump); Q23, Q24 (dU, dt left in float32: the widening is exact and every reader adds them
to a float64 carry, which promotes); Q36 (cpu_events "wait": a block layout chosen for speed, both valid and both
checked in tests/test_pdmp.py's stiff test); Q45 (1/tau_L without the isinf branch: 1.0/inf is 0.0 in Python);
Q50 (a path finished at T > t_end for T >= t_end: T == t_end, a float64 sum of exponential times, has probability
0); Q52 (the float32 kappa promoted inside the float64 displacement is the value its astype gives).  Q07, Q21, Q23
and Q24 also pass tests/test_engine.py::test_pdmp_float32_matches_float64_paired, run on purpose.

Killed only by this file: 15.  Q04 (a >= 0 a hit sliding down: a NaN T* at v = 0, a = 0), Q10 (alpha_k from
float32(k) on a grid beyond 2^24 points), Q16 / Q17 (s_+- on any jump of a lane stuck at k_+-, inwards too),
Q20 (s_+ on a jump onto x_{k_+ +1} while sliding up), Q28 (s_+'s v always float64: a float32 run in float64),
Q34 (start_regenerated False: lanes seek first), Q35 (regen_after_step False: the landing event counted in the
next cycle), Q37 (int(q_+) for round(q_+): a threshold just below a grid point), Q39 / Q40 (int() for floor /
ceil when |gamma_bar| > 1), Q51 (a block run beyond max_events), Q54 (the skeleton's x not a numpy array), Q56
(the skeleton complete once s_- is reached), Q59 (T* = sigma for kappa below float32's tiny).  Q16, Q17, Q20,
Q28, Q34 and Q35 survived the slow tier too; the other 9 were not run there: they change nothing its parameter
points reach (no |gamma_bar| > 1, no grid of 2^24 points, no threshold just below a grid point, no a = 0 sliding
down, no skeleton cut short or type-checked, no max_events at a block boundary, no kappa below 1.2e-38).

Alive: none.

Defects found in pdmp.py: none.  The brute force and the skeleton are pinned here event by event against the
decimal replay of appendix B from their own uniforms, so any further change of the event chain that keeps the
law but not the numbers now shows.

Oracles: a replay of the event chain in 60-digit ``decimal`` from the paper's appendix B and the module docstring
(nondimensional, Gamma = Delta = 1), fed with the very uniforms the code draws (the uniforms are the input, not the
result): the force at v = 0, :math:`a = x_k + \bar\gamma - y`; the stop time :math:`T^\star = \log(1 +
\kappa\sigma)/\kappa`, :math:`\sigma = -v_0/a`, when :math:`y a < 0`; the noise clock :math:`e = -\log(u_1)/\Lambda`,
:math:`\Lambda = 2/(\tau\delta)^2`; the up probability :math:`\alpha_k = 1/2 - \tau\delta^2 k/4`; the flow
:math:`v(s) = v_0 E + a(1 - E)/\kappa`, :math:`x(s) = v_0(1 - E)/\kappa + a(\kappa s - 1 + E)/\kappa^2`,
:math:`E = e^{-\kappa s}`; the mode :math:`\Theta(x, 0)` after a stop or a jump of a stuck lane; :math:`s_\pm`
hit only by a stuck lane's jump onto :math:`x_{k_\pm \pm 1}` or a stop there (kernel Q).  The thresholds of
section 3.3 (:math:`x_{k_+} \le 1 - \bar\gamma < x_{k_++1}`, :math:`x_{k_--1} < -1 - \bar\gamma \le x_{k_-}`) in
exact ``fractions``; the on-grid tolerance :math:`10^{-9}\max(1, |q|)` steps of the module docstring; the
documented contracts of ``draw_lanes`` (":meth:`draw` of every lane at once ... the same numbers"), of
``pdmp_grid_info`` (delta and L_X in physical units), of the brute force's ``max_events`` (a bound checked
between blocks) and of the engine flags as the engine documents their use (excursions.init_lanes, _book).
"""
import math
from decimal import Decimal, getcontext
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.pdmp import grid_offsets, make_pdmp_model, pdmp_grid_info

from test_pdmp_mutants import DELTA, F64, GBAR, KM, KP, TAU, TAU_L, _D, _step  # the first pass's point and step

getcontext().prec = 60


class Replay:
    """The PDMP of appendix B in 60 digits, event by event, from given uniforms (u1, u2)."""

    def __init__(self, tau, tau_L, gbar, delta, kp, km, N):
        self.tau, self.gbar, self.d = _D(tau), _D(gbar), _D(delta)
        self.kap = Decimal(0) if math.isinf(tau_L) else 1 / _D(tau_L)
        self.rate = 2 / (self.tau * self.d) ** 2
        self.kp, self.km, self.N = kp, km, N
        self.k, self.y, self.v = kp + 1, 1, Decimal(0)  # s_+

    def theta(self, k):
        return 1 if k > self.kp else -1 if k < self.km else 0

    def seg(self, v0, a, s):
        """(v(s), x(s)) while sliding with force a."""
        if self.kap == 0:
            return v0 + a * s, v0 * s + a * s * s / 2
        kap, E = self.kap, (-self.kap * s).exp()
        return v0 * E + a * (1 - E) / kap, v0 * (1 - E) / kap + a * (kap * s - 1 + E) / kap**2

    def event(self, u1, u2):
        """One event: returns (dt, v0, a, y0, to_plus, to_minus); the state moves on."""
        k, y, v = self.k, self.y, self.v
        a = k * self.d + self.gbar - y
        t_star = None
        if y * a < 0:
            sigma = -v / a
            t_star = sigma if self.kap == 0 else (1 + self.kap * sigma).ln() / self.kap
        e = -_D(u1).ln() / self.rate
        if t_star is None or e < t_star:
            assert -self.N < k < self.N  # the replay does not model the reflecting ends: the path must not reach them
            alpha = Decimal("0.5") - self.tau * self.d**2 * k / 4
            kn = k + (1 if _D(u2) < alpha else -1)
            self.v = self.seg(v, a, e)[0] if y != 0 else Decimal(0)
            self.k, self.y = kn, (self.theta(kn) if y == 0 else y)
            return e, v, a, y, y == 0 and kn == self.kp + 1, y == 0 and kn == self.km - 1
        self.v, self.y = Decimal(0), self.theta(k)
        return t_star, v, a, y, y == -1 and k == self.kp + 1, y == 1 and k == self.km - 1


def _model(dtype=F64):
    m = make_pdmp_model(dj.Params.from_nondim(TAU, TAU_L, GBAR), DELTA, dtype)
    assert (int(m.kp), int(m.km)) == (KP, KM)
    return m


def test_a_stuck_lane_that_steps_inwards_is_not_regenerated():
    """Stuck at k_+ = 8 with u2 = 0.9 > alpha_8 = 0.49 the noise steps down to 7: still stuck, not s_+ (only a jump
    onto x_{k_+ +1} is); stuck at k_- = -11 with u2 = 0.1 < alpha_-11 = 0.51375 it steps up to -10: not s_-.
    tests/test_pdmp_mutants.py only steps outwards from k_+.  Kills Q16 / Q17 (s_+- flagged on any jump of a lane
    stuck at k_+- : a regeneration into the stuck set, which breaks the i.i.d. cycles) and Q20 (s_+ flagged on a
    jump onto x_{k_+ +1} while sliding up)."""
    m = _model()
    for k, u2, kn in ((KP, 0.9, KP - 1), (KM, 0.1, KM + 1)):
        alpha = Decimal("0.5") - _D(TAU) * _D(DELTA) ** 2 * k / 4
        assert (_D(u2) < alpha) == (kn > k)
        for watch in (True, False):
            (k1, y1, v1), dU, dt, tp, tm, heads = _step(m, k, 0, 0.0, 0.3, u2, watch)
            assert (k1, y1, v1, dU) == (kn, 0, 0.0, 0.0) and not (tp or tm or heads), (k, watch)
    # and outwards from k_-: s_-, heads when s_- is watched
    (k1, y1, v1), dU, dt, tp, tm, heads = _step(m, KM, 0, 0.0, 0.3, 0.9, False)
    assert (k1, y1, v1, dU) == (KM - 1, -1, 0.0, 0.0) and tm and heads and not tp
    # a lane sliding *up* (v = 0.4 at k = 10, a = 0.13 > 0: no stop) whose noise steps down onto x_{k_+ +1} keeps
    # sliding with v > 0: not s_+ = (x_{k_+ +1}, 1, 0); mirrored onto x_{k_- -1} sliding down
    for k, y, v, u2, kn in ((KP + 2, 1, 0.4, 0.9, KP + 1), (KM - 2, -1, -0.4, 0.1, KM - 1)):
        (k1, y1, v1), dU, dt, tp, tm, heads = _step(m, k, y, v, 0.3, u2, y > 0)
        assert (k1, y1) == (kn, y) and v1 * y > 0 and not (tp or tm or heads), k


def _fr_offsets(delta, gbar):
    """k_+-, r_+- of section 3.3 in exact rationals (no threshold on the grid here)."""
    d, g = Fraction(delta), Fraction(gbar)
    kp, km = math.floor((1 - g) / d), math.ceil((-1 - g) / d)
    assert kp * d <= 1 - g < (kp + 1) * d and (km - 1) * d < -1 - g <= km * d
    return kp, km, float(kp * d + g - 1), float(km * d + g + 1)


@pytest.mark.parametrize("gbar", [-3.0, 3.0, 1.25, -1.25])
def test_thresholds_beyond_zero_by_hand(gbar):
    """|gamma_bar| > 1 puts both thresholds on the same side of x = 0 (the params accept it: grid_size's test runs
    gamma_bar = -3), so q_- > 0 or q_+ < 0, where floor and ceil are not truncation: delta = 0.3, gamma_bar = -3
    gives q_- = 2/0.3 = 6.67, k_- = 7 (int() gives 6); gamma_bar = 3, q_+ = -6.67, k_+ = -7.  Checked against
    section 3.3 in fractions, r_+- to 1e-15.  Kills Q39 / Q40 (int() for floor / ceil)."""
    kp, km, r_p, r_m = grid_offsets(0.3, gbar)
    ekp, ekm, er_p, er_m = _fr_offsets(0.3, gbar)
    assert (kp, km) == (ekp, ekm)
    assert r_p == pytest.approx(er_p, abs=1e-15) and r_m == pytest.approx(er_m, abs=1e-15)
    assert -0.3 < r_p <= 0.0 <= r_m < 0.3


def test_a_threshold_just_below_a_grid_point_is_on_it():
    """q_+ = 4 - 1e-11 steps (gamma_bar = 1e-11 delta, delta = 0.25) is within 1e-9 max(1, 4) steps of x_4: on
    the grid, k_+ = 4 (the nearest point, not int(q_+) = 3) and r_+ = 0; q_- = -4 - 1e-11: k_- = -4, r_- = 0.
    tests/test_internals_audit.py only puts the thresholds 1e-11 above the grid points.  Kills Q37 (int(q_+) for
    round(q_+))."""
    assert grid_offsets(0.25, 1e-11 * 0.25) == (4, -4, 0.0, 0.0)


def test_the_on_grid_tolerance_is_1e_9_steps():
    """Module docstring: a threshold within 1e-9 max(1, |q|) grid steps of a grid point is on it.  At q = +-4 the
    tolerance is 4e-9 steps: 2e-9 steps off (gamma_bar = -2e-9 delta) is on (r = 0), 2e-8 steps off is off (k_- = -3,
    r_+ = -2e-8 delta).  The first test of tests/test_internals_audit.py sits at 1e-11 and 1e-7, two decades from
    the bound on each side.  Re-kills Q41 (1e-10) and Q42 (1e-8), which tests/test_pdmp_mutants.py's
    relative-tolerance test already kills."""
    d = 0.25
    assert grid_offsets(d, -2e-9 * d) == (4, -4, 0.0, 0.0)
    kp, km, r_p, r_m = grid_offsets(d, -2e-8 * d)
    assert (kp, km) == (4, -3) and r_p == pytest.approx(-2e-8 * d, rel=1e-6) and r_p < 0


def test_grid_info_reports_delta_and_reach_in_physical_units():
    """Gamma = 4, Delta = 0.5: delta' = delta sqrt(Gamma)/Delta = 4 delta; ``delta`` is the physical step as
    given, L_X = N delta (docstring: delta, delta', L_X in s^-1/2).  Re-kills Q43 (delta returned nondimensional;
    killed before only through the API's estimates in tests/test_pdmp.py)."""
    p = dj.Params(Gamma=4.0, Delta=0.5, tau=0.3, gamma_bar=0.1)
    g = pdmp_grid_info(p, 0.01)
    assert g["delta"] == 0.01 and g["delta_nd"] == pytest.approx(0.04, rel=1e-15)
    assert g["L_X"] == pytest.approx(g["N"] * 0.01, rel=1e-15)


def test_lanes_start_at_s_plus_in_the_simulation_dtype():
    """init_state(n) = s_plus(n) = (k_+ + 1, +1, 0) for every lane, v in the simulation dtype (PDMPModel: 'simulation
    dtype for v and times'), k and y int32.  Kills Q28 (v of s_+ always float64: a float32 run silently in float64)
    and re-kills Q29 (lanes started at s_-; before, only the stiff test)."""
    for dtype in (jnp.float32, F64):
        m = _model(dtype)
        for state in (m.init_state(3), m.s_plus(3)):
            k, y, v = state
            assert (k.dtype, y.dtype, v.dtype) == (jnp.int32, jnp.int32, dtype)
            assert np.all(np.asarray(k) == KP + 1) and np.all(np.asarray(y) == 1) and np.all(np.asarray(v) == 0)


def test_up_probability_is_exact_on_a_grid_beyond_float32_integers():
    """A grid of 2^25 + 1 points each side is accepted (tau = 1, delta = 2^-22: N = ceil(8/delta) + 1), and alpha_k
    = 1/2 - tau delta^2 k/4 must use k itself: at k = 2^24 + 1 (not a float32 integer), u2 = 1/2 - c (k - 1/2),
    c = 2^-46, is above alpha_k (step down) but below alpha_{k-1}.  Kills Q10 (k rounded to float32 in alpha_k, in a
    float64 model: a step up)."""
    d = 2.0**-22
    m = make_pdmp_model(dj.Params.from_nondim(1.0), d)
    k = 2**24 + 1
    assert int(m.N) == 2**25 + 1 and float(m.c_alpha) == 2.0**-46
    c = Fraction(1, 2**46)
    u2 = Fraction(1, 2) - c * (k - Fraction(1, 2))
    assert float(u2) == u2 and Fraction(1, 2) - c * k < u2 < Fraction(1, 2) - c * (k - 1)
    _, _, (kn, yn, vn), _, _ = m.event((jnp.int32(k), jnp.int32(1), F64(0.5)), (F64(0.3), F64(float(u2))))
    assert int(kn) == k - 1


def test_draw_lanes_is_draw_of_every_lane():
    """``draw_lanes`` docstring: :meth:`draw` of every lane at once, leaves of shape (block, lanes), the same
    numbers; and u1, u2 are two streams (waiting time, jump side), not one.  Re-kills Q32 (u1 and u2 swapped in
    draw_lanes; before, only the slow float32 pairing) and Q31 (u2 = u1 in draw; before, only the slow
    brute-force comparison), in both dtypes."""
    keys = jax.random.split(jax.random.key(3), 3)
    for dtype in (jnp.float32, F64):
        m = _model(dtype)
        lanes = m.draw_lanes(keys, 64)
        assert len(lanes) == 2 and all(u.shape == (64, 3) and u.dtype == dtype for u in lanes)
        for j in range(3):
            u1, u2 = (np.asarray(u) for u in m.draw(keys[j], 64))
            assert np.array_equal(np.asarray(lanes[0])[:, j], u1) and np.array_equal(np.asarray(lanes[1])[:, j], u2)
            assert not np.any(u1 == u2) and np.all((u1 > 0) & (u1 < 1) & (u2 > 0) & (u2 < 1))


def test_no_stop_without_a_force_in_either_mode():
    """hitting_time docstring: +inf when the velocity never reaches 0, 'a of the same sign as y, or a = 0', in both
    modes (tests/test_pdmp.py checks a = 0 only for y = +1): a lane at rest in mode -1 with a = 0 (the force at an
    on-grid k_-) never stops, at any viscosity; neither does one sliding down.  Kills Q04 (a >= 0 counted as a hit
    sliding down: -0/0, a NaN event time)."""
    from dryfric_jax.pdmp import hitting_time

    for kappa in (0.0, 0.5):
        for v, y in ((0.0, -1), (-0.5, -1), (0.0, 1), (0.5, 1)):
            assert float(hitting_time(F64(v), F64(0.0), F64(kappa), jnp.int32(y))) == math.inf, (v, y, kappa)


def test_stop_time_with_a_drag_below_float32_tiny():
    """T* = log(1 + kappa sigma)/kappa for every kappa > 0 the float64 reciprocal can take (module docstring), also
    below float32's tiny 1.2e-38: kappa = 1e-39, v = 1, a = -1e-30 (sigma = 1e30, kappa sigma = 1e-9), by 60-digit
    decimal to 4 eps (T* = sigma would be 5e-10 off).  Kills Q59 (the viscous test against float32's tiny)."""
    from dryfric_jax.pdmp import hitting_time

    kappa, v, a = 1e-39, 1.0, -1e-30
    sigma = -_D(v) / _D(a)
    exact = float((1 + _D(kappa) * sigma).ln() / _D(kappa))
    got = float(hitting_time(F64(v), F64(a), F64(kappa)))
    assert abs(got - exact) <= 4 * np.finfo(float).eps * exact, (got, exact)


def test_skeleton_is_the_event_chain_by_hand():
    """excursion_skeleton(m, key) draws (u1, u2) = uniform(fold_in(key, i), (2,), minval = tiny) for event i: the
    60-digit replay of appendix B from those uniforms gives every event time, noise index, mode, velocity and U
    (to 1e-10 relative over the excursion: float64 roundings accumulate over ~1e3 events), the index of s_- and the
    end at s_+; stopped by ``max_events`` after s_- it is not complete.  tau = 0.5, tau_L = 2, gamma_bar = 0.13,
    delta = 0.2 (Lambda = 200).  Kills Q54 (x not a numpy array) and Q56 (complete once s_- is reached)."""
    from dryfric_jax.pdmp import excursion_skeleton

    d = 0.2
    m = make_pdmp_model(dj.Params.from_nondim(TAU, TAU_L, GBAR), d)
    kp, km = math.floor(Fraction(1 - GBAR) / Fraction(d)), math.ceil(Fraction(-1 - GBAR) / Fraction(d))
    assert (int(m.kp), int(m.km)) == (kp, km)
    key = jax.random.key(5)
    sk = excursion_skeleton(m, key, max_events=20_000)
    assert sk["complete"] and all(isinstance(sk[c], np.ndarray) for c in ("t", "x", "y", "v", "U"))
    n = len(sk["t"]) - 1
    tiny = jnp.finfo(F64).tiny
    us = np.asarray(jax.vmap(lambda i: jax.random.uniform(jax.random.fold_in(key, i), (2,), F64, minval=tiny))(
        jnp.arange(n)))
    rp = Replay(TAU, TAU_L, GBAR, d, kp, km, int(m.N))
    T = U = Decimal(0)
    phase, i_half = 0, -1
    for i in range(n):
        dt, v0, a, y0, tp, tm = rp.event(us[i, 0], us[i, 1])
        T += dt
        if y0 != 0:
            U += rp.seg(v0, a, dt)[1]
        assert (round(sk["x"][i + 1] / d), sk["y"][i + 1]) == (rp.k, rp.y), i
        assert sk["t"][i + 1] == pytest.approx(float(T), rel=1e-10), i
        assert sk["v"][i + 1] == pytest.approx(float(rp.v), rel=1e-9, abs=1e-12), i
        assert sk["U"][i + 1] == pytest.approx(float(U), rel=1e-9, abs=1e-9), i
        if phase == 0 and tm:
            phase, i_half = 1, i + 1
        elif phase == 1 and tp:
            phase = 2
            assert i == n - 1
    assert phase == 2 and sk["i_half"] == i_half and n > 100
    # stopped by max_events between s_- and s_+: the same first events, not complete (docstring)
    part = excursion_skeleton(m, key, max_events=i_half + 1)
    assert not part["complete"] and part["i_half"] == i_half and np.array_equal(part["t"], sk["t"][:i_half + 2])


def test_bruteforce_windows_are_the_event_chain_by_hand():
    """simulate_pdmp_bruteforce: path j of chunk 0 draws its block b as draw(fold_in(split(fold_in(key, 0),
    lanes)[j], b), block).  The 60-digit replay from those uniforms, with U the displacement of the sliding
    segments inside [burn_in, burn_in + t] (stuck segments move nothing) and the events counted until the path
    passes burn_in + t, gives each path's U (to 1e-10 relative) and the total event count exactly.  Float64 and
    float32 models (float32: the uniforms and the model's numbers rounded, so 1e-4).  Re-kills Q48 (stuck segments
    moved; before, only the slow brute-force comparison) and Q49 (the window's start not clipped)."""
    from dryfric_jax.pdmp import simulate_pdmp_bruteforce

    d, t, burn, block, n_paths = 0.2, 1.5, 0.7, 64, 2
    p = dj.Params.from_nondim(TAU, TAU_L, GBAR)
    for dtype, rel in ((F64, 1e-10), (jnp.float32, 1e-4)):
        m = make_pdmp_model(p, d, dtype)
        key = jax.random.key(9)
        U, events, unfinished = simulate_pdmp_bruteforce(m, key, n_paths, t, burn_in=burn, block=block)
        assert unfinished == 0 and U.shape == (n_paths,)
        lane_keys = jax.random.split(jax.random.fold_in(key, 0), n_paths)
        want_events, stuck_time = 0, Decimal(0)
        for j in range(n_paths):
            rp = Replay(TAU, TAU_L, GBAR, float(m.delta), int(m.kp), int(m.km), int(m.N))
            if dtype == jnp.float32:  # the float32 model's own numbers
                rp.d, rp.gbar = _D(m.delta), _D(m.r_p) + 1 - int(m.kp) * _D(m.delta)
            T, Uw, b = Decimal(0), Decimal(0), 0
            lo_t, hi_t = _D(burn), _D(burn) + _D(t)
            while T < hi_t:
                u1s, u2s = (np.asarray(u) for u in m.draw(jax.random.fold_in(lane_keys[j], b), block))
                for i in range(block):
                    if T >= hi_t:
                        break
                    dt, v0, a, y0, _, _ = rp.event(u1s[i], u2s[i])
                    lo, hi = min(max(lo_t - T, 0), dt), min(max(hi_t - T, 0), dt)
                    if y0 != 0:
                        Uw += rp.seg(v0, a, hi)[1] - rp.seg(v0, a, lo)[1]
                    else:
                        stuck_time += hi - lo
                    T += dt
                    want_events += 1
                b += 1
            assert U[j] == pytest.approx(float(Uw), rel=rel, abs=rel * 1e-2), (dtype, j)
        assert events == want_events and stuck_time > Decimal("0.1")  # the window does hold stuck time


def test_bruteforce_stops_once_max_events_is_reached():
    """The work bound is checked between blocks: with max_events = block = 4, every path stops after its first
    block (4 events, unfinished), and with max_events = 5 after its second (8 events).  Kills Q51 (n <= max_events:
    a block beyond the bound)."""
    from dryfric_jax.pdmp import simulate_pdmp_bruteforce

    m = _model()
    for max_events, want in ((4, 4), (5, 8)):
        U, events, unfinished = simulate_pdmp_bruteforce(m, jax.random.key(2), 3, 1.0, max_events=max_events,
                                                         block=4, chunk_lanes=3)
        assert (events, unfinished) == (3 * want, 3), max_events


def test_pdmp_lanes_start_in_an_excursion_and_close_it_with_the_landing_event():
    """The engine interface flags (PDMPModel: 'lanes start at s_+, a regeneration state'; 'the event that lands on
    s_+ or s_- closes the cycle'), through the engine's own documented use of them: fresh lanes are in PLUS at
    s_+ (excursions.init_lanes), and an event that lands on s_+ in MINUS adds its dU and dt to the excursion it
    closes (excursions._book: 'for the PDMP ... it belongs to the cycle it closes'), the next one starting at 0.
    Kills Q34 (start_regenerated False: lanes seek first) and Q35 (regen_after_step False: the landing event
    counted in the next excursion, which shifts the closing segment's U and t between consecutive cycles)."""
    from dryfric_jax import excursions as ex

    m = _model()
    lane = ex.init_lanes(m, 2)
    assert np.all(np.asarray(lane.phase) == ex.PLUS)
    lane = ex._Lane(**{**{f: getattr(lane, f) for f in lane.__dataclass_fields__},
                       "phase": jnp.full((2,), ex.MINUS, jnp.int32), "U": jnp.full((2,), 1.0),
                       "t": jnp.full((2,), 2.0), "n": jnp.full((2,), 5, jnp.int64)})
    adv = (m.s_plus(2), jnp.full((2,), 0.25), jnp.full((2,), 0.5), jnp.array([True, False]))
    out = ex._book(m, jnp.int64(10**6), jnp.int64(10**8), jnp.asarray(False), lane, adv)
    stats = [np.asarray(s) for s in out.stats]
    assert stats[0].tolist() == [1.0, 0.0] and stats[1].tolist() == [1.25, 0.0] and stats[5].tolist() == [2.5, 0.0]
    assert np.asarray(out.phase).tolist() == [ex.PLUS, ex.MINUS]
    assert np.asarray(out.U).tolist() == [0.0, 1.25] and np.asarray(out.t).tolist() == [0.0, 2.5]
