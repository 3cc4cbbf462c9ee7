r"""Resumable sweeps of D and M0 over a grid of parameters.

:func:`run_sweep` estimates D and M0 (with their 95% CIs) at every point of a grid and writes
each finished point to a JSON Lines file **atomically** (the whole file is rewritten to a
temporary file in the same directory and renamed over the old one, so a kill at any moment
leaves either the old or the new file, never a torn line).  Each record carries the point's
parameters, the settings that determine its result, its seed and the package version.

Resuming: a point whose record (same parameters and settings) is already in the file is not
recomputed; new points are appended.  The seed of a point is derived from the sweep seed and the
point itself (not from its position in the grid), so adding points to a grid never changes the
others, and a resumed sweep gives bit-identical records.

Every point is planned first (:func:`~dryfric_jax.plan.plan_estimate`): a grid with an invalid
or infeasible point is refused before anything is simulated.
"""
from __future__ import annotations

import itertools
import json
import math
import sys
import time
import warnings
import zlib

from . import __version__
from .api import DryfricWarning, ProjectionWarning, check_seed, estimate_diffusivity
from .limits import MAX_WORK
from .outfiles import check_writable, read_records, write_records
from .params import FIG3, Params
from .plan import plan_estimate

PARAM_KEYS = ("Gamma", "Delta", "tau", "tau_L", "gamma_bar")
#: settings that determine a point's result (with its parameters and seed)
SETTING_KEYS = ("method", "h", "delta", "dtype", "n_excursions", "rtol", "max_work")


def grid(**axes) -> list[dict]:
    """The Cartesian product of the given axes (lists) as parameter dicts, in a stable order."""
    names = [k for k in PARAM_KEYS if k in axes]
    unknown = set(axes) - set(PARAM_KEYS)
    if unknown:
        raise ValueError(f"sweep axes must be among {list(PARAM_KEYS)} (got {sorted(unknown)})")
    return [dict(zip(names, vals)) for vals in itertools.product(*(axes[k] for k in names))]


def _canon(x):
    return "inf" if isinstance(x, float) and math.isinf(x) else repr(float(x)) if isinstance(x, (int, float)) else x


def _ident(seed: int, params: dict, settings: dict) -> str:
    """Canonical text of a point: sweep seed, parameters, and the settings that determine it."""
    return json.dumps([seed, {k: _canon(params[k]) for k in PARAM_KEYS},
                       {k: _canon(settings.get(k)) for k in SETTING_KEYS}], sort_keys=True)


def point_seed(seed: int, params: dict, settings: dict) -> int:
    """A 31-bit seed from the sweep seed and the point (stable under grid edits)."""
    return zlib.crc32(_ident(seed, params, settings).encode()) & 0x7FFFFFFF


def read_results(path: str) -> list[dict]:
    """The records of a sweep file (empty if it does not exist); refuses a file that is not one."""
    return read_records(path, ("params", "settings", "sweep_seed"),
                        "out must be a dryfric sweep file (JSON Lines); {path!r} line {line} is not a sweep record")


def _check_points(points) -> list[dict]:
    """``points`` as a list of parameter dicts; ``ValueError`` naming what is wrong (a TypeError
    from ``Params`` or a dict merge before)."""
    if isinstance(points, (str, bytes, dict)) or not hasattr(points, "__iter__"):
        raise ValueError(f"points must be a list of parameter dicts, e.g. sweep.grid(Gamma=[1, 2]) "
                         f"(got {type(points).__name__})")
    points = list(points)
    for i, pt in enumerate(points):
        if not isinstance(pt, dict):
            raise ValueError(f"points[{i}] must be a dict of parameters (got {type(pt).__name__})")
        unknown = sorted(set(pt) - set(PARAM_KEYS))
        if unknown:
            raise ValueError(f"points[{i}] has unknown parameters {unknown} (known: {list(PARAM_KEYS)})")
    return points


def _at_point(show, pt):
    """``show`` (a ``warnings.showwarning``) with the sweep point appended to the message."""
    def at(message, category, *args, **kw):
        show(f"{message} [at sweep point {json.dumps(pt)}]", category, *args, **kw)
    return at


