r"""The paper's mean long-excursion duration for the DI, by counting releases (Fig. 3, right panel).

The D estimator's cycles end at Nummelin regenerations (:mod:`dryfric_jax.regeneration`), each one or
more of the paper's long excursions, so their mean duration is not the paper's.  The paper's
(section 6.1): a +HLE starts when the stuck particle is released at :math:`x_{\Delta}` (towards
:math:`V > 0`) and ends at the first release at :math:`x_{-\Delta}` (towards :math:`V < 0`), the -HLE
back again; a long excursion is a +HLE and a -HLE.  In continuous time a release happens only where
X crosses a threshold, so an HLE ends exactly where the *direction of release changes*, and the
state there, :math:`(x_{\mp\Delta}, 0)`, is the same every time: the HLEs after the first change of
direction are independent, alternating + and -.

Here each lane runs the DI chain (:meth:`~dryfric_jax.di.DIModel.move`; noise stationary,
:math:`V_0 = 0`) and counts releases (:math:`V_{n-1} = V_n = 0 \ne V_{n+1}`: stuck a whole step,
then moving) whose direction differs from the previous release's.  Its first such change starts a long
excursion (LE); every second change after it ends one and starts the next, so the lane runs LE after LE and
adds each one's duration :math:`d` (in steps) to its sums :math:`N, \sum d, \sum d^2`.

**When the lanes stop (unbiased under a stopping rule).**  After each block of 128 steps the loop checks the
lanes' total :math:`\sum N`; from the block where it reaches ``n_excursions`` on, a lane starts no new LE: it
finishes the one in flight, then counts nothing more (a lane that has not started one stops at once).  Whether an LE
is counted is thus decided when it starts, before its duration is drawn, so by Wald's identity
:math:`E\sum d = \mu\,E\sum N` with :math:`\mu` the mean LE duration, and the ratio

.. math::
    \hat\mu = h\,\frac{\sum d}{N}, \qquad \text{95\% CI } t_{N-1}\,\frac{h\,s_d}{\sqrt N}

over the :math:`N` LEs of all lanes is consistent (its bias is :math:`O(1/N)`; :math:`s_d` their sample sd,
Student's quantile :func:`~dryfric_jax.estimators.t_quantile`).  Stopping at a horizon and dropping the LEs
in flight there instead would leave out the long ones: -32% at a horizon of 3 mean durations (``RESULTS.md``,
``tests/test_durations.py``).  The old design (each lane a fixed number of LEs) was exactly unbiased but idled
its finished lanes until the slowest was done: 1.1-1.9x more wall time per LE on 2 CPU cores (``RESULTS.md``).
The LEs are i.i.d. in continuous time (each starts at :math:`(x_{\pm\Delta}, 0)`); in discrete time X overshoots
the threshold a little, and the spread of the lanes' ratios matched the pooled :math:`s_d` (tested).
Measured at Gamma = 10, tau = 0.125 s, the D estimator's h, 1000 replicates each against 0.44218 +- 0.00042 s (SE;
1,048,849 LEs; ``scripts/duration_coverage.py``, bridged count, 0.2.10): coverage 0.932 +- 0.008, 0.943 +- 0.007,
0.946 +- 0.007 and bias -0.6 +- 0.4%, -0.27 +- 0.25%, +0.05 +- 0.07% for 32 (Fig. 3's floor; 63 counted on average,
in 32 lanes), 128 (163 counted) and 2048 (2330) asked: the durations are right-skewed, so a few dozen LEs cover a
little less than 95%, and below :data:`MIN_RELIABLE_LE` counted a :class:`~dryfric_jax.SmallSampleWarning` says
so.  (0.2.9's uniforms: 0.921, 0.940, 0.942; the raw count of 0.2.8: 0.939, 0.936, 0.951.)

**Crossings between steps (the bridge correction, version 0.2.9).**  The chain sees X only at its steps, and a
stuck particle moves only where a step's mean force :math:`\Xi_n` passes a threshold, so it finds a change of
direction late: between two steps X can pass the opposite threshold and come back, which in continuous time is a
release.  Counted raw, the mean duration's bias falls like :math:`\sqrt h` (a discretely monitored barrier;
Broadie, Glasserman and Kou 1997): at Gamma = 10, tau = 0.125 s 0.533, 0.479, 0.452 s (+- 0.0025) at h, h/4,
h/16 (h the D estimator's default, tau/h = 187), +23%, +11%, +4% against the bridged count's 0.433 at h/16.  So
at a step where the particle stays put (:math:`V_n = V_{n+1} = 0`) after a release in direction :math:`s`, the
count also takes a release towards the opposite threshold :math:`a` (:math:`x_{-\Delta}` for :math:`s = +`,
:math:`x_{\Delta}` for :math:`s = -`) with the probability that a Brownian bridge from :math:`X_n` to
:math:`X_{n+1}` with the step's variance crossed it,

.. math::
    p_n = \exp\Big(-\frac{2\,d_n d_{n+1}}{\operatorname{Var}(X_{n+1}\mid X_n)}\Big), \qquad
    \operatorname{Var}(X_{n+1}\mid X_n) = \frac{1 - e^{-2h/\tau}}{\tau},

with :math:`d_n, d_{n+1}` the distances of :math:`X_n, X_{n+1}` inside :math:`a` (:math:`p_n = 1` where either
is beyond it), from one uniform per step, independent of the step's two normals
(:func:`~dryfric_jax.rng.normals_and_spare`: in float32 18 low bits that the normals leave unused, so the bridge
hashes nothing more; in float64, whose pair reads all 64 bits of its hash since 0.3.0, 52 bits of one more hash
per step), so the chain's path is the raw count's, step for step (0.2.10; 0.2.9 drew the uniform from another
key; since 0.2.11 it is a cell's midpoint, never 0, which at Fig. 3's point changed one LE in 33 000 in float32:
4.0132 against 4.0133 s).  The chain (X, V) itself is not changed: such a release would
move the particle by :math:`O(h^{3/2})`.  The bias then falls like h: at that point 0.4413, 0.4378, 0.4345,
0.4326 s at h, h/2, h/4, h/16 (+- 0.0016: 0.2.9's and 0.2.10's runs of 131 072 LEs each, independent, pooled),
+2.0%, +1.2% and +0.4% against h/16; the PDMP, an independent method, gives 0.4405 and 0.4376 (+- 0.0023) at
delta = 0.0625 and 0.03125, falling by 0.0029 per halving of delta.  The bias shrinks as tau/h grows (and as
Gamma falls): at Gamma = 10, tau = 0.25 s (tau/h = 373 at h) 0.8354 and 0.8355 (+- 0.0033) at h and h/4; at
Fig. 3's point (746) 4.035, 4.030, 4.028 s (+- 0.013) at h, h/2, h/4; at Gamma = 2.15, tau = 0.125 s 0.6807 and
0.6785 (+- 0.0033) at h and h/4 (pooled the same way).  The default step is therefore
:math:`\min(h_D, \tau/\text{TAU\_STEPS})` (:func:`default_duration_h`), :math:`h_D` the D estimator's,
:data:`TAU_STEPS` = 700: a bias of ~0.5% at most over Fig. 3's grid (its worst point, Gamma = 10, tau = 0.125 s,
at h/3.7), where its CIs are 1.2-2.1%.  The bridge's arithmetic makes a step ~1.4x as dear as the raw count's
(51 against 73 M lane-steps/s at Fig. 3's point, 256 lanes, 2 CPU cores, medians of 5), which ran at h/8 for a
bias of a few % (0.2.8).  (All +- here are 95% CIs; tau, h nondimensional in the variance.)

**Fast noise: the step against the stuck band (version 0.3.1).**  The bias is a function of :math:`q =
\operatorname{Var}(X_{n+1}\mid X_n) = (1 - e^{-2h/\tau})/\tau'` (:func:`step_band_variance`), X's variance over one
step against the stuck band's half-width squared (nondimensional X: the band is :math:`[-1 - \bar\gamma', 1 -
\bar\gamma']`), not of tau/h: the mean is about :math:`\mu_0 (1 + c\,q)`, fitted over q <= 0.38
(``scripts/duration_step_bias.py``; Gamma = Delta = 1, tau_L = inf, gamma_bar = 0, 4 000-21 000 LEs a point, seeds
1-3) with c = 0.34 +- 0.09, 0.25 +- 0.09 and 0.31 +- 0.17 at tau' = 0.1, 0.03 and 0.01 (tau/h 53 to 4300), and ~0.35
at Fig. 3's worst point (+2.0% at q = 0.058).  Were it a function of tau/h, c would fall tenfold from tau' = 0.1 to
0.01.  At tau' = 0.184 (Gamma = 10, tau = 0.125 s) tau/ :data:`TAU_STEPS` gives q = 0.0155, but q grows like 1/tau'
at a fixed tau/h: tau/700 made the count +3% long at tau' = 0.03 (3.42 +- 0.07 against 3.32 +- 0.05 extrapolated),
+5% +- 6% at 0.01 (5.38 +- 0.24 against 5.11 +- 0.21, q = 0.29; +9% by the fit), and 10.1 +- 1.1 tau0 at 0.003 (q =
0.95) is unconverged.  So the default step also keeps q <= :data:`MAX_BAND_VARIANCE` = 0.0155, the value at that
point: at tau' = 0.1 and 0.03 it gives 2.41 +- 0.06 and 3.32 +- 0.11 against 2.40 +- 0.04 and 3.32 +- 0.05
extrapolated.  Its cost grows like :math:`1/\tau'^2` steps per tau0 (tau/h = 12 900 at tau' = 0.01), and with the
LEs' growth like :math:`1/\sqrt{\tau'}` the predicted work at the default ``max_work`` refuses the default 2048 LEs
below tau' ~ 0.004 and 64 below ~1e-3 (naming the step); an h given with q > :data:`WARN_BAND_VARIANCE` is warned
about.  An audit (seed 11) agreed: c = 0.35 +- 0.07 at tau' = 0.3, 0.26 +- 0.11 at 0.1 and 0.27 +- 0.10 damped
(tau' = 0.1, tau_L' = 0.3); beyond q ~ 0.4 the bias grows more slowly than 0.3 q: +22-26% at q = 1 and ~+36% at 1.8
(tau' = 0.1), +60% at 5 and +115% at 15 (tau' = 0.01).

A V that lands on 0 for one step while passing through it (the force beyond the threshold) is not a release:
counting those (a first version) ended half excursions early, 15 SE below the PDMP at Gamma = 10, tau = 0.125 s,
h/16.  Where :math:`\tau \ll h` releases happen at any X and the count is not the paper's quantity: below
:data:`MIN_TAU_STEPS` steps per :math:`\tau` a :class:`~dryfric_jax.DryfricWarning` says so.

Loops are bounded: the loop runs at most ``max_steps`` steps; an LE still in flight there is dropped (which
biases the mean low), counted in ``n_truncated`` and warned about.  It runs in pieces of ~:data:`PIECE_S` seconds,
the same bits as one piece: between them a Ctrl-C and ``max_time`` act as on the estimator (no LE starts after them;
those in flight finish, or are dropped at a second Ctrl-C or at twice ``max_time``).
"""
from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from . import rng
from ._version import __version__
from .api import (DryfricWarning, _key, _live_text, _Record, _with_warnings, category, check_progress, key_id,
                  time_left)
