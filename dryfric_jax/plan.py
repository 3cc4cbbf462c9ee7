r"""What a run will do, decided before any simulation: method, step, dtype and work bounds.

:func:`plan_estimate` validates every argument of
:func:`~dryfric_jax.api.estimate_diffusivity` that fixes the run (all but ``key``, ``rtol``,
``max_time`` and ``progress``, which ``estimate_diffusivity`` checks itself) and returns a :class:`Plan`, or raises
``ValueError`` naming the parameter and its valid range.  It is pure Python (no JAX, no chain
is built), so a test can check thousands of parameter sets, and a user can ask whether a run is
feasible before paying for it.

Decisions, in order:

1. the model has a stationary state (:func:`~dryfric_jax.limits.check_recurrent`), and a
   simulable one (:func:`~dryfric_jax.limits.check_simulable`: :math:`\tau_L' \ge 10^{-60}`), whose excursions end
   within float range (:func:`~dryfric_jax.limits.check_duration_in_range`: no h or delta could help);
2. the method (``"auto"``: :mod:`dryfric_jax.cost`), the DI step h (:func:`check_h`) or the
   PDMP grid step delta (:func:`~dryfric_jax.noise.check_delta`);
3. the dtype: the DI and the PDMP fall back to float64 where float32 is not safe
   (:func:`~dryfric_jax.limits.float32_unsafe_reason`,
   :func:`~dryfric_jax.limits.pdmp_float32_unsafe_reason`), and say so in ``notes``;
4. the work: refused if the prediction exceeds ``max_work``
   (:func:`~dryfric_jax.limits.check_work`), and a per-excursion bound ``max_steps``
   (:func:`~dryfric_jax.limits.max_steps_per_excursion`, at most ``max(max_work / lanes, 64)``).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from .cost import choose_method, default_delta, default_delta_note
from .excursions import MAX_LAYOUT, default_block, lanes_for
from .limits import (
    MAX_WORK, check_duration_in_range, check_recurrent, check_simulable, check_work, di_cycle_floor,
    float32_unsafe_reason, max_steps_per_excursion, pdmp_cycle_floor, pdmp_float32_unsafe_reason,
)
from .params import Params, check_params, real_or_none, refuse_traced, rounded_bound, shown
from .pdmp import pdmp_grid_info

METHODS = ("di", "pdmp", "auto")
DTYPES = {"float64": jnp.float64, "float32": jnp.float32}

#: Default step, relative to the fastest deterministic time scale: h = H_REL * min(tau0, tau_L).
#: tau0 sets the stick-slip dynamics, tau_L the explicit viscous relaxation; tau itself needs no
#: resolution because the OU step is exact for any h/tau.  See README "Choosing h".
H_REL = 0.01
#: Largest admissible step: h <= H_MAX_REL * min(tau0, tau_L).
H_MAX_REL = 0.1
#: Smallest admissible step, h >= H_MIN_REL * min(tau0, tau_L): 1e12 steps per tau0, far past any
#: run's work bound.  Without it a step like 5e-324 s made the step count per tau0 inf, and the
#: refusal then named max_work or t instead of h.
H_MIN_REL = 1e-12


def default_h(params: Params) -> float:
    """The default DI step ``H_REL * min(tau0, tau_L)`` in seconds."""
    check_params(params)  # a dict (FIG3) was an AttributeError
    return H_REL * min(params.tau0, params.tau_L)


def h_max(params: Params) -> float:
    check_params(params)
    return H_MAX_REL * min(params.tau0, params.tau_L)


def scalar(x):
    """A 0-d numpy or JAX array of numbers as its Python scalar (README: taken like a Python number;
    ``jnp.array(1000)`` was refused as "n_excursions must be an integer"); anything else as is, a
    ``jax.random`` key and a traced value included."""
    if isinstance(x, np.ndarray) and x.shape == ():
        return x.item()
    if isinstance(x, jax.Array) and x.shape == () and jax.dtypes.issubdtype(x.dtype, np.number):
        try:
            return x.item()
        except jax.errors.ConcretizationTypeError:  # under jit: for the checks to refuse by name
            return x
    return x


def real(x) -> float | None:
    """``x`` as a float if it is a real number (:func:`~dryfric_jax.params.real_or_none`; an int
    beyond float range as +-inf, for the range checks to refuse), else None."""
    x = scalar(x)
    if isinstance(x, int) and not isinstance(x, bool):
        try:
            return float(x)
        except OverflowError:
            return math.inf if x > 0 else -math.inf
    return real_or_none(x)


def check_h(params: Params, h: float) -> float:
    if h is None:
        return default_h(params)
    refuse_traced("h", h, "the range check of the step h")
    hm = h_max(params)
    lo = H_MIN_REL * min(params.tau0, params.tau_L)
    v = real(h)
    if v is None or not (math.isfinite(v) and lo <= v <= hm):
        raise ValueError(f"h must be in [{rounded_bound(lo, lower=True)}, {rounded_bound(hm, lower=False)}] s, i.e. "
                         f"between {H_MIN_REL:g} and {H_MAX_REL:g} times "
                         f"min(tau0, tau_L) (got {shown(h)})")
    return v


def dtype_name(dtype) -> str:
    # jnp.dtype(None) is float64: None is refused, not taken for the default; so is a value (a numpy
    # scalar or array: jnp.dtype(np.float32(nan)) is float32)
    try:
        value = dtype is None or isinstance(dtype, (np.generic, np.ndarray, jnp.ndarray))
        name = dtype if isinstance(dtype, str) else None if value else jnp.dtype(dtype).name
    except TypeError:
        name = None
    if name not in DTYPES:
        raise ValueError(f"dtype must be one of {sorted(DTYPES)} (got {dtype!r})")
    return name


#: largest count of excursions (paths) of a run, and of steps of one excursion: the engine's
#: counters are int64
MAX_COUNT = MAX_STEPS = 1 << 62


def check_count(name, n, lo=2, hi=None, why: str = "") -> int:
    """``n`` as an int (a numpy integer or a 0-d array too); ``ValueError`` naming ``name`` unless it
    is an integer >= ``lo`` (and <= ``hi``); ``why``, if given, follows the range in the message."""
    n = scalar(n)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < lo or (hi is not None and n > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {'2^62' if hi == MAX_COUNT else hi}]"
        raise ValueError(f"{name} must be an integer {rng}{why} (got {shown(n)})")
    return int(n)


MAX_LANES, MAX_BLOCK = 1 << 22, 1024


def check_layout(lanes, block):
    """The engine's layout: ``lanes`` (None: :func:`~dryfric_jax.excursions.lanes_for`) and the
    block size K, integers in [1, 2^22] and [1, 1024] with lanes * K <= 2^28 (a block's normals
    are drawn at once, 2 per lane-step: 2 GiB in float32).  Returns them as ints (None kept)."""
    lanes, block = scalar(lanes), scalar(block)
    for name, v, hi in (("lanes", lanes, MAX_LANES), ("block", block, MAX_BLOCK)):
        if v is None and name == "lanes":
            continue
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= v <= hi:
            raise ValueError(f"{name} must be an integer in [1, {hi}] (got {shown(v)})")
    if lanes is not None and lanes * block > MAX_LAYOUT:
        raise ValueError(f"lanes * block must be <= 2^28 (a block's normals are drawn at once) "
                         f"(got lanes = {lanes}, block = {block})")
    return None if lanes is None else int(lanes), int(block)


#: the engine's peak memory per layout on a CPU, a lower fit (bytes): ``LAYOUT_PEAK_PER_NUMBER`` times a block's random
#: numbers (2 per lane-step, of the dtype's size), plus ``LAYOUT_PEAK_PER_LANE`` a lane, plus ``LAYOUT_PEAK_BASE``
#: (Python, JAX and the compiled code: 0.26 GB after importing them).  Measured peak RSS of
#: ``dryfric estimate --lanes L --block K`` (2026-12-07, stop 91): float64 2.57 GB at L = 2^20, K = 64; 6.50 GB at
#: 2^20, 256; 5.90 GB at 2^18, 1024; 8.96 GB at 2^22, 64 (the fit 1.22 x the numbers + 780 B a lane + 0.44 GB, within
#: 1%); float32 4.39 GB at 2^20, 256 (the fit 3.9 GB: float32 is over it too)
LAYOUT_PEAK_PER_NUMBER, LAYOUT_PEAK_PER_LANE, LAYOUT_PEAK_BASE = 1.2, 768, 0.4e9


def host_memory() -> int | None:
    """This machine's memory in bytes (the smaller of the physical memory and a cgroup v2 limit), None where
    unknown (no ``sysconf``: Windows)."""
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            limit = f.read().strip()
        if limit.isdigit():
            mem = min(mem, int(limit))
    except OSError:
        pass
    return mem if mem > 0 else None


def check_layout_memory(lanes: int, block: int, dtype: str, name: str = "lanes",
                        other: str = " at this block, or a smaller block") -> None:
    """``ValueError`` naming ``name`` when the engine's layout needs more memory than this machine has, by the lower
    fit :data:`LAYOUT_PEAK_PER_NUMBER`, on a CPU (host memory; not checked on other devices, where it was not
    measured); ``other`` ends the advice.  2^22 lanes at K = 64 (float64), which :func:`check_layout` allows,
    peaked at 9 GB: an 8 GB machine would run out of memory, its results with it."""
    mem = host_memory()
    if mem is None or jax.default_backend() != "cpu":
        return
    per_lane = LAYOUT_PEAK_PER_NUMBER * 2 * block * np.dtype(dtype).itemsize + LAYOUT_PEAK_PER_LANE
    need = lanes * per_lane + LAYOUT_PEAK_BASE
    if need > mem:
        most = max(int((mem - LAYOUT_PEAK_BASE) // per_lane), 0)
        raise ValueError(f"{name} = {lanes} at block = {block} ({dtype}) needs at least {need / 2**30:.3g} GiB of "
                         f"memory (a block's 2 random numbers per lane-step, the lanes' state and JAX), more than this "
                         f"machine's {mem / 2**30:.3g} GiB: use at most {most} lanes{other}")


def check_max_work(max_work) -> float:
    """``max_work`` as a float; ``ValueError`` unless it is a finite number >= 1e3."""
    v = real(max_work)
    if v is None or not (math.isfinite(v) and v >= 1e3):
        raise ValueError(f"max_work must be a finite number >= 1e3 (got {shown(max_work)})")
    return v


def check_rtol(rtol) -> float | None:
    """The precision target as a float (None: none); ``ValueError`` unless it is in (0, 1)."""
    v = None if rtol is None else real(rtol)
    if rtol is not None and (v is None or not 0 < v < 1):
        raise ValueError(f"rtol must be in (0, 1) (got {shown(rtol)})")
    return v


def check_max_time(max_time) -> float | None:
    """The time limit in seconds as a float (None: none); ``ValueError`` unless it is > 0 (inf: none)."""
    v = None if max_time is None else real(max_time)
    if max_time is not None and (v is None or not v > 0):
        raise ValueError(f"max_time must be > 0 seconds (got {shown(max_time)})")
    return v


def check_method(method, h=None, delta=None, *, auto: bool = True) -> None:
    """``ValueError`` unless ``method`` is one of :data:`METHODS` and takes the step given (h or delta).  Where the
    caller does not take 'auto' (``auto=False``: brute force), 'auto' is refused and no message offers it (brute
    force's refusal sent the user to a method it then refused, an audit)."""
    if not (isinstance(method, str) and method in METHODS and (auto or method != "auto")):
        ok = "one of " + str(list(METHODS)) if auto else "'di' or 'pdmp' for brute force"
        raise ValueError(f"method must be {ok} (got {shown(method)})")
    alt = " or 'auto'" if auto else ""
    if method == "di" and delta is not None:
        raise ValueError(f"delta must not be given with method 'di': it is the PDMP noise grid step "
                         f"(method 'pdmp'{alt})")
    if method == "pdmp" and h is not None:
        raise ValueError(f"h must not be given with method 'pdmp': it is the DI step (method 'di'{alt})")


def check_settings(*, method="di", h=None, delta=None, dtype="float64", n_excursions=20_000, rtol=None,
                   max_work=MAX_WORK) -> dict:
    """The settings of :func:`plan_estimate` (and ``rtol``) that no parameter point changes, as plain
    values: ``ValueError`` naming the first one that is wrong.  A sweep checks them once, before its
    grid: a wrong setting is no point's refusal.  h and delta are checked only against the bounds
    that hold at every point (h in [1e-12, 0.1]*min(tau0, tau_L) and delta's bound depend on the point)."""
    check_method(method, h, delta)
    steps = {}
    for name, v, rng in (("h", h, f"[{H_MIN_REL:g}, {H_MAX_REL:g}] times min(tau0, tau_L) s"),
                         ("delta", delta, "(0, delta_max) s^-1/2, delta_max depending on tau and gamma_bar")):
        x = None if v is None else real(v)
        if v is not None and (x is None or not (math.isfinite(x) and x > 0)):
            raise ValueError(f"{name} must be in {rng} (got {shown(v)})")
        steps[name] = x
    return dict(method=method, **steps, dtype=dtype_name(dtype),
                n_excursions=check_count("n_excursions", n_excursions, hi=MAX_COUNT), rtol=check_rtol(rtol),
                max_work=check_max_work(max_work))


@dataclass
class Plan:
    """A validated run: what :func:`~dryfric_jax.api.estimate_diffusivity` will simulate."""

    method: str  # "di" or "pdmp" (auto resolved)
    h: float | None  # DI step, s
    delta: float | None  # PDMP grid step, s^-1/2
    grid: dict | None  # pdmp_grid_info (delta_nd, L_X, N, rate_nd)
    dtype: str  # simulation dtype actually used
    reason: str  # why this method
    unit: str  # "steps" or "events"
    per_tau0: float  # steps (events) per tau0
    predicted_work: float = 0.0  # lane-steps (events) predicted for the run: a lower estimate
    min_duration: float = 0.0  # the fast-noise floor on the predicted cycle (tau0): predicted_duration_floor
    max_steps: int = 0  # work bound per excursion
    lanes: int = 0
    block: int = 0  # steps per loop iteration (default_block unless given)
    max_work: float = MAX_WORK
    notes: list = field(default_factory=list)  # e.g. float32 -> float64


def choose(params: Params, method: str, h, delta, dtype, *, excursions: bool = False) -> Plan:
    """Steps 1-3 of the module docstring (no work bounds): method, h or delta, dtype.  ``excursions``: the plan is
    for excursions, which must end (:func:`~dryfric_jax.limits.check_duration_in_range`, before any h or delta);
    brute force's fixed horizon need not."""
    check_params(params)
    check_method(method, h, delta)
    dtype = dtype_name(dtype)
    check_recurrent(params.tau_L_nd, params.gamma_bar_nd)
    check_simulable(params.tau_L_nd, params.tau_L, params.tau0)
    if excursions:
        check_duration_in_range(params.tau_nd, params.tau_L_nd, params.gamma_bar_nd)
    d = real(delta)
    if d is not None and math.isfinite(d):  # as a float (an int of 400 digits stays itself, for check_delta to show)
        delta = d
    reason = f"method {method!r} requested"
    defaulted = delta is None  # the PDMP's default delta carries a caveat where it was not validated
    if method == "auto":
        h_c = check_h(params, h)
        d_c = default_delta(params) if delta is None else delta
        try:
            pdmp_grid_info(params, d_c)  # validates delta
        except ValueError as e:
            if not defaulted:  # the caller's delta: refused by name
                raise
            # the default grid cannot be built (tau' tiny: 8 noise sds need > 2^31 points): the DI, which needs
            # none (this refused the run, saying "use method 'di'", where auto should have chosen it)
            method, reason, h, delta = "di", f"the PDMP cannot run here ({e}); chose di", h_c, None
        else:
            method, reason = choose_method(params, h_c, d_c)
            h, delta = (h_c, None) if method == "di" else (None, d_c)
    if method == "di":
        h = check_h(params, h)
        unsafe = float32_unsafe_reason(h / params.tau, h / params.tau0, params.tau_nd, params.tau_L_nd,
                                       params.gamma_bar_nd)
        plan = Plan("di", h, None, None, dtype, reason, "steps", params.tau0 / h)
    else:
        delta = default_delta(params) if defaulted else delta
        grid = pdmp_grid_info(params, delta)
        unsafe = pdmp_float32_unsafe_reason(params.tau_L_nd, grid["rate_nd"], params.gamma_bar_nd)
        # every noise jump is an event: the jump rate Lambda' is a lower estimate of the events per tau0
        plan = Plan("pdmp", None, grid["delta"], grid, dtype, reason, "events", grid["rate_nd"])
        if defaulted and (note := default_delta_note(params)):
            plan.notes.append(note)
    if dtype == "float32" and unsafe:
        plan.notes.append(f"float32 is not safe here ({unsafe}): simulated in float64")
        plan.dtype = "float64"
    return plan


def predicted_duration_floor(params: Params, plan: Plan) -> float:
    r"""The fast-noise floor (:math:`\tau_0`) on the predicted mean cycle of ``plan``'s method: the DI's
    regeneration cycle (:func:`~dryfric_jax.limits.di_cycle_floor`, from h/tau) or the PDMP's long excursion
    (:func:`~dryfric_jax.limits.pdmp_cycle_floor`, from its grid step).
    :func:`~dryfric_jax.limits.log_duration_scale` alone, the noise's passage time, vanishes for fast noise where the
    cycles last several to tens of :math:`\tau_0`."""
    if plan.method == "di":
        return di_cycle_floor(params.tau_nd, params.tau_L_nd, plan.h / params.tau0)
    return pdmp_cycle_floor(params.tau_nd, params.tau_L_nd, plan.grid["delta_nd"])


def plan_estimate(params: Params, *, method: str = "di", h: float | None = None, delta: float | None = None,
                  dtype="float64", n_excursions: int = 20_000, max_work: float = MAX_WORK,
                  max_steps: int | None = None, lanes: int | None = None, chunk_lanes: int | None = None,
                  block: int | None = None) -> Plan:
    """Validate a long-excursion run and fix its method, step, dtype and work bounds.

    The arguments of :func:`~dryfric_jax.api.estimate_diffusivity` that fix the run (not ``key``,
    ``rtol``, ``max_time``, ``progress``).  Raises ``ValueError`` (naming
    the parameter and its range) for anything it would refuse, including a run predicted to need
    more than ``max_work`` lane-steps (events), counting an excursion per lane at least (every lane finishes
    the one it is in).
    """
    n_excursions = check_count("n_excursions", n_excursions, hi=MAX_COUNT)  # the engine's counters are int64
    max_work = check_max_work(max_work)
    lanes, block1 = check_layout(lanes, 1 if block is None else block)  # a default K is fitted to the lanes below
    if chunk_lanes is not None:
        chunk_lanes = check_count("chunk_lanes", chunk_lanes, 1)
    plan = choose(params, method, h, delta, dtype, excursions=True)
    nd = (params.tau_nd, params.tau_L_nd, params.gamma_bar_nd)
    plan.min_duration = predicted_duration_floor(params, plan)
    plan.lanes = int(lanes or lanes_for(n_excursions, chunk_lanes))
    # every lane runs its round's budget and finishes the excursion it is in, so the run closes about one or more per
    # lane (4096 lanes asked for 200 closed 3205; 2^18 asked for 2000 ran 201,925, and 2^22 at the default point
    # needed some 5e10 lane-steps against a predicted 1.2e8: an audit)
    plan.predicted_work = check_work(*nd, plan.per_tau0, n_excursions, max_work, plan.unit, plan.min_duration,
                                     lanes=plan.lanes)
    if plan.lanes >= 2 * n_excursions:  # said where it at least doubles the run (4096 lanes for 4095 said "~1x")
        plan.notes.append(f"lanes = {plan.lanes} > n_excursions = {n_excursions}: every lane finishes the excursion "
                          f"it is in, so the run closes about one or more per lane (~{plan.lanes / n_excursions:.3g}x "
                          "the excursions asked for, and their work); fewer lanes keep to n_excursions")
    plan.block = int(default_block(plan.method, plan.lanes) if block is None else block1)
    check_layout(plan.lanes, plan.block)
    check_layout_memory(plan.lanes, plan.block, plan.dtype)
    plan.max_work = max_work
    if max_steps is None:
        plan.max_steps = max_steps_per_excursion(*nd, plan.per_tau0, cap=max(max_work / plan.lanes, 64),
                                                 min_duration=plan.min_duration)
    else:  # the step counters are int64
        plan.max_steps = check_count("max_steps", max_steps, 1, hi=MAX_STEPS)
    return plan