def run_sweep(points: list[dict], out: str, *, seed: int = 0, method: str = "di", h=None, delta=None,
              dtype: str = "float64", n_excursions: int = 20_000, rtol=None, max_work: float = MAX_WORK,
              progress=None) -> dict:
    r"""Estimate D and M0 at every point, one JSON line per finished point in ``out``.

    Args:
        points: parameter dicts (physical units); missing keys take the Fig. 3 values.
        out: the JSON Lines results file (created, or resumed if it exists).
        seed: the sweep seed; point seeds come from :func:`point_seed`.
        method, h, delta, dtype, n_excursions, rtol, max_work: as in
            :func:`~dryfric_jax.api.estimate_diffusivity`, the same for every point.
        progress: optional ``progress(done, total, record)`` after each point (and once at start).

    The points' warnings are kept in their records, not shown; a
    :class:`~dryfric_jax.api.ProjectionWarning` (max_work will end a point early) is shown at
    once, with the point.

    Returns:
        ``dict(computed=k, skipped=s, total=n, interrupted=bool)``.  A Ctrl-C stops after the
        points already written; the point in progress is not written.
    """
    check_writable(out)
    points = _check_points(points)
    seed = check_seed(seed)
    settings = dict(method=method, h=h, delta=delta, dtype=dtype, n_excursions=n_excursions, rtol=rtol,
                    max_work=max_work)
    full = [{**{k: FIG3[k] for k in PARAM_KEYS}, **pt} for pt in points]
    for pt in full:  # plan every point first: bad or infeasible input is refused before any work
        try:
            plan_estimate(Params(**pt), method=method, h=h, delta=delta, dtype=dtype, n_excursions=n_excursions,
                          max_work=max_work)
        except ValueError as e:
            raise ValueError(f"{e} [at sweep point {json.dumps(pt)}]") from None
    records = read_results(out)
    have = {_ident(r["sweep_seed"], r["params"], r["settings"]) for r in records}
    todo = []
    for pt in full:
        ident = _ident(seed, pt, settings)
        if ident not in have:
            todo.append(pt)
            have.add(ident)  # a point listed twice runs once
    total, done = len(full), len(full) - len(todo)
    if progress:
        progress(done, total, None)
    computed, interrupted = 0, False
    for pt in todo:
        s = point_seed(seed, pt, settings)
        try:
            with warnings.catch_warnings():  # the warnings are kept in the record ...
                warnings.simplefilter("ignore", DryfricWarning)
                warnings.simplefilter("always", ProjectionWarning)  # ... except this one, said at once
                warnings.showwarning = _at_point(warnings.showwarning, pt)
                r = estimate_diffusivity(Params(**pt), s, method=method, h=h, delta=delta, dtype=dtype,
                                         n_excursions=n_excursions, rtol=rtol, max_work=max_work)
        except KeyboardInterrupt:
            interrupted = True
            break
        if r.stopped_by == "interrupted":  # Ctrl-C inside the point: not a finished point
            interrupted = True
            break
        res = r.to_dict()
        for k in ("params", "seed"):
            res.pop(k)
        rec = dict(params=pt, settings=settings, sweep_seed=seed, seed=s, version=__version__,
                   finished_at=time.strftime("%Y-%m-%dT%H:%M:%S"), result=res)
        records.append(rec)
        write_records(out, records)
        computed += 1
        done += 1
        if progress:
            progress(done, total, rec)
    return dict(computed=computed, skipped=total - len(todo), total=total, interrupted=interrupted)


def progress_bar(done: int, total: int, rec) -> None:
    """A one-line bar on stderr (terminal), one line per point otherwise."""
    width = 30
    fill = int(width * done / max(total, 1))
    last = ""
    if rec is not None:
        r, p = rec["result"], rec["params"]
        last = f"  Gamma={p['Gamma']:.4g} tau={p['tau']:.4g}: D={r['D']:.4g}±{r['D_ci']:.2g}"
    line = f"[{'#' * fill}{'.' * (width - fill)}] {done}/{total} points{last}"
    if sys.stderr.isatty():
        print("\r" + line[:150].ljust(150), end="" if done < total else "\n", file=sys.stderr, flush=True)
    elif rec is not None:
        print(line, file=sys.stderr, flush=True)