from .di import make_di_model
from .excursions import BLOCK, MAX_LAYOUT, block_keys
from .estimators import t_quantile
from .limits import MAX_WORK, check_work, le_floor, log_predicted_duration
from .live import live_progress
from .params import Params
from .plan import check_count, check_layout_memory, check_max_time, check_max_work, choose, default_h
from .rounds import _ABANDON, INTERRUPT_GRACE_S, after_run, noted_late
from .sharding import over_lanes


class NoCountError(ValueError):
    """A count ended with fewer than 2 long excursions within ``max_steps``, ``max_time`` or ``max_work``: no mean,
    no spread.
    A ``ValueError`` (as the other refusals), of its own class so that a caller recording it as a point's outcome
    (a sweep's, Fig. 3's) catches only it and not an error raised by its own ``progress`` callback."""


@dataclass(frozen=True)
class LEDuration(_Record):
    """Mean duration (s) of the paper's long excursion of the DI, its 95% CI half-width, and what made it;
    ``print`` shows :meth:`summary` and the warnings, ``to_dict``/``to_json`` every field (what ``dryfric
    duration --json`` prints).  The same seed (key) and settings give the same numbers to the last bit."""

    mean: float
    ci: float
    n_excursions: int  # long excursions counted (>= n_requested unless a bound or limit stopped the loop)
    n_requested: int  # the run's n_excursions: from the block where the lanes' total reached it, none started
    n_lanes: int
    n_truncated: int  # in flight at the bound max_steps (or at twice max_time): dropped (the mean is then biased low)
    h: float
    dtype: str  # the chain's: float32 where asked and safe (else float64, with a warning)
    lane_steps: int  # steps the lanes ran until each stopped (its seek for a first change included)
    loop_steps: int  # steps computed: lanes x the loop's steps, as a lane that stopped idles in the loop
    max_steps: int = 0  # the loop's bound (whole blocks of 128)
    bridge: bool = True  # the crossings of X between steps counted too (module docstring); False: the raw count
    stopped_by: str = "n_excursions"  # what ended it: the rule ("n_excursions"), "max_steps", "max_time",
    # "work_bound", "interrupted"
    max_time: float | None = None  # the time limit given (s), None for none
    seed: int | None = None  # None for a jax.random key
    key: str | None = None  # a key-made run's key (api.key_id); None for a seed
    params: dict = field(default_factory=dict)
    version: str = __version__
    warnings: tuple = ()  # every note the run issued (also issued as DryfricWarning)
    wall_s: float = field(default=0.0, compare=False)

    def __post_init__(self):  # a record read back from JSON gives a list: the tuple the run made (frozen, hashable)
        object.__setattr__(self, "warnings", tuple(self.warnings))

    def summary(self) -> str:
        """The mean with its CI, the excursions behind it, the step and what made it (what ``dryfric duration``
        prints)."""
        rel = f"  ({100 * self.ci / self.mean:.1f}%)" if self.mean else ""
        return (f"mean long-excursion duration = {self.mean:.6g} ± {self.ci:.2g} s{rel}   (95% CI, Student t over "
                f"the excursions)\n{self.n_excursions} long excursions (releases counted; {self.n_requested} asked) "
                f"in {self.n_lanes} lanes, {self.n_truncated} truncated, h = {self.h:.3g} s, {self.dtype}, "
                + ("" if self.bridge else "raw count (no bridge correction), ")
                + (f"seed {self.seed}" if self.key is None else f"key {self.key}")
                + f"\nwall {self.wall_s:.1f} s, {self.loop_steps:.3g} lane-steps computed "
                f"({self.lane_steps:.3g} run by the lanes)")

    def __str__(self) -> str:
        return _with_warnings(self.summary(), self.warnings)


