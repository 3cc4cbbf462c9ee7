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
then moving) whose direction differs from the previous release's.  From its first such change to
its :math:`(n_{1/2} + 1)`-th it holds :math:`n_{1/2}` whole HLEs (:math:`n_{1/2}` even: as many + as -), so

.. math::
    d_l = \frac{2 h\,(n_b - n_a)}{n_{1/2}}

is the mean of :math:`n_{1/2}/2` i.i.d. long-excursion durations, and the lanes' :math:`d_l` are i.i.d.:
their mean, with a 95% CI of :math:`t_{L-1}\,\mathrm{sd}/\sqrt{L}` (Student's quantile,
:func:`~dryfric_jax.estimators.t_quantile`). The durations are right-skewed, so with few excursions in all
the CI covers less than 95%: measured at Gamma = 10, tau = 0.125 s over 1000 replicates (against a pooled
0.5353 +- 0.0016 s), 0.929 +- 0.008 with 32 lanes x 2 HLEs (Fig. 3's floor; 0.913 with 1.96 in place of
:math:`t_{31}`), 0.943 +- 0.007 with 64 x 2, 0.932 with 32 x 4 and, with 1.96, 0.943 with 32 x 20 (the
default 20 HLEs). Each lane runs a fixed number of HLEs, not a fixed time, so nothing is cut at a horizon (a
fixed horizon would weigh short excursions more). A V that lands on 0 for one step while passing through it
(the force beyond the threshold) is not a release: counting those (a first version) ended half excursions
early, 15 SE below the PDMP at Gamma = 10, tau = 0.125 s, h/16, and further below as h fell. In discrete
time a release is still not exactly at the threshold (X overshoots it), so the count has a bias that falls
with h: at that point 0.548, 0.479, 0.452 s (+- 0.009) at h, h/4, h/16 against the PDMP's 0.442
(``tests/test_durations.py``). Where :math:`\tau \ll h` releases happen at any X and the count is not the
paper's quantity: below :data:`MIN_TAU_STEPS` steps per :math:`\tau` a :class:`~dryfric_jax.DryfricWarning`
says so; Fig. 3 has :math:`\tau/h \ge 187` at the D estimator's default h, 8 times that at the count's
(:data:`H_DIV`).

Loops are bounded: a lane that has not reached its count after ``max_steps`` steps is counted in
``n_truncated`` and left out of the mean (which it would have raised: it is biased low then, and
the result says so).
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from . import rng
from ._version import __version__
from .api import DryfricWarning, _key, _Record, _with_warnings, key_id
from .di import make_di_model
from .excursions import BLOCK, block_keys
from .estimators import t_quantile
from .limits import MAX_WORK, check_work
from .params import Params
from .plan import MAX_LANES, check_count, check_max_work, choose, default_h


@dataclass(frozen=True)
class LEDuration(_Record):
    """Mean duration (s) of the paper's long excursion of the DI, its 95% CI half-width, and what made it;
    ``print`` shows :meth:`summary` and the warnings, ``to_dict``/``to_json`` every field (what ``dryfric
    duration --json`` prints).  The same seed (key) and settings give the same numbers to the last bit."""

    mean: float
    ci: float
    n_lanes: int  # lanes that reached their count
    n_half: int  # HLEs per lane
    n_truncated: int  # lanes stopped by max_steps (left out: the mean is then biased low)
    h: float
    dtype: str  # the chain's: float32 where asked and safe (else float64, with a warning)
    lane_steps: int  # steps the lanes ran until each reached its count (or its bound), all lanes
    loop_steps: int  # steps computed: lanes x the slowest lane's, as a lane that finished stands still in the loop
    max_steps: int = 0  # each lane's bound (whole blocks of 128)
    seed: int | None = None  # None for a jax.random key
    key: str | None = None  # a key-made run's key (api.key_id); None for a seed
    params: dict = field(default_factory=dict)
    version: str = __version__
    warnings: tuple = ()  # every note the run issued (also issued as DryfricWarning)
    wall_s: float = field(default=0.0, compare=False)

    def summary(self) -> str:
        """The mean with its CI, the lanes behind it, the step and what made it (what ``dryfric duration``
        prints)."""
        rel = f"  ({100 * self.ci / self.mean:.1f}%)" if self.mean else ""
        return (f"mean long-excursion duration = {self.mean:.6g} ± {self.ci:.2g} s{rel}   (95% CI, Student t over "
                f"the lanes)\n{self.n_lanes} lanes x {self.n_half} half excursions (releases counted), "
                f"{self.n_truncated} lanes truncated, h = {self.h:.3g} s, {self.dtype}, "
                + (f"seed {self.seed}" if self.key is None else f"key {self.key}")
                + f"\nwall {self.wall_s:.1f} s, {self.loop_steps:.3g} lane-steps computed "
                f"({self.lane_steps:.3g} needed by the lanes)")

    def __str__(self) -> str:
        return _with_warnings(self.summary(), self.warnings)


