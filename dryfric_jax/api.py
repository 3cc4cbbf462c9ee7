"""Public entry points: ``estimate_diffusivity`` (long excursions) and ``bruteforce_diffusivity``.

Both take physical :class:`~dryfric_jax.params.Params`, simulate the nondimensional DI chain and
return physical numbers (D in m^2/s, M0 in m/s, durations in s) with 95% CIs.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import asdict, dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from .bruteforce import simulate_bruteforce
from .di import make_di_model
from .estimators import MIN_RELIABLE_N, WEAK_DAMPING_TAU_L, bruteforce_estimates, long_excursion_estimates
from .excursions import simulate_long_excursions
from .params import Params, check_positive

METHODS = ("di",)
DTYPES = {"float64": jnp.float64, "float32": jnp.float32}

#: Default step, relative to the fastest deterministic time scale: h = H_REL * min(tau0, tau_L).
#: tau0 sets the stick-slip dynamics, tau_L the explicit viscous relaxation; tau itself needs no
#: resolution because the OU step is exact for any h/tau.  See README "Choosing h".
H_REL = 0.01
#: Largest admissible step: h <= H_MAX_REL * min(tau0, tau_L).
H_MAX_REL = 0.1
#: Work bound per excursion, in units of max(tau0, tau): excursions longer than this are
#: truncated and reported.
MAX_TIME_REL = 1.0e4


class DryfricWarning(UserWarning):
    """A result that should be read with care (too few excursions, truncated excursions)."""


def default_h(params: Params) -> float:
    """The default DI step ``H_REL * min(tau0, tau_L)`` in seconds."""
    return H_REL * min(params.tau0, params.tau_L)


def h_max(params: Params) -> float:
    return H_MAX_REL * min(params.tau0, params.tau_L)


def check_h(params: Params, h: float) -> float:
    if h is None:
        return default_h(params)
    hm = h_max(params)
    h_ok = isinstance(h, (int, float, np.floating)) and math.isfinite(h) and 0 < h <= hm
    if not h_ok:
        raise ValueError(f"h must be in (0, {hm:.4g}] s, i.e. at most 0.1*min(tau0, tau_L) (got {h!r})")
    return float(h)


def _dtype(dtype) -> str:
    name = dtype if isinstance(dtype, str) else jnp.dtype(dtype).name
    if name not in DTYPES:
        raise ValueError(f"dtype must be one of {sorted(DTYPES)} (got {dtype!r})")
    return name


def _key(key):
    if isinstance(key, (int, np.integer)):
        if key < 0:
            raise ValueError(f"seed must be a non-negative integer (got {key})")
        return jax.random.key(int(key)), int(key)
    if key is None:
        return jax.random.key(0), 0
    return key, None


def _check_method(method):
    if method not in METHODS:
        raise ValueError(f"method must be one of {list(METHODS)} (got {method!r})")


@dataclass
class EstimateResult:
    """Long-excursion estimate (physical units; CIs are 95% half-widths)."""

    D: float
    D_ci: float
    M0: float
    M0_ci: float
    mean_duration: float
    n_excursions: int
    n_truncated: int
    method: str
    h: float
    dtype: str
    seed: int | None
    wall_s: float
    lane_steps_per_s: float
    params: dict
    mean_duration_ci: float = 0.0
    lane_utilization: float = 0.0
    ci_level: float = 0.95
    rtol: float | None = None
    stopped_by: str = "n_excursions"
    warnings: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class BruteForceResult:
    """Fixed-horizon estimate (physical units; CIs are 95% half-widths)."""

    D_t: float
    D_t_ci: float
    M0_t: float
    M0_t_ci: float
    t: float
    n_paths: int
    method: str
    h: float
    dtype: str
    seed: int | None
    wall_s: float
    lane_steps_per_s: float
    params: dict
    burn_in: float = 0.0
    ci_level: float = 0.95

    def to_dict(self) -> dict:
        return asdict(self)


def estimate_diffusivity(params: Params, key=0, *, method: str = "di", h: float | None = None,
                         n_excursions: int = 20_000, dtype="float64", lanes: int | None = None,
                         chunk_lanes: int = 4096, block: int = 32, max_steps: int | None = None,
                         rtol: float | None = None, max_time: float | None = None,
                         progress=None) -> EstimateResult:
    r"""Estimate D and M0 from N i.i.d. long excursions (paper sections 4-6).

    Args:
        params: physical parameters.
        key: a ``jax.random`` key or a non-negative integer seed.
        method: ``"di"`` (differential inclusion with exact OU step).
        h: DI step in seconds; default :func:`default_h` = 0.01 min(tau0, tau_L).
        n_excursions: N >= 2 (the run ends with slightly more: every lane finishes its in-flight
            excursion); below :data:`MIN_RELIABLE_N` the CI under-covers and a
            :class:`DryfricWarning` is issued (also for weak viscous damping, see README).
        dtype: ``"float64"`` or ``"float32"`` for the simulation (statistics are float64).
        lanes, chunk_lanes, block: engine layout (do not change the estimate's law).
        max_steps: work bound per excursion (default 1e4 max(tau0, tau)/h).
        rtol: precision target: after the first ``n_excursions``, keep running rounds until
            the 95% half-width of D is at most ``rtol * |D|``.
        max_time: stop after the round that passes this many seconds (``stopped_by`` says so).
        progress: optional callback ``progress(dict)`` after every round (N, D, D_ci so far).

    A Ctrl-C between rounds returns what the completed rounds reached (``stopped_by =
    "interrupted"``); nothing already simulated is lost.

    Returns:
        :class:`EstimateResult`: D, M0 with 95% CI half-widths, mean excursion duration, counts.
    """
    _check_method(method)
    h = check_h(params, h)
    dname = _dtype(dtype)
    if not isinstance(n_excursions, (int, np.integer)) or n_excursions < 2:
        raise ValueError(f"n_excursions must be an integer >= 2 (got {n_excursions!r})")
    key, seed = _key(key)
    if max_steps is None:
        max_steps = int(min(math.ceil(MAX_TIME_REL * max(params.tau0, params.tau) / h), 2**62))
    if rtol is not None and not (isinstance(rtol, (int, float)) and math.isfinite(rtol) and 0 < rtol < 1):
        raise ValueError(f"rtol must be in (0, 1) (got {rtol!r})")
    if max_time is not None and not (isinstance(max_time, (int, float)) and max_time > 0):
        raise ValueError(f"max_time must be > 0 seconds (got {max_time!r})")
    model = make_di_model(params, h, DTYPES[dname])

    def snapshot(st):
        if st.n_excursions < 2:
            return None
        return long_excursion_estimates(st.total())

    def more(st):  # precision target: excursions still wanted, from the CI's N^{-1/2} scaling
        e = snapshot(st)
        if e is None:
            return st.n_excursions + 2
        rel = e["D_ci"] / max(abs(e["D"]), 1e-300)
        return 0 if rel <= rtol else int(math.ceil(e["n_excursions"] * ((rel / rtol) ** 2 * 1.1 - 1)))

    def report(st):
        if progress is not None:
            e = snapshot(st) or {}
            progress(dict(n_excursions=st.n_excursions, D=e.get("D", math.nan) * params.D0,
                          D_ci=e.get("D_ci", math.nan) * params.D0, target=n_excursions, rtol=rtol))

    t0 = time.perf_counter()
    sim, stopped = simulate_long_excursions(model, key, int(n_excursions), lanes=lanes, chunk_lanes=chunk_lanes,
                                            block=block, max_steps=max_steps, more=more if rtol else None,
                                            max_time=max_time, progress=report)
    wall = time.perf_counter() - t0
    # a lane the block bound stopped (never expected) lost its in-flight excursion: count it too
    n_truncated = sim.n_truncated + sim.n_unfinished
    notes = []
    if stopped == "interrupted":
        notes.append(f"interrupted: result of the {sim.n_excursions} excursions completed before Ctrl-C")
    elif stopped == "max_time":
        notes.append(f"max_time reached ({max_time} s) before the "
                     + (f"target rtol = {rtol}" if rtol else f"{n_excursions} excursions"))
    if n_truncated:
        notes.append(f"{n_truncated} of {n_truncated + sim.n_excursions} excursions hit the work bound "
                     f"({max_steps} steps) and are excluded: the estimate is biased low")
    if sim.n_excursions < 2:
        raise RuntimeError("fewer than 2 complete excursions: " + "; ".join(notes))
    if sim.n_excursions < MIN_RELIABLE_N:
        notes.append(f"n_excursions = {sim.n_excursions} < {MIN_RELIABLE_N}: the delta-method CI "
                     "under-covers at this size (heavy-tailed excursions)")
    if params.tau_L_nd > WEAK_DAMPING_TAU_L:
        notes.append(f"tau_L/tau0 = {params.tau_L_nd:.3g} > {WEAK_DAMPING_TAU_L:g} (weak or no viscous damping): "
                     "the 95% CI for D covers only ~90% (measured), misses are on the low side")
    for n in notes:
        warnings.warn(n, DryfricWarning, stacklevel=2)
    e = long_excursion_estimates(sim.total())
    return EstimateResult(
        D=float(e["D"] * params.D0), D_ci=float(e["D_ci"] * params.D0), M0=float(e["M0"] * params.v0),
        M0_ci=float(e["M0_ci"] * params.v0),
        mean_duration=float(e["mean_duration"]) * params.tau0, n_excursions=sim.n_excursions,
        n_truncated=n_truncated, method=method, h=h, dtype=dname, seed=seed, wall_s=wall,
        lane_steps_per_s=sim.useful_steps / wall, params=params.as_dict(),
        mean_duration_ci=float(e["mean_duration_ci"]) * params.tau0,
        lane_utilization=sim.useful_steps / max(sim.slot_steps, 1), rtol=rtol, stopped_by=stopped,
        warnings=notes)


def bruteforce_diffusivity(params: Params, key=0, *, t: float, n_paths: int, method: str = "di",
                           h: float | None = None, burn_in: float = 0.0, dtype="float64",
                           block: int = 32, chunk_lanes: int = 4096) -> BruteForceResult:
    r"""Brute-force :math:`\hat D^t_{N'}` and :math:`\hat M_0^t` on the horizon ``t`` (s).

    Paths start at :math:`(x_\Delta, 0)`; ``burn_in`` seconds are simulated first and not counted.
    The bias is O(1/t): pick t long against the velocity correlation time.
    """
    _check_method(method)
    h = check_h(params, h)
    dname = _dtype(dtype)
    check_positive("t", t)
    if not (isinstance(burn_in, (int, float)) and math.isfinite(burn_in) and burn_in >= 0):
        raise ValueError(f"burn_in must be a finite number >= 0 (got {burn_in!r})")
    if not isinstance(n_paths, (int, np.integer)) or n_paths < 2:
        raise ValueError(f"n_paths must be an integer >= 2 (got {n_paths!r})")
    if t < h:
        raise ValueError(f"t must be >= h = {h:.4g} s (got {t!r})")
    key, seed = _key(key)
    model = make_di_model(params, h, DTYPES[dname])
    t0 = time.perf_counter()
    U, t_nd = simulate_bruteforce(model, key, int(n_paths), round(t / h), burn_in_steps=round(burn_in / h),
                                  block=block, chunk_lanes=chunk_lanes)
    wall = time.perf_counter() - t0
    e = bruteforce_estimates(U, t_nd)
    steps = n_paths * (t_nd + burn_in / params.tau0) / float(model.h)
    return BruteForceResult(
        D_t=float(e["D_t"] * params.D0), D_t_ci=float(e["D_t_ci"] * params.D0), M0_t=float(e["M0_t"] * params.v0),
        M0_t_ci=float(e["M0_t_ci"] * params.v0), t=t_nd * params.tau0, n_paths=int(n_paths), method=method, h=h,
        dtype=dname, seed=seed, wall_s=wall, lane_steps_per_s=steps / wall, params=params.as_dict(),
        burn_in=burn_in)