#: the most lanes a count takes: a block's normals are drawn at once, and lanes x the block stay within the
#: estimator's bound (:data:`~dryfric_jax.excursions.MAX_LAYOUT`; 2^22 lanes were taken, ~18 GB extrapolated from
#: 1.5 and 2.6 GB measured at 2^18 and 2^19: an audit)
MAX_COUNT_LANES = MAX_LAYOUT // BLOCK


#: what :func:`_run` says where the rule stopped the starts and twice ``max_time`` cut the LEs still in flight (the
#: result's ``stopped_by`` is ``"max_time"``, its note says the rule had stopped the starts)
RULE_THEN_MAX_TIME = "rule_then_max_time"


def check_lanes(n_lanes) -> int:
    """``n_lanes`` as an int; ``ValueError`` naming it unless it is an integer in [1, :data:`MAX_COUNT_LANES`]."""
    return check_count("n_lanes", n_lanes, 1, MAX_COUNT_LANES,
                       " (2^28 / the block of 128 steps: a block's normals are drawn at once, as the estimator's)")


def bridge_crossing(d0, d1, var1):
    r"""The probability that a Brownian bridge over one step, from distance ``d0`` inside a threshold to ``d1``
    inside it, with the step's variance ``var1`` (:math:`\operatorname{Var}(X_{n+1}\mid X_n)`), reached it:
    :math:`\exp(-2 d_0 d_1/\mathrm{var}_1)`, and 1 where either end is not inside (module docstring; tested against
    finely stepped OU paths: a factor 2 in the exponent, MODEL_NOTES' trap, moved the count by only 1.5 SE of the
    PDMP)."""
    return jnp.where((d0 > 0) & (d1 > 0), jnp.exp(-2.0 * d0 * d1 / var1), 1.0)


def released(stuck, V, Vn):
    r"""The release rule: step n releases the particle when it was stuck a whole step and then moves,
    :math:`V_{n-1} = V_n = 0 \ne V_{n+1}` (``stuck``: :math:`V_{n-1} = 0`), towards :math:`\operatorname{sign}
    (V_{n+1})`; a V that lands on 0 for one step while passing through it is no release (module docstring)."""
    return stuck & (V == 0) & (Vn != 0)


def _lane_start(model, keys, live):
    """The lanes' state before the first block (:func:`_lane_blocks`): X drawn from its stationary law, V = 0,
    nothing counted; a lane not ``live`` (padding to a multiple of the devices) is stopped from the start and
    counts nothing.  The state: X, V, whether V was 0 a step before, last release direction (0: none yet), phase
    (0: no change of direction yet, 1 / 2: in the first / second HLE of an LE), step index, step of the LE's start,
    stopped, and the sums: LEs, their steps, their steps squared."""
    dt = model.h.dtype
    lanes = keys.shape[0]
    x0 = jax.vmap(lambda k: jax.random.normal(jax.random.fold_in(k, 2**31 - 1), (), dt))(keys)
    sd = model.ou.stationary_sd()
    zero_i = jnp.zeros(lanes, jnp.int32)
    zero_n = jnp.zeros(lanes, jnp.int64)
    no = jnp.zeros(lanes, bool)
    return (x0 * sd, jnp.zeros(lanes, dt), no, zero_i, zero_i, zero_n, zero_n, ~live, zero_n, zero_n,
            jnp.zeros(lanes, jnp.float64))


def _lane_blocks(model, keys, b, stop, carry, n_excursions, b_end, block: int, bridge: bool = True, n_dev: int = 1):
    """The lanes' loop (module docstring) from block ``b`` up to ``b_end`` or until every lane has stopped: returns
    the block reached, the rule's flag and the state (:func:`_lane_start`).  ``b`` and ``stop`` are given and
    returned per lane (the same in every lane), so that every argument and output is split over the lanes.
    ``stop`` (no lane starts an LE) is raised by the rule, once the lanes' total reaches ``n_excursions``, or by the
    host (``max_time``, ``max_work``, a Ctrl-C); a lane with none started then stops at once.  The loop run in
    pieces gives the bits of one run (tested).  ``bridge``: also count the crossings of the opposite threshold that
    X makes between two steps of a stuck particle (module docstring), with a uniform per step independent of the
    step's normals (:func:`~dryfric_jax.rng.normals_and_spare`: their spare bits in float32, one more hash in
    float64).  With ``n_dev`` > 1 this runs as one shard of the lanes (:func:`_run`): the rule's total and the
    loop's condition are summed over the devices (``psum`` over the mesh axis ``"lanes"``), so every device runs the
    same blocks and the rule is the one-device rule."""
    dt = model.h.dtype
    lanes = keys.shape[0]

    def total(x):  # over the lanes of every device
        return jax.lax.psum(x, "lanes") if n_dev > 1 else x

    var1 = model.ou.L21 ** 2 + model.ou.L22 ** 2  # Var(X_{n+1} | X_n), exactly (1 - e^{-2h/tau}) / tau
    # a stuck particle moves up once the step's mean force Xi passes x_plus = 1 - gamma_bar, down below x_minus
    # = -1 - gamma_bar (DIModel.step with V = 0, nondimensional Delta = 1)
    x_plus, x_minus = 1.0 - model.gamma_bar, -1.0 - model.gamma_bar
    b, stop = b[0], stop[0]
    carry = carry[:7] + (carry[7] | (stop & (carry[4] == 0)),) + carry[8:]  # as the rule does, for the host's stop

    def step(z1, z2, u, stop, c):
        X, V, stuck, last, ph, n, s0, off, N, S, Q = c
        _, Xn, Vn, _ = model.move(X, V, z1, z2)
        release = released(stuck, V, Vn)
        s = jnp.sign(Vn).astype(jnp.int32)
        if bridge:  # X's path between X_n and X_{n+1} crossed the opposite threshold while the particle stayed put
            up = last < 0  # the opposite threshold is x_plus after a release down, x_minus after one up
            d0 = jnp.where(up, x_plus - X, X - x_minus)  # distances inside the threshold
            d1 = jnp.where(up, x_plus - Xn, Xn - x_minus)
            cross = bridge_crossing(d0, d1, var1)
            virtual = (V == 0) & (Vn == 0) & (last != 0) & (u < cross)
            release, s = release | virtual, jnp.where(virtual, -last, s)
        change = release & (last != 0) & (s != last) & ~off
        n1 = n + 1
        end = change & (ph == 2)  # an LE ends here (and the next starts, unless the lanes stop)
        d = n1 - s0
        # A stopped lane's X and V run on unused (change is off there, so its sums, phase and start stay), and
        # its step count n stands still.  Freezing X, V with jnp.where(off, old, new) as well ran 3.7x slower
        # on 2 CPU cores (7.2 against 27 M lane-steps/s, 32 lanes, tau = 1 s, Gamma = 1), to the same bits.
        return (Xn, Vn, V == 0, jnp.where(release, s, last),
                jnp.where(change, jnp.where(ph == 1, 2, 1), ph), n + (~off).astype(n.dtype),
                jnp.where(change & (ph != 1), n1, s0), off | (end & stop), N + end, S + jnp.where(end, d, 0),
                Q + jnp.where(end, d.astype(jnp.float64) ** 2, 0.0))

    def body(st):
        b, stop, c = st
        bk = block_keys(keys, b)
        # the block key's normals (the raw count's); the bridge's uniform from their spare bits (float32) or one
        # more hash (float64, since 0.3.0)
        z1, z2, u = rng.normals_and_spare(bk, block, dt) if bridge else rng.normals(bk, block, 2, dt) + (None,)
        c = jax.lax.fori_loop(0, block, lambda i, cc: step(z1[i], z2[i], None if u is None else u[i], stop, cc), c)
        stop = stop | (total(c[8].sum()) >= n_excursions)  # from the next block on, no lane starts an LE
        c = c[:7] + (c[7] | (stop & (c[4] == 0)),) + c[8:]  # a lane with none started stops at once
        return b + 1, stop, c

    def cond(st):
        b, _, c = st
        return (b < b_end) & (total(jnp.sum(~c[7], dtype=jnp.int32)) > 0)

    b, stop, c = jax.lax.while_loop(cond, body, (b, stop, carry))
    return jnp.broadcast_to(b, (lanes,)), jnp.broadcast_to(stop, (lanes,)), c