def _lane_loop(model, keys, n_half, max_blocks, block: int):
    dt = model.h.dtype
    lanes = keys.shape[0]
    x0 = jax.vmap(lambda k: jax.random.normal(jax.random.fold_in(k, 2**31 - 1), (), dt))(keys)
    sd = jnp.sqrt((model.ou.L21.astype(jnp.float64) ** 2 + model.ou.L22.astype(jnp.float64) ** 2)
                  / (1.0 - model.ou.m2.astype(jnp.float64) ** 2)).astype(dt)  # the X chain's stationary sd
    zero_i = jnp.zeros(lanes, jnp.int32)
    zero_n = jnp.zeros(lanes, jnp.int64)
    # X, V, whether V was 0 a step before, last release direction (0: none yet), changes counted, step index,
    # step of the first change, of the last
    carry = (x0 * sd, jnp.zeros(lanes, dt), jnp.zeros(lanes, bool), zero_i, zero_i, zero_n, zero_n, zero_n)

    def step(z1, z2, c):
        X, V, stuck, last, K, n, na, nb = c
        done = K > n_half
        _, Xn, Vn, _ = model.move(X, V, z1, z2)
        s = jnp.sign(Vn).astype(jnp.int32)
        release = stuck & (V == 0) & (Vn != 0)  # stuck a whole step before: not a pass through 0
        change = release & (last != 0) & (s != last) & ~done
        n1 = n + 1
        na = jnp.where(change & (K == 0), n1, na)
        nb = jnp.where(change & (K == n_half), n1, nb)
        K = K + change.astype(jnp.int32)
        keep = lambda new, old: jnp.where(done, old, new)  # noqa: E731  (a finished lane stands still)
        return (keep(Xn, X), keep(Vn, V), keep(V == 0, stuck), keep(jnp.where(release, s, last), last), K, keep(n1, n),
                na, nb)

    def body(bc):
        b, c = bc
        z1, z2 = rng.normals(block_keys(keys, b), block, 2, dt)
        c = jax.lax.fori_loop(0, block, lambda i, cc: step(z1[i], z2[i], cc), c)
        return b + 1, c

    def cond(bc):
        b, c = bc
        return (b < max_blocks) & jnp.any(c[4] <= n_half)

    b, c = jax.lax.while_loop(cond, body, (jnp.int32(0), carry))
    return c[4] > n_half, c[7] - c[6], c[5], b


# n_half and the bound are traced: a figure's points differ in them and share one compiled loop per lane count
_run = jax.jit(_lane_loop, static_argnames=("block",))
#: the count's default step is default_h / H_DIV (near the paper's h = 1e-4 s at Fig. 3's point), as Fig. 3's: its
#: bias falls slowly with h.  At Fig. 3's point the DI's mean duration was 4.50, 4.24, 4.15 and 4.09 s (+- 0.05) at
#: 4, 1, 1/4 and 1/16 times default_h, the PDMP's 4.17, 4.14 and 4.11 (+- 0.035) at delta = 0.125, 0.0625, 0.03125;
#: at Gamma = 10, tau = 0.125 s 0.68, 0.55, 0.48, 0.45 (+- 0.01) against 0.442; at Gamma = 7.74, tau = 1 s 10.01 and
#: 10.03 (+- 0.25) at 1/8 and 1/32 against the PDMP's 10.19 (+- 0.06) at delta = 0.0156 (RESULTS.md)
H_DIV = 8
#: steps per tau below which a warning says the count is not the paper's long excursion.  The count's bias is
#: already +24% at tau/h = 187 (Gamma = 10, tau = 0.125 s, the default h), +2.4% at 746 (Fig. 3's point)
MIN_TAU_STEPS = 10
#: each lane's bound in steps: whole blocks, counted in int32 and folded into its key
MAX_STEPS = (2**31 - 2) * BLOCK


def default_duration_h(params: Params) -> float:
    """The count's default step in seconds: :func:`~dryfric_jax.plan.default_h` / :data:`H_DIV`."""
    return default_h(params) / H_DIV