def _run(model, keys, n_excursions: int, max_blocks: int, block: int = BLOCK, bridge: bool = True,
         max_time: float | None = None, t0: float | None = None, progress=None, max_work: float | None = None):
    """:func:`_lane_blocks` over the lanes ``keys`` in pieces of ~:data:`PIECE_S` seconds, split over the local
    devices (:func:`~dryfric_jax.sharding.over_lanes`; on a CPU one device per core, so the count uses every
    core).  Returns numpy arrays per lane (those of ``keys`` only): the LEs counted, the sums of their durations
    and of their squares (steps), whether the lane stopped (not in flight at the end), whether it started an LE,
    its steps; then the blocks run and what ended the loop (``"n_excursions"``: every lane stopped by the rule;
    ``"max_steps"``: the bound; ``"max_time"``: the limit stopped the starts; :data:`RULE_THEN_MAX_TIME`: the rule
    did, and twice the limit cut those in flight; ``"work_bound"``: the lanes' lane-steps computed reached
    ``max_work`` and stopped the starts (those in flight finish, within the loop's bound; from the first block whose
    end has the ``keys``' lanes past ``max_work`` lane-steps, a piece ending there, so that the bits do not depend
    on the pieces' timing); ``"interrupted"``: a Ctrl-C, SIGTERM under
    ``dryfric``).

    The lanes are padded to a multiple of the devices with lanes that count nothing.  The numbers are those of one
    device, and of one piece, to the bit (tested).  Between pieces a Ctrl-C takes effect (a compiled loop of
    minutes could not be stopped before 2026-12-05), and ``max_time`` (seconds from ``t0``) acts as the
    estimator's: past it no lane starts an LE, those in flight finish, and at twice it the loop ends (those still
    in flight are truncated).  A Ctrl-C acts as the estimator's too: the first starts no LE and finishes those
    in flight within :data:`~dryfric_jax.rounds.INTERRUPT_GRACE_S` (said on stderr), a second keeps what was
    counted; within :func:`~dryfric_jax.rounds.abandon_on_interrupt` it raises at once.  Split over 2 CPU cores
    (AMD EPYC, 2026-12-05, 5 interleaved runs each, medians) the count took 1.89 against 2.16 s in 16 lanes, 1.77
    against 1.82 in 32 and 2.27 against 2.73 in 64 (tau = 1 s, Gamma = 2.15, 48 LEs asked), and 0.18 against
    0.25 s in 256 (Gamma = 10, tau = 0.125 s, 1024 asked).  ``n_excursions`` and the blocks are traced: a
    figure's points differ in them and share one compiled loop per lane count (and device count).  ``progress``:
    called after every piece with :func:`_progress`'s dict (it reads the state, never changes it)."""
    t0 = time.perf_counter() if t0 is None else t0
    n = keys.shape[0]
    n_dev = len(jax.local_devices())
    pad = -n % n_dev
    live = jnp.arange(n + pad) < n
    if pad:
        keys = jnp.concatenate([keys, keys[jnp.arange(pad) % n]])
    carry = over_lanes(_lane_start, (model, keys, live), (False, True, True))
    b, stop = jnp.zeros(n + pad, jnp.int32), jnp.zeros(n + pad, bool)
    # the first piece 4 blocks up to 2^13 lanes (~2^22 lane-steps), 1 block from 2^15 (at 2^21 lanes still 2.7e8
    # lane-steps, ~7 s on 2 cores, which --max-time cannot cut: it acts between pieces); it was 4 blocks at any lane
    # count, and --max-time 2 at 2^21 lanes ended the count after 70 s (an audit)
    first_chunk = int(min(4, max(1, (1 << 22) // ((n + pad) * block))))
    done, chunk, ended, deadline, first = 0, first_chunk, "n_excursions", None, []
    # the block from which no LE starts for max_work: the first whose end has the lanes past it
    b_work = max_blocks if max_work is None or not math.isfinite(max_work) else \
        int(min(max(math.ceil(max_work / (n * block)), 1), max_blocks))
    while True:
        try:
            t, before = time.perf_counter(), done
            end = min(done + chunk, max_blocks, b_work if done < b_work else max_blocks)  # a piece ends there
            b, stop, carry = over_lanes(_lane_blocks, (model, keys, b, stop, carry, jnp.int64(n_excursions),
                                                       jnp.int32(end)),
                                        (False, True, True, True, True, False, False), block=block, bridge=bridge,
                                        n_dev=n_dev)
            done = int(b[0])
            if progress is not None:
                progress(_progress(carry, n_excursions, bool(stop[0]), t0, first, max_time, n * done * block,
                                   max_work))
            if bool(np.all(np.asarray(carry[7]))):
                break
            if done >= max_blocks:
                ended = "max_steps" if ended != "interrupted" else ended
                break
            now = time.perf_counter()
            if deadline is not None and now > deadline:  # the grace after a Ctrl-C is over
                break
            if done >= b_work and not bool(stop[0]):  # at that block whatever the pieces: the same bits
                # (it bounded the prediction only: a count ran 5.4x a max_work of 5e7, a sweep audit)
                ended, stop = "work_bound", jnp.ones_like(stop)
            if max_time is not None and now - t0 > max_time and ended != "interrupted":
                if now - t0 > 2 * max_time:  # those still in flight are cut by the limit, whatever stopped the starts
                    ended = ended if ended in ("max_time", "work_bound") else RULE_THEN_MAX_TIME
                    break
                if not bool(stop[0]):  # the limit stops the starts; where the rule already had, the count ends as
                    ended = "max_time"  # the rule's (it said "max_time stopped the count at 119 of the 64 asked")
                stop = jnp.ones_like(stop)
            # the next piece ~PIECE_S long (at most 64x the last: a first piece of compile time says nothing), from
            # the blocks the last ran (one cut short at max_work's block made the next 1.2 s long: an audit)
            ran = max(done - before, 1)
            chunk = int(min(max(ran * PIECE_S / max(now - t, 1e-6), 1), 64 * ran, 1 << 24))
        except KeyboardInterrupt:
            # the piece it stopped is lost, the state before it is whole (the arrays are not changed in place)
            if _ABANDON[0]:  # a caller that keeps finished runs only (a sweep's point, a figure's run)
                raise
            if ended == "interrupted":  # a second Ctrl-C: keep what was counted, those in flight dropped
                break
            # the first, as the estimator's: no excursion starts, those in flight finish within the grace
            ended, stop = "interrupted", jnp.ones_like(stop)
            deadline = time.perf_counter() + INTERRUPT_GRACE_S
            if max_time is not None:
                deadline = min(deadline, max(t0 + 2 * max_time, time.perf_counter()))
            clear = "\r\x1b[K" if sys.stderr.isatty() else ""
            print(f"{clear}dryfric: interrupted: finishing the long excursions in flight for at most "
                  f"{deadline - time.perf_counter():.3g} s (any still running then are reported as truncated); "
                  "interrupt again to drop them", file=sys.stderr, flush=True)
    N, S, Q, off, started, steps = (np.asarray(a)[:n] for a in (*carry[8:11], carry[7], carry[4] != 0, carry[5]))
    return N, S, Q, off, started, steps, done, ended


def _progress(carry, n_excursions, stopping, t0, first, max_time, computed, max_work=None) -> dict:
    """What a ``progress`` callback of :func:`di_long_excursion_duration` gets after a piece of the loop (there with
    ``mean_s``, in seconds, for ``mean_steps``): the LEs counted so far (``n_excursions``) of the ``target``, those
    ``in_flight``, the ``mean_steps`` of those counted (nan before the first; it is the final mean only at the end,
    as the long ones finish last), ``stopping`` (no LE starts any more: the rule, ``max_time``, ``max_work`` or a
    Ctrl-C), ``elapsed_s``, and the projected ``left_s`` with the limit that ends the run first, ``left_to``
    (:func:`~dryfric_jax.api.time_left`: ``"n_excursions"``, ``"max_time"`` or ``"max_work"``; both None before a
    projection, once those counted and in flight make up the target, and once stopping: the LEs in flight then end
    when they end). The work is the lanes' ``computed`` lane-steps, as ``max_work`` counts them (before the stop
    every lane runs). The rate is that of the pieces after the first, whose time holds the compilation; ``first``
    holds its (time, lane-steps) between calls."""
    now = time.perf_counter()
    N, S, ph, off = (np.asarray(a) for a in (carry[8], carry[9], carry[4], carry[7]))
    k, work, in_flight = int(N.sum()), float(computed), int(((ph != 0) & ~off).sum())
    left = to = None
    if not first:
        first.append((now, work))
    elif not stopping and now > first[0][0] and work > first[0][1] and k + in_flight < n_excursions:
        # (once those in flight would make up the count, time_left counts them as done and said "~0 s left" for
        # most of the count, which then finished the long ones: 62 s at tau = 1e-3 s, a sweep audit; no projection)
        rate = (work - first[0][1]) / (now - first[0][0])
        left, to = time_left(now - t0, work, k, in_flight, n_excursions, max_time=max_time, max_work=max_work,
                             rate=rate)
    return dict(n_excursions=k, target=int(n_excursions), in_flight=in_flight,
                mean_steps=float(S.sum()) / k if k else math.nan, stopping=stopping,
                elapsed_s=now - t0, left_s=left, left_to=to)


#: the wall time a piece of the count's loop aims at (:func:`_run`): a Ctrl-C or ``max_time`` acts within about it
PIECE_S = 0.25


#: the count's default step keeps at least TAU_STEPS steps per tau (default_duration_h): with the bridge correction
#: its bias falls like h, +2.0%, +1.2% and +0.4% (+- 0.5%) at tau/h = 187, 373 and 746 (Gamma = 10, tau = 0.125 s,
#: against tau/h = 2992), none seen (+- 0.3%) at 746 to 2984 (Fig. 3's point); module docstring
TAU_STEPS = 700
#: the count's default step keeps the step's X variance against the stuck band's half-width squared
#: (:func:`step_band_variance`) at most this: its value at Fig. 3's worst point (Gamma = 10, tau = 0.125 s,
#: tau' = 0.184, tau/h = 700: 0.01548), where the bias was measured +0.4% +- 0.5% (TAU_STEPS).  The bias is ~0.3 q
#: at any tau' (+2.0% at q = 0.058 there; c = 0.25-0.34 +- 0.1 at tau' = 0.1, 0.03, 0.01): with tau/h = 700 alone it
#: was +5% +- 6% at tau' = 0.01, q = 0.29, +9% by the fit (module docstring)
MAX_BAND_VARIANCE = 0.0155
#: the step's X variance against the band (:func:`step_band_variance`) above which a warning says the count is
#: biased long (~0.3 q: +2% here)
WARN_BAND_VARIANCE = 0.06
#: steps per tau below which a warning says the count is not the paper's long excursion (its bias is +2% already
#: at tau/h = 187, Gamma = 10, tau = 0.125 s)
MIN_TAU_STEPS = 10
#: long excursions counted below which a SmallSampleWarning says the CI under-covers: measured (1000 replicates at
#: Gamma = 10, tau = 0.125 s, the D estimator's h; scripts/duration_coverage.py) 0.932 +- 0.008 at 63 counted,
#: 0.943 +- 0.007 at 163 and 0.946 +- 0.007 at 2330 (0.2.9's uniforms: 0.921, 0.940, 0.942)
MIN_RELIABLE_LE = 100
#: the loop's bound in steps: whole blocks, counted in int32 and folded into the lanes' keys
MAX_STEPS = (2**31 - 2) * BLOCK
#: the planned loop bound's least value in steps (:func:`default_max_steps`; the fixed default before 2026-12-06)
MIN_DEFAULT_MAX_STEPS = 10**8


def step_band_variance(params: Params, h: float) -> float:
    r"""The variance of X over one step against the stuck band's half-width squared,
    :math:`q = \operatorname{Var}(X_{n+1}\mid X_n) = (1 - e^{-2h/\tau})/\tau'` (nondimensional X, whose band is
    :math:`[-1 - \bar\gamma', 1 - \bar\gamma']` whatever :math:`\tau_L`).  The count's step bias is a function
    of q, not of tau/h (module docstring): at q = 0.38 the count is 13%, 9% and 13% long at tau' = 0.1, 0.03 and
    0.01 (tau/h = 53, 175 and 526; ``scripts/duration_step_bias.py``)."""
    return -math.expm1(-2.0 * h / params.tau) / params.tau_nd


def band_h(params: Params, q: float) -> float:
    """The largest step (s) whose :func:`step_band_variance` is at most ``q`` (inf where every step's is)."""
    x = q * params.tau_nd
    return math.inf if x >= 1.0 else -0.5 * params.tau * math.log1p(-x)


def default_duration_h(params: Params) -> float:
    """The count's default step in seconds: the D estimator's :func:`~dryfric_jax.plan.default_h`,
    :math:`\\tau/` :data:`TAU_STEPS`, or the step whose :func:`step_band_variance` is
    :data:`MAX_BAND_VARIANCE`, whichever is smallest (the bridged count's bias falls like h, and is a function of
    that variance: module docstring).  The last binds at tau' < 0.184 (tau' = tau Delta^2 / Gamma) unless the D
    estimator's step is finer (stiff damping: 0.01 tau_L), and the step's cost then grows like 1/tau'^2 in tau0."""
    return min(default_h(params), finest_rules_h(params))


def finest_rules_h(params: Params) -> float:
    """The count's own bound on its step (s), whatever step is asked of it by default or by a sweep
    (:func:`~dryfric_jax.sweep.duration_h`): :math:`\\tau/` :data:`TAU_STEPS` or the step whose
    :func:`step_band_variance` is :data:`MAX_BAND_VARIANCE`, whichever is smaller."""
    return min(params.tau / TAU_STEPS, band_h(params, MAX_BAND_VARIANCE))


def default_lanes(n_excursions: int) -> int:
    """Lanes for ``n_excursions`` LEs: the power of 2 nearest ``n_excursions / 3``, within [32, 256].  After the
    stop the loop runs until the longest LE in flight ends, ~ln(lanes) mean durations, so each lane should run
    a few LEs; but a block's cost on a CPU grows far slower than its width below ~100 lanes.  Measured on 2 cores
    (RESULTS.md), wall per LE counted: 180 asked at tau = 1 s, Gamma = 1.67 (~2.6e6 steps each), 0.104 s in 64
    lanes against 0.22, 0.14, 0.12 in 16, 32, 128; 32 asked there, 18 s in all in 32 lanes (62 counted) against
    18 in 16 (48) and 21 in 64 (83); 1024 at Gamma = 10, tau = 0.125 s, 0.65 and 0.67 ms in 128 and 256 lanes."""
    return 2 ** int(min(8, max(5, round(math.log2(max(n_excursions, 1) / 3)))))


def le_duration_floor(params: Params) -> float:
    r"""A floor on the mean long-excursion duration for fast noise, in :math:`\tau_0`:
    :math:`C\,\min(1, \tau_L')/\sqrt{\tau'}`, :math:`C =` :data:`~dryfric_jax.limits.LE_FLOOR_C`
    (:func:`~dryfric_jax.limits.le_floor`).  A stuck particle is released only where its velocity reaches 0 while the
    force lies inside the friction window, whose chance at such a moment falls
    with the noise's spread :math:`1/\sqrt{\tau'}`; so for :math:`\tau' \ll 1` the LEs grow like
    :math:`1/\sqrt{\tau'}` while :func:`~dryfric_jax.limits.log_duration_scale` stays at :math:`\min(1, \tau_L')`.
    Measured (64 asked, seed 0, 0.2.11; the LE in :math:`\tau_0`, then the measured
    :math:`C = \text{LE}\sqrt{\tau'}/\min(1, \tau_L')`): :math:`\tau_L = \infty`, :math:`\bar\gamma = 0`,
    :math:`\tau/h = 700`: 2.3, 2.6, 5.3 and 20.7 at :math:`\tau' = 0.1, 0.03, 0.01, 10^{-3}` (C = 0.73, 0.45, 0.53,
    0.65; the last with this planned loop bound, 608 s: the old one cut it, 16.7 biased low); coarser steps
    lengthen them: 14.3 at :math:`\tau' = 0.01`, :math:`\tau/h = 10` (C = 1.4), 47.6 and 37.6 at
    :math:`\tau' = 10^{-3}`, :math:`\tau/h = 10, 100` (1.5, 1.2); damped, at :math:`\tau' = 0.01`, 4.0, 2.5 and
    1.7 with :math:`\tau_L' = 1, 0.3, 0.1` (C = 0.40, 0.83, 1.7), at :math:`\tau' = 10^{-3}` 1.6 and 0.46 with
    :math:`\tau_L' = 10^{-2}, 10^{-3}` (5.1, 15); 7.0 with :math:`\bar\gamma' = 0.5` at :math:`\tau' = 0.01` (0.70).
    The CIs are +-25-30%.  These steps were coarse for the count below tau' ~ 0.1 (:func:`step_band_variance` q =
    0.29 at tau' = 0.01 and 2.9 at 1e-3, tau/h = 700; the default step now keeps q <= :data:`MAX_BAND_VARIANCE`), so
    those LEs are long: at tau' = 0.01 5.25 +- 0.17 at q = 0.07, 5.11 +- 0.21 extrapolated to q = 0
    (``scripts/duration_step_bias.py``), still C = 0.5.
    Without the floor the work predicted at :math:`\tau' = 10^{-3}` was 1/30 of what the lanes
    ran (2.1e9 lane-steps, 4.4e9 computed), and the fixed loop bound of 10^8 steps before 2026-12-06 truncated a
    count of 64 there."""
    return le_floor(params.tau_nd, params.tau_L_nd)


def check_duration_run(params, h=None, n_excursions: int = 2048, dtype: str = "float64",
                       max_work: float = MAX_WORK, name: str = "n_excursions", n_lanes: int | None = None,
                       ruled: bool = False):
    """The checks :func:`di_long_excursion_duration` makes before it runs anything, for a sweep to refuse a point
    before its grid runs: the estimator's (:func:`~dryfric_jax.plan.choose`: a stationary state, a simulable tau_L,
    h, the dtype), ``n_excursions`` in [2, 2^40] and the predicted work within ``max_work``
    (:func:`~dryfric_jax.limits.check_work`) of the LEs the lanes run: ``max(n_excursions, n_lanes) + n_lanes``
    (``n_lanes`` default :func:`default_lanes`), since every lane seeks its first LE and finishes the one in flight
    at the stop (for ``n_excursions`` alone, 2 asked in 32 lanes ran 34 times a max_work it passed: an audit), each
    of the estimator's predicted duration or :func:`le_duration_floor`, whichever is longer.
    Returns the plan (its ``h``, default :func:`default_duration_h`, and ``dtype``, float32 only where safe);
    ``ValueError`` naming the argument otherwise (``n_excursions`` as ``name``: a sweep's setting is
    ``durations``).  ``ruled``: ``h`` is a sweep's held to the count's rules (:func:`~dryfric_jax.sweep.duration_h`),
    named as the count's step where it is refused, as the default is."""
    default = h is None and isinstance(params, Params)  # a non-Params is refused by choose, by name
    if default:
        h = default_duration_h(params)
    try:
        plan = choose(params, "di", h, None, dtype, excursions=True)
    except ValueError as e:  # the rules' step refused: say it is tau that is too short, not an h never given
        if not ((default or ruled) and str(e).startswith("h must")):
            raise
        raise ValueError(f"tau = {params.tau:.3g} s is too short for the long-excursion count: its step "
                         f"tau/{params.tau / h:.3g} = {h:.3g} s (the rules of durations.default_duration_h) is refused "
                         f"({e}); it needs a longer tau, or an h given to it ('dryfric duration --h'), which it then "
                         "warns is coarse") from None
    n_excursions = check_count(name, n_excursions, 2, 2**40, " (long excursions)")
    lanes = default_lanes(n_excursions) if n_lanes is None else check_lanes(n_lanes)
    # as the estimator's layout (2^20 lanes peaked at 4.8 GB here, above that fit's 3.8 GB: stop 91)
    check_layout_memory(lanes, BLOCK, plan.dtype, name="n_lanes", other="")
    max_work = check_max_work(max_work)
    try:
        check_work(params.tau_nd, params.tau_L_nd, params.gamma_bar_nd, params.tau0 / plan.h,
                   max(n_excursions, lanes) + lanes, max_work, min_duration=le_duration_floor(params))
    except ValueError as e:
        step = (f"; its step tau/{params.tau / plan.h:.3g} keeps X's step variance against the stuck band at "
                f"q = {MAX_BAND_VARIANCE}, and a coarser h biases the count long, ~30q%"
                if plan.h == band_h(params, MAX_BAND_VARIANCE) else "")
        raise ValueError(f"{e} (here for the {n_excursions} long excursions ({name}) counted in {lanes} lanes, each "
                         "of which also seeks its first one and finishes the one in flight at the end: lower them"
                         f"{step})") from None
    le = predicted_le_steps(params, plan.h)
    if le > MAX_STEPS:  # (a max_work of 1e17 passed one at tau' = 1e-4 whose every LE the loop's bound would cut)
        raise ValueError(f"the predicted long excursion, {le:.3g} steps of h = {plan.h:.3g} s (a lower estimate), "
                         f"exceeds the loop's bound of {MAX_STEPS:.3g} steps: no count could end; it needs a "
                         "longer tau (or a coarser h, which biases it long)")
    return plan


def predicted_le_steps(params: Params, h: float) -> float:
    """The predicted mean LE in steps of ``h`` (s): the estimator's predicted duration
    (:func:`~dryfric_jax.limits.log_duration_scale`, a lower estimate) or :func:`le_duration_floor`, whichever is
    longer (:func:`~dryfric_jax.limits.log_predicted_duration`, as :func:`check_duration_run` checks the work)."""
    log_t = log_predicted_duration(params.tau_nd, params.tau_L_nd, params.gamma_bar_nd, le_duration_floor(params))
    return math.exp(min(log_t, 700.0)) * params.tau0 / h


def default_max_steps(params: Params, h: float, n_excursions: int, n_lanes: int | None = None) -> int:
    """The count's loop bound when none is given: :func:`max_steps_for` the predicted LE
    (:func:`predicted_le_steps`), at least :data:`MIN_DEFAULT_MAX_STEPS`.  The fixed 10^8 before 2026-12-06
    truncated a count of 64 LEs at tau' = 10^-3 (tau_L = inf, the default step), where the LEs last ~21 tau0,
    1.5e7 steps, and the longest lane ran 1.4e8."""
    return max(MIN_DEFAULT_MAX_STEPS, max_steps_for(n_excursions, predicted_le_steps(params, h), n_lanes))


def max_steps_for(n_excursions: int, le_steps: float, n_lanes: int | None = None) -> int:
    """A loop bound (steps) for ``n_excursions`` LEs of at most ~``le_steps`` steps each (an upper estimate, e.g.
    the D estimator's mean cycle over h: a cycle spans at least one LE): 50 times the LEs a lane runs (two more for
    its seek and the one in flight at the stop), at least 10 000 steps, at most :data:`MAX_STEPS`.  What Fig. 3
    and a sweep's durations run with; a bound this loose is reached only by a wrong estimate."""
    per_lane = n_excursions / (default_lanes(n_excursions) if n_lanes is None else n_lanes)
    return int(min(max(50 * (per_lane + 2) * max(le_steps, 1.0), 10_000), MAX_STEPS))


def di_long_excursion_duration(params, key, h: float | None = None, n_excursions: int = 2048,
                               n_lanes: int | None = None, max_steps: int | None = None, dtype: str = "float64",
                               max_work: float = MAX_WORK, bridge: bool = True, max_time=None,
                               progress=None) -> LEDuration:
    r"""Mean duration of the paper's long excursion of the DI at step ``h`` (module docstring), in seconds.

    Args:
        params: :class:`~dryfric_jax.Params`.
        key: a ``jax.random`` key or an integer seed in [0, 2^62]; lane l uses ``split(key, n_lanes)[l]``,
            its block b ``fold_in(lane_key, b)``.
        h: DI step in seconds (default :func:`default_duration_h`: the D estimator's
            :func:`~dryfric_jax.plan.default_h`, finer where tau/h would fall below :data:`TAU_STEPS` or X's step
            variance against the stuck band exceed :data:`MAX_BAND_VARIANCE`: :func:`step_band_variance`).
        n_excursions: long excursions to count, an integer in [2, 2^40]: once the lanes' total reaches it no lane
            starts another, and those in flight are finished (so a run counts a few more).
        n_lanes: lanes, an integer in [1, 2^21] (default :func:`default_lanes`; 2^21 x 128 steps is the
            estimator's bound on a block's normals, ~4.6 GB here); they change the bits, not the
            law.
        max_steps: the loop's bound in steps, an integer in [1, :data:`MAX_STEPS`] (rounded up to whole blocks
            of 128); default :func:`default_max_steps`, planned from the predicted LE, at least 10^8.
        dtype: ``"float64"`` or ``"float32"`` (or the dtype), the chain's; float32 where it is not safe runs in
            float64 with a :class:`~dryfric_jax.DryfricWarning`, as :func:`~dryfric_jax.estimate_diffusivity` does.
        max_work: a run whose predicted lane-steps (:func:`~dryfric_jax.limits.check_work`, for the LEs the lanes
            run: :func:`check_duration_run`) exceed it is refused before it starts, as the estimator's
            (h = 1e-10 s at Fig. 3's point would run ~15 min to its bound, then fail: an audit).  The prediction
            can be several times short (at tau = 1e-3 s and a large Gamma: a sweep audit), so it also bounds the
            starts: once the lanes have computed ``max_work`` lane-steps no LE starts, and ``stopped_by`` is
            ``"work_bound"`` (a note says so; fewer than 2: :class:`NoCountError`).  Those in flight then finish,
            bounded by ``max_steps`` only (``max_time`` bounds the time), which can take the run several times past
            it (3-10x in an audit): a note says so.  (The estimator also caps each excursion at ~max_work / lanes
            steps; dropping an LE in flight would bias the mean low.)  Until 0.3.1 it bounded the prediction
            only.
        bridge: count the crossings of the opposite threshold between two steps of a stuck particle too (module
            docstring; default); ``False`` gives the raw count, whose bias falls only like :math:`\sqrt h`.
        max_time: a time limit in seconds (> 0; None or inf: none), as the estimator's: past it no lane starts a
            long excursion and those in flight finish (so the count stays consistent, with fewer than asked); at
            twice it the loop ends and those still in flight are left out (``n_truncated``).  The result's
            ``stopped_by`` says ``"max_time"`` (also where the rule had stopped the starts and twice it cut those
            in flight: its note says so); a count that ends within twice it after the rule stopped the starts, or
            within it, has the bits it has without it.
        progress: ``True`` for a live status line (counted so far, their mean, the time taken and the projected
            time left: an updated display in a Jupyter notebook, a self-overwriting line on a terminal's stderr,
            nothing elsewhere; :mod:`dryfric_jax.live`), or a callback ``progress(dict)`` after every piece of the
            loop (~:data:`PIECE_S` s), with the keys ``n_excursions`` (counted so far), ``target``, ``in_flight``,
            ``mean_s`` (of those counted so far, s; the long ones finish last, so it is the result's mean only at the
            end), ``stopping``, ``elapsed_s``, ``left_s`` and ``left_to`` (the projected time left and the limit
            that ends the run, as the estimator's; None until the second piece and once stopping); what ``dryfric
            duration`` shows on a terminal.  It never changes the numbers (tested).  An exception it raises ends
            the count and goes on up (:class:`NoCountError` is the count's own).

    A Ctrl-C (SIGTERM under ``dryfric``) acts as it does on the estimator: the first starts no long excursion and
    finishes those in flight within :data:`~dryfric_jax.rounds.INTERRUPT_GRACE_S`, a second drops them, and the
    result says ``stopped_by = "interrupted"`` (a ``KeyboardInterrupt`` where fewer than 2 were counted, or at once
    within :func:`~dryfric_jax.rounds.abandon_on_interrupt`).

    ``ValueError`` naming the argument, also where the estimator refuses the parameters (tau_L = inf with
    :math:`|\bar\gamma| \ge \Delta`: the particle runs away; it gave a number here, 9 of 32 lanes truncated);
    :class:`NoCountError` (a ``ValueError``) where fewer than 2 were counted within ``max_steps``, ``max_time`` or
    ``max_work``;
    the result's ``n_truncated`` counts the LEs in flight at ``max_steps`` (dropped, with a warning).
    """
    t0 = time.perf_counter()
    plan = check_duration_run(params, h, n_excursions, dtype, max_work, n_lanes=n_lanes)  # n_lanes checked there
    key, seed = _key(key)
    n_excursions = int(n_excursions)
    n_lanes = default_lanes(n_excursions) if n_lanes is None else check_lanes(n_lanes)
    if max_steps is None:
        max_steps = default_max_steps(params, plan.h, n_excursions, n_lanes)
    max_steps = check_count("max_steps", max_steps, 1, MAX_STEPS, " (blocks of 128 steps counted in 32 bits)")
    max_time = check_max_time(max_time)
    max_time = None if max_time == math.inf else max_time
    check_progress(progress)
    h, dtype = plan.h, plan.dtype
    if not isinstance(bridge, (bool, np.bool_)):
        raise ValueError(f"bridge must be True or False, got {bridge!r}")
    bridge = bool(bridge)
    q = step_band_variance(params, h)
    if params.tau / h < MIN_TAU_STEPS:
        notes = [f"tau/h = {params.tau / h:.3g} < {MIN_TAU_STEPS}: the noise decorrelates within a few steps, so "
                 "releases happen at any X and the count of their changes of direction is not the paper's long "
                 "excursion (threshold to threshold); lower h"]
    elif q > WARN_BAND_VARIANCE:
        bias = (f"~{30 * q:.2g}% (~30q% where q <= 0.4: +9-13% measured at q = 0.38)" if q <= 0.4 else
                "more than 10% (measured +20-26% at q = 1, ~+36% at 1.8, +60% at 5 and +115% at 15)")
        notes = [f"h = {h:.3g} s is coarse for the count: X moves {math.sqrt(q):.2g} of the stuck band's half-width "
                 f"per step (step variance q = {q:.3g} > {WARN_BAND_VARIANCE}), so releases are found late and the "
                 f"mean is biased long, by {bias}; the default step keeps q <= {MAX_BAND_VARIANCE} "
                 "(durations.step_band_variance)"]
    else:
        notes = []
    notes = plan.notes + notes
    for note in notes:
        warnings.warn(note, DryfricWarning, stacklevel=2)
    model = make_di_model(params, h, jnp.dtype(dtype))
    max_blocks = -(-max_steps // BLOCK)
    bound = max_blocks * BLOCK  # the bound used: max_steps rounded up to whole blocks

    def report(d):  # the mean in seconds
        steps = d.pop("mean_steps")
        progress({**d, "mean_s": h * steps})

    with live_progress(progress, _live_text) as progress:  # report() calls the callback this gives
        N, S, Q, off, started, steps, blocks, ended = _run(model, jax.random.split(key, n_lanes), n_excursions,
                                                           max_blocks, block=BLOCK, bridge=bridge, max_time=max_time,
                                                           t0=t0, progress=None if progress is None else report,
                                                           max_work=max_work)
    # from here the count is over: a Ctrl-C or SIGTERM is held until its result is formed, then noted in it, as the
    # estimator's (api.estimate_diffusivity), except where a caller keeps finished runs only (abandon_on_interrupt)
    with after_run() as late:
        rule_first = ended == RULE_THEN_MAX_TIME  # the rule stopped the starts, twice max_time cut those in flight
        ended = "max_time" if rule_first else ended
        k, cut = int(N.sum()), int((started & ~off).sum())
        if k < 2:  # no mean or no spread: say why rather than return a NaN
            if ended == "interrupted":  # nothing to keep: the Ctrl-C goes on up, saying why (it said nothing)
                raise KeyboardInterrupt(f"fewer than 2 long excursions counted before the interrupt ({k})")
            if ended == "max_time":
                raise NoCountError(f"max_time = {max_time:g} s is too short here: the {n_lanes} lanes counted {k} long "
                                   "excursions within twice it (at least 2 must); raise max_time")
            if ended == "work_bound":
                raise NoCountError(f"max_work = {max_work:.3g} lane-steps is too small here: the {n_lanes} lanes "
                                   f"counted {k} long excursions by the time they had computed it (at least 2 must); "
                                   "raise max_work")
            raise NoCountError(f"max_steps = {bound} is too small here: the {n_lanes} lanes counted {k} long excursions "
                               f"within it (at least 2 must); raise max_steps")
        stop_note = None  # what stopped the count short of the rule, if anything
        if ended == "interrupted":
            stop_note = (f"interrupted: {k} of the {n_excursions} long excursions asked counted, none started after it"
                         + (f"; {cut} still in flight are left out, so the mean is biased low" if cut
                            else ", those in flight finished"))
        elif rule_first:  # the rule had stopped the starts (not max_time: an audit), twice max_time cut the rest
            stop_note = (f"max_time = {max_time:g} s: at twice it {cut} long excursions still in flight, after the rule "
                         f"had stopped the starts ({k} counted of the {n_excursions} asked), are left out, so the mean "
                         "is biased low")
        elif (ended == "max_time" and (k < n_excursions or cut)) or ended == "work_bound":
            # (not "257 of the 200 asked": an audit); those in flight may take it past the count asked: not "at 47 of
            # the 32 asked" (a sweep audit); max_work's said also there (a review: a whole count read as cut short)
            limit, after = ((f"max_time = {max_time:g} s", "it") if ended == "max_time" else
                            (f"max_work = {max_work:.3g} lane-steps", "the lanes had computed it"))
            stop_note = (f"{limit} stopped the count at {k} of the {n_excursions} long excursions asked: none started "
                         f"after {after}" if k < n_excursions else
                         f"{limit} stopped the count: none started after {after}, and those then in flight took it to "
                         f"{k} ({n_excursions} asked)")
            stop_note += (f"; {cut} still in flight at twice max_time are left out, so the mean is biased low" if cut
                          else ", those in flight finished")
        elif cut or k < n_excursions:
            stop_note = (f"the loop's bound max_steps = {bound} stopped {k} of the {n_excursions} long excursions asked"
                         + (f", with {cut} in flight: left out, so the mean is biased low" if cut else "")
                         + "; raise max_steps")
        if stop_note is not None:
            warnings.warn(stop_note, DryfricWarning, stacklevel=2)
            notes.append(stop_note)
        ran = n_lanes * int(blocks) * BLOCK  # lane-steps computed, the idle lanes' included
        if ran > max_work:  # those in flight finish past it, unbounded but by max_steps (an audit: 3-10x): said
            note = (f"the count ran {ran:.3g} lane-steps, {ran / max_work:.2g}x max_work = {max_work:.3g}: no long "
                    "excursion started after the lanes had computed it, and those then in flight finished; max_time "
                    "bounds a count's time")
            warnings.warn(note, DryfricWarning, stacklevel=2)
            notes.append(note)
        if k < MIN_RELIABLE_LE:
            note = (f"n_excursions = {k} < {MIN_RELIABLE_LE}: the t CI under-covers at this size (right-skewed "
                    "durations: 0.92-0.93 at ~60 counted, 0.94 from ~160; durations.py)")
            warnings.warn(note, category(note), stacklevel=2)  # a SmallSampleWarning, as the estimator's
            notes.append(note)
        s_sum = float(S.sum())  # exact: int64 sums of steps
        m = s_sum / k
        var = max(float(Q.sum()) - s_sum * m, 0.0) / (k - 1)
        if var == 0:  # all of the same length: a CI of 0 is no interval (a sweep audit: 2 of 2 steps each, +- 0 s)
            note = (f"the {k} long excursions counted all lasted {m:.0f} steps: the CI of 0 is no interval; "
                    "count more (or a finer h)")
            warnings.warn(note, DryfricWarning, stacklevel=2)
            notes.append(note)
        r = LEDuration(mean=h * m, ci=float(t_quantile(0.95, k - 1) * h * math.sqrt(var / k)), n_excursions=k,
                       n_requested=n_excursions, n_lanes=n_lanes, n_truncated=cut, h=float(h), dtype=dtype,
                       lane_steps=int(steps.sum()), loop_steps=ran, max_steps=bound,
                       bridge=bridge, stopped_by=ended, max_time=max_time, seed=seed,
                       key=None if seed is not None else key_id(key), params=params.as_dict(), warnings=tuple(notes),
                       wall_s=time.perf_counter() - t0)
    return noted_late(r, "count") if late and r.stopped_by != "interrupted" else r