def di_long_excursion_duration(params, key, h: float | None = None, n_lanes: int = 256, n_half: int = 20,
                               max_steps: int = 10**8, dtype: str = "float64",
                               max_work: float = MAX_WORK) -> LEDuration:
    r"""Mean duration of the paper's long excursion of the DI at step ``h`` (module docstring), in seconds.

    Args:
        params: :class:`~dryfric_jax.Params`.
        key: a ``jax.random`` key or an integer seed in [0, 2^62]; lane l uses ``split(key, n_lanes)[l]``,
            its block b ``fold_in(lane_key, b)``.
        h: DI step in seconds (default :func:`default_duration_h`, :data:`H_DIV` times finer than the D
            estimator's :func:`~dryfric_jax.plan.default_h`: the count's bias falls slowly with h).
        n_lanes: independent lanes, an integer in [2, 2^22] (the CI is their spread).
        n_half: HLEs per lane, an even integer >= 2.
        max_steps: bound on each lane's steps, an integer in [1, :data:`MAX_STEPS`] (rounded up to whole
            blocks of 128).
        dtype: ``"float64"`` or ``"float32"`` (or the dtype), the chain's; float32 where it is not safe runs in
            float64 with a :class:`~dryfric_jax.DryfricWarning`, as :func:`~dryfric_jax.estimate_diffusivity` does.
        max_work: a run whose predicted lane-steps (:func:`~dryfric_jax.limits.check_work`, for the
            ``n_lanes * n_half / 2`` long excursions) exceed it is refused before it starts, as the estimator's
            (h = 1e-10 s at Fig. 3's point would run ~15 min to its bound, then fail: an audit).

    ``ValueError`` naming the argument, also where the estimator refuses the parameters (tau_L = inf with
    :math:`|\bar\gamma| \ge \Delta`: the particle runs away; it gave a number here, 9 of 32 lanes truncated);
    the result's ``n_truncated`` counts lanes stopped by ``max_steps``.
    """
    t0 = time.perf_counter()
    if h is None and isinstance(params, Params):  # a non-Params is refused by choose, by name
        h = default_duration_h(params)
    plan = choose(params, "di", h, None, dtype)  # the estimator's checks: a stationary state, a simulable tau_L,
    key, seed = _key(key)  # h, the dtype (float32 only where safe)
    n_lanes = check_count("n_lanes", n_lanes, 2, MAX_LANES)
    n_half = check_count("n_half", n_half, 2, 2**30, " (HLEs per lane)")
    if n_half % 2:
        raise ValueError(f"n_half must be even, as many +HLEs as -HLEs (got {n_half})")
    max_steps = check_count("max_steps", max_steps, 1, MAX_STEPS, " (blocks of 128 steps counted in 32 bits)")
    h, dtype = plan.h, plan.dtype
    max_work = check_max_work(max_work)
    try:
        check_work(params.tau_nd, params.tau_L_nd, params.gamma_bar_nd, params.tau0 / h, n_lanes * n_half // 2,
                   max_work)
    except ValueError as e:
        raise ValueError(f"{e} (here the excursions are n_lanes x n_half / 2: lower n_lanes or n_half)") from None
    notes = plan.notes + ([f"tau/h = {params.tau / h:.3g} < {MIN_TAU_STEPS}: the noise decorrelates within a few "
                           "steps, so releases happen at any X and the count of their changes of direction is not "
                           "the paper's long excursion (threshold to threshold); lower h"]
                          if params.tau / h < MIN_TAU_STEPS else [])
    for note in notes:
        warnings.warn(note, DryfricWarning, stacklevel=2)
    model = make_di_model(params, h, jnp.dtype(dtype))
    max_blocks = -(-max_steps // BLOCK)
    bound = max_blocks * BLOCK  # the bound used: max_steps rounded up to whole blocks
    done, span, steps, blocks = (np.asarray(a) for a in _run(model, jax.random.split(key, n_lanes),
                                                             jnp.int32(n_half), jnp.int32(max_blocks), block=BLOCK))
    d = 2.0 * span[done] * h / n_half
    k = int(done.sum())
    if k < 2:  # no mean or no spread: say why rather than return a NaN
        raise ValueError(f"max_steps = {bound} is too small here: {k} of {n_lanes} lanes ran {n_half} half "
                         f"excursions within it (at least 2 must); raise max_steps or lower n_half")
    if k < n_lanes:
        note = (f"{n_lanes - k} of {n_lanes} lanes stopped by max_steps = {bound} before their {n_half} half "
                "excursions: left out, so the mean is biased low; raise max_steps")
        warnings.warn(note, DryfricWarning, stacklevel=2)
        notes.append(note)
    ci = t_quantile(0.95, k - 1) * d.std(ddof=1) / math.sqrt(k)
    return LEDuration(mean=float(d.mean()), ci=float(ci), n_lanes=k, n_half=n_half, n_truncated=n_lanes - k,
                      h=float(h), dtype=dtype, lane_steps=int(steps.sum()), loop_steps=n_lanes * int(blocks) * BLOCK,
                      max_steps=bound, seed=seed, key=None if seed is not None else key_id(key),
                      params=params.as_dict(), warnings=tuple(notes), wall_s=time.perf_counter() - t0)
