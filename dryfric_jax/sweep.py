r"""Resumable sweeps of D and M0 over a grid of parameters.

:func:`run_sweep` estimates D and M0 (with their 95% CIs) at every point of a grid and writes
each finished point to a JSON Lines file as one appended line, fsync'd (a record that replaces one is
written by rewriting the whole file to a temporary file in the same directory and renaming it over the
old one).  A kill at any moment loses no finished point: at most the line being written is cut short,
which readers skip (with a warning) and the next write removes (a file whose first line was cut short is
refused: delete it).  Each record carries the point's
parameters, the settings that determine its result, its seed and the package version.

Resuming: a point whose record (same parameters and settings) is already in the file is not
recomputed; new points are appended.  The seed of a point is derived from the sweep seed and the
point itself (not from its position in the grid), so adding points to a grid never changes the
others, and a resumed sweep gives bit-identical records.

With ``durations=N`` each point also gets the paper's mean long-excursion duration, counted over N long
excursions of the DI (:func:`~dryfric_jax.di_long_excursion_duration`; :func:`run_sweep`'s docstring says how).

The settings (method, h, delta, dtype, n_excursions, rtol, max_work; durations) are checked once, before the
grid (:func:`~dryfric_jax.plan.check_settings`): a wrong setting is a user's mistake, never a point's
refusal.  Every point is then planned (:func:`~dryfric_jax.plan.plan_estimate`).  A point with invalid
parameters refuses the grid before anything is simulated.  A point the planner refuses (its
predicted work exceeds ``max_work``, no stationary state, an inadmissible h or delta) refuses the
grid too, and the message counts them and names the first ``1 + MAX_NAMED``; with ``skip_refused`` they are recorded as
``"refused"`` (with the reason) and the others run.  A point that runs but ends without an
estimate (:class:`~dryfric_jax.api.NoEstimateError`: fewer than 2 complete excursions within the
work bounds) is recorded as ``"failed"`` and the sweep goes on; with the same seed and settings it
would fail again, so a resumed sweep does not rerun it (raise ``max_work``, which changes the
settings, or delete its line).  ``max_work`` is a setting, not a limit as ``max_time`` is: a grid run again with
a larger one is a new grid (new seeds, every point computed again), and :func:`rows` lists both unless given
``max_work`` too.  Each record's ``status`` is ``"ok"`` (with ``result``),
``"refused"`` or ``"failed"`` (with ``reason``); records written before statuses existed are
``"ok"``.

``max_time`` bounds each point's wall time (as in :func:`~dryfric_jax.api.estimate_diffusivity`:
the rounds stop after it, the final round is cut at twice it).  It is a limit, not a setting: it
does not enter a point's seed or identity, and a point that finished within it gets the same result
as without it.  A point that it stopped (``"ok"`` with ``stopped_by = "max_time"``, or ``"failed"``
with ``stopped_by = "max_time"``) keeps its record, with the ``max_time`` it had; a resumed sweep
reruns it when given more time (a larger ``max_time``, or none), and the new record replaces the old
one only once the point has finished.  The rerun repeats the first run's rounds (same seed) and goes on.

A record made by another package version (``version``) is rerun the same way, and replaced once
the point has finished: the version is raised with every change to the numbers a seed gives or
fix of a result (:mod:`dryfric_jax._version`), so a resumed sweep never mixes in points of older
code.

Two sweeps may write to one file at once (two GPUs, two shells): each point's record is written
under a lock (:func:`~dryfric_jax.outfiles.locked`), re-reading the file first, so neither loses
the other's points.  A point is claimed while it is computed (:func:`~dryfric_jax.outfiles.claim`, a
``flock`` the kernel releases when the process ends, even killed), and the file is read again once the
claim is held: a point of both grids is computed by one sweep only.  The other leaves it for after
its remaining points, then waits for the claim and takes the record (counted as ``skipped``), or
computes the point if its holder stopped without one.  On Windows (no ``fcntl``) there is no lock: both may
compute a point, and two sweeps writing one file at once may lose each other's records (a ``FileWarning`` says
so).
"""
from __future__ import annotations

import decimal
import functools
import itertools
import json
import math
import numbers
import os
import sys
import time
import warnings
import zlib

import jax
import numpy as np

from ._version import __version__
from .api import (DryfricWarning, NoEstimateError, ProjectionWarning, check_progress, check_seed, duration_text,
                  estimate_diffusivity, progress_text, status_line, terminal_columns)
from .combine import bad_sums, has_sums
from .durations import (NoCountError, check_duration_run, default_duration_h, default_max_steps,
                        di_long_excursion_duration, finest_rules_h, max_steps_for)
from .limits import MAX_WORK
from .live import live_progress
from .outfiles import (ReadCache, check_writable, claim, drop_claims_dir, dumps, locked, put_record, read_records,
                       write_records)
from .params import FIG3, Params, _tau0, brief, check_flag, check_positive, plain_number, real_or_none, shown
from .plan import check_count, check_max_time, check_settings, plan_estimate
from .rounds import abandon_on_interrupt

PARAM_KEYS = ("Gamma", "Delta", "tau", "tau_L", "gamma_bar")
#: settings that determine a point's result (with its parameters and seed)
SETTING_KEYS = ("method", "h", "delta", "dtype", "n_excursions", "rtol", "max_work")
#: the optional setting of the paper's long-excursion durations (``run_sweep(durations=N)``): in a point's settings
#: and identity only when given, and never in its D seed, so that a sweep without it keeps its identities and seeds
#: and one with it gives the same D
DURATIONS = "durations"
#: the points of a refusal message named beyond the first
MAX_NAMED = 5


def grid(**axes) -> list[dict]:
    """The Cartesian product of the given axes (lists) as parameter dicts, in a stable order."""
    names = [k for k in PARAM_KEYS if k in axes]
    unknown = set(axes) - set(PARAM_KEYS)
    if unknown:
        raise ValueError(f"sweep axes must be among {list(PARAM_KEYS)} (got {sorted(unknown)})")
    values = {}
    for k in names:
        v = axes[k]
        # "5,6" was read as the points '5', ',' and '6'; None, True or 1+2j failed with a TypeError
        if isinstance(v, (str, bytes, dict)) or (real_or_none(v) is None and not hasattr(v, "__iter__")):
            raise ValueError(f"sweep axis {k} must be a list of numbers (got {repr(v)[:60]})")
        values[k] = [v] if real_or_none(v) is not None else list(np.ravel(v)) if isinstance(v, np.ndarray) else list(v)
    return [dict(zip(names, vals)) for vals in itertools.product(*(values[k] for k in names))]


def _canon(x):
    """A number as the repr of its float ('inf' for tau_L = inf, as before); anything else as is.  The
    old special case for infinities wrote -inf as 'inf' too (as figures.points did); Params refuses
    -inf before any identity is made, so no point's identity or seed changes."""
    return repr(float(x)) if isinstance(x, (int, float)) else x


def _ident(seed: int, params: dict, settings: dict) -> str:
    """Canonical text of a point: sweep seed, parameters, and the settings that determine it (:data:`DURATIONS`
    only where given)."""
    keyed = {k: _canon(settings.get(k)) for k in SETTING_KEYS}
    if settings.get(DURATIONS) is not None:
        keyed[DURATIONS] = _canon(settings[DURATIONS])
    return json.dumps([seed, {k: _canon(params[k]) for k in PARAM_KEYS}, keyed], sort_keys=True)


def _without_durations(settings: dict) -> dict:
    return {k: v for k, v in settings.items() if k != DURATIONS}


def _check_point(seed, params, settings) -> int:
    """``ValueError`` naming the argument of :func:`point_seed` or :func:`duration_seed` where ``seed`` is not an
    integer in [0, 2^62], ``params`` not a dict with the :data:`PARAM_KEYS`, or ``settings`` not a dict (they were
    a KeyError, TypeError or AttributeError); the seed as an int."""
    seed = check_seed(seed)
    if not isinstance(params, dict) or any(k not in params for k in PARAM_KEYS):
        raise ValueError(f"params must be a dict with the keys {', '.join(PARAM_KEYS)} (got {shown(params)})")
    if not isinstance(settings, dict):
        raise ValueError(f"settings must be a dict (got {shown(settings)})")
    return seed


def point_seed(seed: int, params: dict, settings: dict) -> int:
    """A 31-bit seed from the sweep seed and the point (stable under grid edits): the seed of its D estimate, which
    the :data:`DURATIONS` setting does not enter."""
    seed = _check_point(seed, params, settings)
    return zlib.crc32(_ident(seed, params, _without_durations(settings)).encode()) & 0x7FFFFFFF


def duration_seed(seed: int, params: dict, settings: dict) -> int:
    """The 31-bit seed of a point's long-excursion count (``run_sweep(durations=N)``), another stream than
    :func:`point_seed`'s."""
    seed = _check_point(seed, params, settings)
    return zlib.crc32(("durations " + _ident(seed, params, settings)).encode()) & 0x7FFFFFFF


def duration_h(params: Params, h) -> float:
    """The step of a point's long-excursion count: the sweep's ``h`` (None: the D estimator's default),
    tau / :data:`~dryfric_jax.durations.TAU_STEPS` or the step whose X variance against the stuck band is
    :data:`~dryfric_jax.durations.MAX_BAND_VARIANCE`, whichever is smallest (the count's bias falls like h and is a
    function of that variance: :mod:`dryfric_jax.durations`); without ``h``, i.e.,
    :func:`~dryfric_jax.durations.default_duration_h`.  A sweep's ``h`` coarser than the D estimator's default
    makes the count coarser too (and its bias larger), as it does the D (the docs said the count kept its default
    step then: an audit).  ``h`` other than None or a finite number > 0: ``ValueError`` (NaN gave NaN)."""
    if h is None:
        return default_duration_h(params)
    check_positive("h", h)
    return min(float(h), finest_rules_h(params))


def _is_real(x) -> bool:
    """A number (inf included, for tau_L) that float() takes: a hand-edited integer beyond float range
    was an OverflowError traceback where the point's identity is made, not the file's refusal."""
    if not isinstance(x, (int, float)) or isinstance(x, bool):
        return False
    try:
        float(x)
    except OverflowError:
        return False
    return True


def _is_finite(x) -> bool:
    """:func:`_is_real` and finite: a result's numbers (a hand-edited D of NaN passed as a finished point, never
    rerun: an audit)."""
    return _is_real(x) and math.isfinite(float(x))


def _check_record(rec: dict) -> None:
    """Raise (TypeError) unless ``rec`` has the shape of a sweep record: what resuming, counting and
    :func:`rows` read.  A hand-edited line used to fail with a KeyError after new points had run."""
    ok = (isinstance(rec["params"], dict) and all(_is_real(rec["params"].get(k)) for k in PARAM_KEYS)
          and isinstance(rec["settings"], dict) and isinstance(rec["sweep_seed"], int)
          # a setting is part of the point's identity too: an integer beyond float range was the same traceback
          and all(_is_real(v) for v in map(rec["settings"].get, SETTING_KEYS + (DURATIONS,)) if type(v) is int)
          and not isinstance(rec["sweep_seed"], bool) and status(rec) in ("ok", "refused", "failed"))
    if ok and status(rec) == "ok":
        res = rec.get("result")
        ok = isinstance(res, dict) and all(_is_finite(res.get(k)) for k in ("D", "D_ci", "M0", "M0_ci", "n_truncated"))
        # the excursion sums that combine pools: a hand-edited t = 0, or none at all, passed as a finished point
        # that combine then refused and a resumed sweep never reran (an audit); a record of another version, which
        # is rerun, may predate them
        ok = ok and (bad_sums(res["sums"]) == [] if has_sums(res.get("sums")) else _outdated(rec))
        # and its numbers those of its sums: a hand-edited D = -5, or an n_excursions other than the sums' n, read
        # as the point's result in rows() while combine pooled the sums (an audit)
        ok = ok and (_outdated(rec) or _agrees_with_sums(res, rec["params"]))
        if ok and rec["settings"].get(DURATIONS) is not None:  # the count's numbers, or why there are none
            d = rec.get(DURATIONS)
            ok = isinstance(d, dict) and (isinstance(d.get("reason"), str) or all(
                _is_finite(d.get(k)) for k in ("mean", "ci", "n_excursions", "n_truncated")))
    elif ok:
        ok = isinstance(rec.get("reason"), str)
    if ok and not _outdated(rec):
        # the seed this version derives from the record's identity: a hand-edited Gamma served the old point's
        # result as the new point's (an audit); a record of this version always has it
        s = rec.get("seed")
        ok = type(s) is int and s == point_seed(rec["sweep_seed"], rec["params"], rec["settings"])
    if not ok:
        raise TypeError("not a sweep record")


def _agrees_with_sums(res: dict, params: dict) -> bool:
    r"""A result's ``n_excursions``, D and M0 are those of its excursion sums: n, and
    :math:`M_0 = v_0 \sum U/\sum t`, :math:`D = D_0(\sum U^2 - 2m\sum Ut + m^2\sum t^2)/\sum t` (the point
    estimates :func:`~dryfric_jax.estimators.psi_M` and :func:`~dryfric_jax.estimators.psi_D` of the means, in
    plain floats: ~14 us a record, 0.14 s per reading of 10^4 records), each within 1e-9 of its terms' size
    (rounding; the run computes them in XLA) plus 1e-6 of its CI.  The units as :class:`~dryfric_jax.params.Params`
    computes them (``G**3 / De**4`` overflowed, or lost digits, at extreme units Params takes: a review); an
    arithmetic error (a hand-edited Delta = 0) is a disagreement."""
    T = res["sums"]
    if type(res.get("n_excursions")) is not int or res["n_excursions"] != T["n"]:
        return False
    try:
        G, De = float(params["Gamma"]), float(params["Delta"])
        v0 = G / De
        D0 = _tau0(G, De) * v0 * v0  # Params.D0: u0 v0, u0 = tau0 v0
    except ArithmeticError:
        return False
    m = T["U"] / T["t"]
    terms = (T["U2"], 2 * m * T["Ut"], m * m * T["t2"])
    D = (terms[0] - terms[1] + terms[2]) / T["t"] * D0
    size = math.fsum(map(abs, terms)) / T["t"] * D0
    return (abs(res["D"] - D) <= 1e-9 * size + 1e-6 * abs(res["D_ci"])
            and abs(res["M0"] - m * v0) <= 1e-9 * abs(m * v0) + 1e-6 * abs(res["M0_ci"]))


def read_results(path: str) -> list[dict]:
    """The records of a sweep file (empty if it does not exist); refuses a file that is not one,
    naming the first line that is not a sweep record, and a ``path`` that is not a file path (None or a number was
    a TypeError).  Read under the file's lock (:func:`~dryfric_jax.outfiles.locked`), so a record another process
    is appending is never seen half written."""
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a sweep file's path (got {shown(path)})")
    with locked(path):
        return _read(path)


def _read(path: str, cache: ReadCache | None = None) -> list[dict]:
    """:func:`read_results`; with ``cache`` (one :class:`~dryfric_jax.outfiles.ReadCache` per file, kept between
    reads), only the records appended since the last read are parsed and checked (run_sweep reads its file twice a
    point; ``path`` is a path: run_sweep's ``out``, checked writable)."""
    return read_records(path, ("params", "settings", "sweep_seed"),
                        "out must be a dryfric sweep file (JSON Lines); {path!r} line {line} is not a sweep record",
                        check=_check_record, cache=cache)


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
    # -0.0 as 0.0 (gamma_bar = -0.0 was another point, with its own seed and record, of the same physics)
    return [{k: _no_negative_zero(_real_value(v, i, k)) for k, v in pt.items()} for i, pt in enumerate(points)]


def _real_value(v, i: int, name: str):
    """A point's value as a Python float (a Fraction or Decimal too: their points were a TypeError from the
    JSON encoder, as was a complex one, while its refusal was being written; a sweep audit); a string or
    None is left for ``Params`` to refuse by name, anything else is refused here."""
    v = plain_number(v)
    if isinstance(v, (int, float, str)) or v is None or isinstance(v, jax.core.Tracer):
        return v
    if isinstance(v, (numbers.Real, decimal.Decimal)) and not isinstance(v, (bool, np.bool_)):
        return float(v)
    raise ValueError(f"points[{i}] {name} must be a real number (got {shown(v)})")


def _no_negative_zero(x):
    return 0.0 if isinstance(x, float) and x == 0.0 else x


def status(record: dict) -> str:
    """A record's status: ``"ok"``, ``"refused"`` or ``"failed"`` (``"ok"`` for older records)."""
    return record.get("status", "ok")


def stopped_by(record: dict) -> str | None:
    """What ended a point's run (``"max_time"``, ``"target"``, ...); None for a refused point or an
    older record that does not say."""
    return (record.get("result") or {}).get("stopped_by") if status(record) == "ok" else record.get("stopped_by")


def _time_limited(record: dict) -> bool:
    """Whether ``max_time`` stopped the point's D estimate or its long-excursion count."""
    return stopped_by(record) == "max_time" or (record.get(DURATIONS) or {}).get("stopped_by") == "max_time"


def _count_failed(record: dict) -> bool:
    """Whether an ``"ok"`` point's long-excursion count (``durations``) ended without a mean, not stopped by
    ``max_time``: fewer than 2 long excursions within the loop's bound, or refused by its planner (its ``reason``)."""
    d = record.get(DURATIONS)
    return status(record) == "ok" and isinstance(d, dict) and "reason" in d and d.get("stopped_by") != "max_time"


def _more_time(record: dict, max_time) -> bool:
    """True when a point that its ``max_time`` stopped gets more time now (None: no limit)."""
    old = record.get("max_time")
    return _time_limited(record) and (max_time is None or (_is_real(old) and max_time > old))


def _at_point(show, pt):
    """``show`` (a ``warnings.showwarning``) with the sweep point appended to the message."""
    def at(message, category, *args, **kw):
        show(f"{message} [at sweep point {dumps(pt)}]", category, *args, **kw)
    return at


def _first_clause(reason: str) -> str:
    """A refusal's or failure's reason up to its first colon (what was refused, not the numbers)."""
    return reason.split(":")[0]


def _refusal_text(refused: list, total: int) -> str:
    """One line: the first refused point's reason in full, then the others' points and first clauses."""
    (pt, why), rest = refused[0], refused[1:]
    text = f"{why} [at sweep point {dumps(pt)}]"
    if rest:
        named = "; ".join(f"{dumps(p)} ({_first_clause(w)})" for p, w in rest[:MAX_NAMED])
        more = f"; and {len(rest) - MAX_NAMED} more" if len(rest) > MAX_NAMED else ""
        text = f"{len(refused)} of {total} sweep points are refused. {text}. Also refused: {named}{more}"
    return (f"{text}.  Nothing was run; --skip-refused records the refused points and runs the others "
            "(skip_refused=True from Python)")


def run_sweep(points: list[dict], out: str, *, seed: int = 0, method: str = "di", h=None, delta=None,
              dtype: str = "float64", n_excursions: int = 20_000, rtol=None, max_work: float = MAX_WORK,
              max_time=None, skip_refused: bool = False, progress=None, durations=None,
              point_progress=None) -> dict:
    r"""Estimate D and M0 at every point, one JSON line per finished point in ``out``.

    Args:
        points: parameter dicts (physical units); missing keys take the Fig. 3 values.
        out: the JSON Lines results file (created, or resumed if it exists).
        seed: the sweep seed; point seeds come from :func:`point_seed`.
        method, h, delta, dtype, n_excursions, rtol, max_work: as in
            :func:`~dryfric_jax.api.estimate_diffusivity`, the same for every point.
        max_time: optional time limit of each point, seconds (module docstring: a point it stopped is
            rerun by a resumed sweep that gives more time).
        skip_refused: record the points the planner refuses (status ``"refused"``) and run the
            others, instead of refusing the grid (``ValueError`` counting the refused points, naming the first six).
        progress: optional ``progress(done, total, record)`` after each point (and once at start); ``True``
            for :func:`progress_bar_for` the grid (a bar on a terminal, a line per point elsewhere).
        point_progress: ``True`` for a live status line of the point running (the bar, the point, its D or
            count so far and the projected time left: an updated display in a Jupyter notebook, a self-overwriting
            line on a terminal, nothing elsewhere; :mod:`dryfric_jax.live`), or a callback
            ``point_progress(dict)`` while a point runs: the dict its D estimate gives
            after every round (:func:`~dryfric_jax.estimate_diffusivity`'s ``progress``) with ``stage = "D"``,
            or its long-excursion count after every piece (:func:`~dryfric_jax.di_long_excursion_duration`'s)
            with ``stage = "durations"``; both with the point's ``params`` and the sweep's ``done`` and
            ``total`` (points finished, of the grid's).  :func:`point_line` shows it on a terminal.  An
            exception it (or ``progress``) raises ends the sweep and goes on up; the point it stopped is not
            recorded (the finished ones are), so the same call resumes there.
        durations: None, or an integer N in [2, 2^40]: also count the paper's mean long-excursion duration
            (threshold to threshold, Fig. 3's right panel) at each point, over N long excursions of the DI
            (:func:`~dryfric_jax.di_long_excursion_duration`, whatever ``method``: for the DI the D estimate's
            ``mean_duration`` is its regeneration cycle's, which spans one or more of them), at :func:`duration_h`
            and ``dtype``, with the seed :func:`duration_seed`; the loop's bound is planned from the point's mean
            cycle (:func:`~dryfric_jax.durations.max_steps_for`).  A point's record then holds them under
            ``"durations"`` (``mean``, ``ci``, ``n_excursions``, ``n_truncated``, ``h``, ``seed``, ...; or a
            ``reason`` where fewer than 2 ended within the bound), and :func:`rows` flattens them (``le_duration``,
            ...).  It is part of a point's identity but not of its D seed: the D is the sweep's without it, and a
            resumed sweep that adds it takes the D of a finished point's record of this version and runs only the
            count, and a sweep run again without it takes the D of a record with it (any N).  The count's predicted
            work is checked against ``max_work`` with the grid: a point over it refuses the grid, or, with
            ``skip_refused``, still gets its D, and its count the reason ``"durations: ..."`` (counted in
            ``no_count``; the point was refused whole, its D lost: an audit).
            ``max_time`` bounds the D estimate and the count, each
            (:func:`~dryfric_jax.di_long_excursion_duration`'s ``max_time``); a count it stopped makes the point
            one that a resumed sweep with more time reruns.

    The points' warnings are kept in their records, not shown; a
    :class:`~dryfric_jax.api.ProjectionWarning` (max_work will end a point early) is shown at
    once, with the point.  A point that ends without an estimate is recorded as ``"failed"``
    (module docstring) and the sweep goes on.

    Returns:
        ``dict(computed=k, skipped=s, total=n, duplicates=d, interrupted=bool, refused=r, failed=f,
        truncated=t, time_limited=m, no_count=c, kept_d=e)``: n distinct points (d more entries repeat one of them:
        a point listed twice runs once; -0.0 is 0.0), k run now (``"ok"`` or ``"failed"``; also a point written now
        whose D was taken from its record with or without durations, not estimated again), s found in the file
        (``"ok"`` or ``"failed"``, not rerun); r, f, t and m count the grid's points now recorded as
        refused, failed, ``"ok"`` with truncated excursions (a result biased low), or stopped by
        ``max_time`` (``"ok"`` short of N or rtol, or ``"failed"``); ``truncated`` also counts a point whose
        long-excursion count left some out; c counts the ``"ok"`` points whose count (``durations``) ended
        without a mean within its loop's bound, or was refused by its planner (not stopped by ``max_time``: those
        are in m).  A point another sweep
        finished while this one ran is counted in s.  A Ctrl-C stops after the points already
        written; the point in progress is not written, except a D it finished before its count (``durations``),
        written as its record without the count, which a resumed sweep takes up (e = 1 then, else 0; not in k).
    """
    check_writable(out)
    points = _check_points(points)
    seed = check_seed(seed)
    max_time = check_max_time(max_time)
    max_time = None if max_time == math.inf else max_time  # no limit, as recorded
    check_progress(progress)
    check_progress(point_progress, "point_progress")
    progress = progress_bar_for(points) if progress is True else progress or None
    skip_refused = check_flag("skip_refused", skip_refused)
    # as JSON values (numpy numbers as Python ones, a numpy dtype as its name), checked once: a wrong
    # setting refuses the grid (dtype float16 was recorded as every point's refusal)
    settings = check_settings(method=method, h=h, delta=delta, dtype=dtype, n_excursions=n_excursions, rtol=rtol,
                              max_work=max_work)
    method, h, delta, dtype, n_excursions, rtol, max_work = (settings[k] for k in SETTING_KEYS)
    if durations is not None:  # in the settings (and identities) only where given: older records keep theirs
        settings[DURATIONS] = check_count("durations", durations, 2, 2**40, " (long excursions per point)")
    full = [{**{k: FIG3[k] for k in PARAM_KEYS}, **pt} for pt in points]
    refused = {}  # ident -> (point, reason); every point is planned before any work
    count_refused = {}  # ident -> reason: with skip_refused, a point whose count alone is refused still gets its D
    for pt in full:
        try:
            p = Params(**pt)
        except ValueError as e:  # invalid parameters: the grid itself is wrong
            raise ValueError(f"{e} [at sweep point {dumps(pt)}]") from None
        try:
            plan_estimate(p, method=method, h=h, delta=delta, dtype=dtype, n_excursions=n_excursions,
                          max_work=max_work)
        except ValueError as e:
            refused.setdefault(_ident(seed, pt, settings), (pt, str(e)))
            continue
        if durations is not None:
            try:
                dh = None if h is None else duration_h(p, h)
                check_duration_run(p, dh, settings[DURATIONS], dtype, max_work, name="durations",
                                   ruled=dh is not None and dh < h)
            except ValueError as e:
                if skip_refused:
                    count_refused.setdefault(_ident(seed, pt, settings), f"durations: {e}")
                else:
                    refused.setdefault(_ident(seed, pt, settings), (pt, f"durations: {e}"))
    if refused and not skip_refused:
        raise ValueError(_refusal_text(list(refused.values()), len(full)))
    grid_idents = [_ident(seed, pt, settings) for pt in full]
    read = functools.partial(_read, cache=ReadCache())  # the file is read again before and after each point
    with locked(out):
        records = read(out)
        # a refused record of a grid point that the planner now accepts (another version) is dropped and run
        stale = set(grid_idents) - set(refused)
        pairs = [(_rec_ident(r), r) for r in records]
        pairs = [(i, r) for i, r in pairs if status(r) != "refused" or i not in stale]
        pairs = _one_per_point(pairs, max_time, out)
        kept, have = [r for _, r in pairs], dict(pairs)
        new_refused = [(i, pt, why) for i, (pt, why) in refused.items() if i not in have]
        for i, pt, why in new_refused:
            rec = _record(seed, pt, settings, "refused", reason=why)
            kept.append(rec)
            have[i] = rec
        # an existing file is rewritten now (unchanged if nothing is): one that cannot be replaced fails before any
        # work, not after the first point is computed
        if len(kept) != len(records) or new_refused or os.path.exists(out):
            write_records(out, kept)
    # a point that max_time stopped is rerun when given more time, and one an earlier version recorded
    # is rerun by this one; its record stays until replaced.  Not a point this version's planner refuses
    # (skip_refused): the refusal, raised by estimate_diffusivity, ended the sweep; its record is kept
    rerun = {i for i in grid_idents if i in have and i not in refused
             and (_more_time(have[i], max_time) or _outdated(have[i]))}
    # the grid's distinct points, in order: a point listed twice runs once, and is counted once (it was
    # counted as "already in the file")
    distinct = dict(zip(grid_idents, full))
    todo = [(i, pt) for i, pt in distinct.items() if i not in have or i in rerun]
    total = len(distinct)
    done = total - len(todo)
    skipped = done - sum(i in have and status(have[i]) == "refused" for i in distinct)
    if progress:
        progress(done, total, None)
    interrupted, later, tally, kept_d = False, [], [], []  # tally: the points computed and written
    with live_progress(point_progress, functools.partial(_point_text, axes=_axes(points))) as point_progress:
        # a point another sweep is computing (claimed) is left for later and waited for after the others:
        # it is usually finished by then, and is not computed twice
        for wait, queue in ((False, todo), (True, later)):
            for ident, pt in list(queue):
                try:
                    with claim(out, ident, wait=wait) as c:
                        if not c.held:
                            later.append((ident, pt))
                            continue
                        rec = _finished_elsewhere(out, ident, max_time, read)
                        if rec is not None:
                            skipped += 1
                        else:
                            within = None if point_progress is None else functools.partial(
                                _within, point_progress, dict(params=pt, done=done, total=total))
                            rec = _compute(out, pt, seed, settings, max_time, within, kept_d, read,
                                           count_refused.get(ident))
                            if rec is None:  # Ctrl-C: the point in progress is not written
                                interrupted = True
                                break
                            # the file read again under its lock: another sweep's records are kept, a record of this
                            # point (a rerun with more time, or the other sweep's) is replaced in place; a Ctrl-C or
                            # SIGTERM during the write acts after it and its count (put_record)
                            put_record(out, rec, _of_point(ident), read,
                                       done=lambda: tally.append(ident))
                        c.finish()
                except KeyboardInterrupt:  # also while waiting for another sweep's point
                    interrupted = True
                    if ident in tally:  # written before the signal acted
                        have[ident] = rec
                    break
                have[ident] = rec
                done += 1
                if progress:
                    progress(done, total, rec)
            if interrupted:
                break
    drop_claims_dir(out)
    mine = [have[i] for i in distinct if i in have]
    count = {k: sum(status(r) == k for r in mine) for k in ("refused", "failed")}
    truncated = sum(status(r) == "ok" and (r["result"].get("n_truncated", 0) > 0
                                           or (r.get(DURATIONS) or {}).get("n_truncated", 0) > 0) for r in mine)
    return dict(computed=len(tally), skipped=skipped, total=total, duplicates=len(full) - total,
                interrupted=interrupted, refused=count["refused"], failed=count["failed"], truncated=truncated,
                time_limited=sum(map(_time_limited, mine)), no_count=sum(map(_count_failed, mine)),
                kept_d=len(kept_d))


def _finished_elsewhere(out: str, ident: str, max_time, read=read_results) -> dict | None:
    """The record of the point ``ident`` that another sweep wrote since this one read the file (``read(out)``), if
    it is one this sweep would not rerun (not stopped short of ``max_time``, not of another version)."""
    with locked(out):
        recs = read(out)
    rec = next(filter(_of_point(ident), recs), None)
    if rec is None or status(rec) == "refused" or _more_time(rec, max_time) or _outdated(rec):
        return None
    return rec


def _counted_elsewhere(out: str, ident: str, max_time, read=read_results) -> dict | None:
    """A record of the point ``ident`` (a sweep without durations) made with durations, by any sweep of this version,
    whose D this sweep would not rerun (not refused, not stopped by a shorter ``max_time``): its D is this point's,
    whose seed does not depend on them (a sweep run again without ``durations`` estimated every D again)."""
    of_point = _of_point(ident)
    with locked(out):
        recs = read(out)
    for rec in recs:
        settings = rec["settings"]
        if settings.get(DURATIONS) is None or not of_point({**rec, "settings": _without_durations(settings)}):
            continue
        # (its count's max_time does not matter here: the D's only)
        if status(rec) != "refused" and not _more_time({**rec, DURATIONS: None}, max_time) and not _outdated(rec):
            return rec
    return None


def _within(point_progress, where: dict, stage: str, d: dict) -> None:
    """``run_sweep``'s ``point_progress`` of a point's D estimate or count (``stage``) at the point ``where``."""
    point_progress({**d, "stage": stage, **where})


def _compute(out: str, pt: dict, seed: int, settings: dict, max_time, within=None, kept_d=None,
             read=read_results, count_refused: str | None = None) -> dict | None:
    """Run one point and return its record (``"ok"`` or ``"failed"``), for the caller to write; None if Ctrl-C
    stopped it (its finished D, if the count stopped, written here as its record without durations, and the point
    appended to the list ``kept_d``); the file is read by ``read``.  ``within(stage,
    dict)``, if given, is called with the D estimate's (``"D"``) and the count's (``"durations"``) progress.
    ``count_refused``: the planner's refusal of the point's count (``durations``), recorded as the count's
    ``reason`` instead of running it."""
    method, h, delta, dtype, n_excursions, rtol, max_work = (settings[k] for k in SETTING_KEYS)
    s = point_seed(seed, pt, settings)
    # with durations: the D of this point's record without them, if this version finished it (the same seed); without
    # them, the D of a record with them
    plain = _ident(seed, pt, _without_durations(settings))
    base = (_finished_elsewhere(out, plain, max_time, read) if settings.get(DURATIONS) is not None
            else _counted_elsewhere(out, plain, max_time, read))
    res = None
    try:
        with warnings.catch_warnings():  # the warnings are kept in the record ...
            warnings.simplefilter("ignore", DryfricWarning)
            warnings.simplefilter("always", ProjectionWarning)  # ... except this one, said at once
            warnings.showwarning = _at_point(warnings.showwarning, pt)
            with abandon_on_interrupt():  # a point stopped short is not kept: no grace spent finishing it
                if base is not None and status(base) == "failed":
                    raise NoEstimateError(base["reason"], stopped_by=base.get("stopped_by") or "work_bound")
                if base is not None:
                    res = base["result"]
                else:
                    r = estimate_diffusivity(Params(**pt), s, method=method, h=h, delta=delta, dtype=dtype,
                                             n_excursions=n_excursions, rtol=rtol, max_work=max_work,
                                             max_time=max_time, progress=within and functools.partial(within, "D"))
                    if r.stopped_by == "interrupted":  # Ctrl-C inside the point: not a finished point
                        return None
                    d = r.to_dict()
                    for k in ("params", "seed"):
                        d.pop(k)
                    res = d  # only once complete: a Ctrl-C keeps it (below)
                extra = {} if settings.get(DURATIONS) is None else {
                    DURATIONS: dict(reason=count_refused) if count_refused else
                    _durations(pt, seed, settings, res.get("mean_duration"), max_time,
                               within and functools.partial(within, DURATIONS))}
    except KeyboardInterrupt:
        if res is not None and base is None and settings.get(DURATIONS) is not None:
            _keep_d(out, pt, seed, settings, max_time, res, read, kept_d)
        return None
    except NoEstimateError as e:  # deterministic (unless max_time stopped it): recorded, not rerun on resume
        rec = _record(seed, pt, settings, "failed", max_time, reason=str(e), stopped_by=e.stopped_by)
    else:
        rec = _record(seed, pt, settings, "ok", max_time, result=res, **extra)
    return rec


def _keep_d(out: str, pt: dict, seed: int, settings: dict, max_time, res: dict, read=read_results,
            kept: list | None = None) -> bool:
    """A point stopped by a Ctrl-C in its count (``durations``): its finished D is written as its record without
    durations, which the resumed sweep takes up (:func:`_compute`'s ``base``) instead of estimating it again (it was
    lost: an audit) -- unless the file holds one that this sweep would keep (another sweep's, finished meanwhile).
    Called while the Ctrl-C is handled: a failure to write (a full disk, a file another process spoiled) is said and
    the D lost as before, so the Ctrl-C still ends the sweep as one.  True if it wrote the record."""
    d_only = _without_durations(settings)
    ident = _ident(seed, pt, d_only)
    try:
        if _finished_elsewhere(out, ident, max_time, read) is None:
            # counted in ``kept`` once written, also where a further Ctrl-C then acts (it was left out: a review)
            put_record(out, _record(seed, pt, d_only, "ok", max_time, result=res), _of_point(ident), read,
                       done=None if kept is None else (lambda: kept.append(pt)))
            return True
    except (OSError, ValueError) as e:
        warnings.warn(f"the point's finished D could not be kept ({e}): a resumed sweep estimates it again",
                      DryfricWarning, stacklevel=2)
    return False


def _durations(pt: dict, seed: int, settings: dict, cycle_s, max_time=None, progress=None) -> dict:
    """A point's long-excursion count (``run_sweep(durations=N)``) as its record keeps it: the
    :class:`~dryfric_jax.LEDuration`'s fields but ``params``, or ``{"reason": ...}`` where fewer than 2 ended within
    the loop's bound, planned from the D estimate's mean cycle ``cycle_s`` (s; where it is not a number > 0, from the
    predicted LE: :func:`~dryfric_jax.durations.default_max_steps`), by ``max_work`` (the sweep's), or within
    ``max_time`` (then with ``stopped_by = "max_time"``).  ``progress``: the count's."""
    p = Params(**pt)
    h = duration_h(p, settings["h"])
    n = settings[DURATIONS]
    c = real_or_none(cycle_s)
    max_steps = (max_steps_for(n, c / h) if c is not None and math.isfinite(c) and c > 0
                 else default_max_steps(p, h, n))
    try:
        d = di_long_excursion_duration(p, duration_seed(seed, pt, settings), h=h, n_excursions=n,
                                       max_steps=max_steps, dtype=settings["dtype"], max_work=settings["max_work"],
                                       max_time=max_time, progress=progress)
    except NoCountError as e:  # fewer than 2 within the bound, max_work or max_time (point_progress's error goes up)
        return dict(reason=str(e), max_steps=max_steps,
                    **({"stopped_by": "max_time"} if str(e).startswith("max_time") else {}))
    out = d.to_dict()
    out.pop("params")
    return out


def _outdated(rec: dict) -> bool:
    """A record of an ``"ok"`` or ``"failed"`` point made by another package version (the version
    is raised with every change to the numbers a seed gives, or fix of a result: :mod:`dryfric_jax._version`)."""
    return status(rec) != "refused" and rec.get("version") != __version__


def _one_per_point(pairs: list, max_time, out: str) -> list:
    """``(identity, record)`` pairs with one record per point: where a file holds a point twice (hand-edited or
    merged), the first record this sweep would not rerun (not stopped short of ``max_time``, not of another version),
    else the first; a :class:`DryfricWarning` says how many.  Both were kept, and rows() listed the point twice (an
    audit); keeping the first whatever it was dropped a finished record for a stale one (a review)."""
    best: dict = {}
    for k, (i, r) in enumerate(pairs):
        stale = _more_time(r, max_time) or _outdated(r)
        if i not in best or (best[i][1] and not stale):
            best[i] = (k, stale)
    if len(best) == len(pairs):
        return pairs
    n = len(pairs) - len(best)
    warnings.warn(f"{out} held {n} record{'s' if n > 1 else ''} of points recorded already (a hand-edited or merged "
                  "file): kept one record per point, a finished one where there was one", DryfricWarning, stacklevel=3)
    keep = {k for k, _ in best.values()}
    return [pr for k, pr in enumerate(pairs) if k in keep]


def _rec_ident(rec: dict) -> str:
    return _ident(rec["sweep_seed"], rec["params"], rec["settings"])


def _of_point(ident: str):
    """A test of whether a record is the point ``ident``'s: its seed and parameters are compared first, and its
    identity (~20 us, a JSON text) made only where they are equal (made for every record of a file of 10^4, it took
    0.2 s a point)."""
    seed, canon, _ = json.loads(ident)
    return lambda rec: (rec["sweep_seed"] == seed and all(_canon(rec["params"][k]) == canon[k] for k in PARAM_KEYS)
                        and _rec_ident(rec) == ident)


def _record(seed: int, pt: dict, settings: dict, state: str, max_time=None, **what) -> dict:
    return dict(params=pt, settings=settings, sweep_seed=seed, seed=point_seed(seed, pt, settings),
                version=__version__, finished_at=time.strftime("%Y-%m-%dT%H:%M:%S"), status=state,
                **({} if max_time is None else dict(max_time=max_time)), **what)


def failures(path: str) -> list[dict]:
    """The refused and failed records of a sweep file (``status``, ``params``, ``reason``)."""
    return [r for r in read_results(path) if status(r) != "ok"]


ROW_KEYS = ("D", "D_ci", "M0", "M0_ci", "mean_duration", "n_excursions", "n_truncated", "method", "dtype")
#: the row keys of a point's long-excursion count (``run_sweep(durations=N)``) and the fields they come from
LE_ROW_KEYS = {"le_duration": "mean", "le_duration_ci": "ci", "le_n_excursions": "n_excursions",
               "le_n_truncated": "n_truncated", "le_h": "h"}


def rows(path: str, seed: int | None = None, **settings) -> list[dict]:
    """The records of a sweep file as flat dicts for tables and plots, sorted by the parameters:
    the parameters, ``status``, the result's :data:`ROW_KEYS` (NaN for a point without a result),
    the long-excursion count's :data:`LE_ROW_KEYS` (``le_duration``, its CI, ...; NaN without one),
    ``reason`` (why a point has no result, or, for an ``"ok"`` one, no count), ``stopped_by``
    (``"max_time"`` for a point its time limit stopped; "" if unknown), ``le_stopped_by`` (the count's:
    ``"max_time"`` where the limit stopped it, its mean then over fewer excursions, or biased low where
    ``le_n_truncated`` > 0; "" without a count; the row showed the D's alone: an audit) and ``warnings`` (the notes
    of the point's D and count: a small N, truncated excursions, weak damping, ...; a table of D and its CI alone hid
    them: an audit).  ``seed`` (the sweep seed) and keyword settings keep only the matching records (e.g.
    ``n_excursions=500``, ``durations=2048``; ``durations=None`` keeps the records without a count: a point given
    ``durations`` after its D was recorded, or whose count a Ctrl-C stopped, holds two records, its D's and its
    count's, and ``rows`` lists both)."""
    known = SETTING_KEYS + (DURATIONS,)
    unknown = sorted(set(settings) - set(known))
    if unknown:
        raise ValueError(f"settings must be among {list(known)} (got {unknown})")
    if seed is not None:  # 'a' or -1 matched nothing and gave [] without a word
        seed = check_seed(seed)
    out = []
    pairs = _one_per_point([(_rec_ident(r), r) for r in read_results(path)], None, path)  # as a resume keeps them
    for _, r in pairs:
        if (seed is not None and r["sweep_seed"] != seed) or any(r["settings"].get(k) != v
                                                                 for k, v in settings.items()):
            continue
        res, le = r.get("result") or {}, r.get(DURATIONS) or {}
        out.append({**r["params"], "status": status(r), **{k: res.get(k, math.nan) for k in ROW_KEYS},
                    **{k: le.get(f, math.nan) for k, f in LE_ROW_KEYS.items()},
                    "le_stopped_by": le.get("stopped_by") or "",
                    "reason": r.get("reason") or le.get("reason", ""), "stopped_by": stopped_by(r) or "",
                    "warnings": [*(res.get("warnings") or ()), *(le.get("warnings") or ())]})
    return sorted(out, key=lambda r: tuple(r[k] for k in PARAM_KEYS))


def progress_bar_for(points: list[dict]):
    """:func:`progress_bar` showing Gamma, tau and every other parameter that varies over
    ``points``, so that each line says which point it is (a grid over tau_L or gamma_bar printed
    the same "Gamma=5 tau=0.001" on every line)."""
    return functools.partial(progress_bar, axes=_axes(points))


def point_line_for(points: list[dict]):
    """:func:`point_line` showing the parameters that :func:`progress_bar_for` shows."""
    return functools.partial(point_line, axes=_axes(points))


def _axes(points: list[dict]) -> tuple:
    """Gamma, tau and every other parameter that varies over ``points``."""
    return tuple(k for k in PARAM_KEYS if k in ("Gamma", "tau") or len({_canon(pt.get(k)) for pt in points}) > 1)


def _bar(done: int, total: int, width: int = 30) -> str:
    fill = int(width * done / max(total, 1))
    return f"[{'#' * fill}{'.' * (width - fill)}] {done}/{total} points"


def _where(p: dict, axes) -> str:
    return "  " + " ".join(f"{k}={brief(p[k])}" for k in axes) + ": "  # 0.999999 and 1.000001 not both "1"


def point_line(d: dict, axes=("Gamma", "tau")) -> None:
    """:func:`progress_bar`'s line, rewritten while a point runs (``run_sweep``'s ``point_progress``; terminal
    only, nothing otherwise; ``point_progress=True`` shows it in a notebook too): :func:`_point_text`."""
    if not sys.stderr.isatty():
        return
    print(status_line(*_point_text(d, axes)), end="", file=sys.stderr, flush=True)


def _point_text(d: dict, axes=("Gamma", "tau")) -> tuple:
    """:func:`point_line`'s text and its tail: the bar, the point, and its D estimate so far (N of the target or
    the CI against ``rtol``) or its long-excursion count so far; then the time it has taken and the projected time
    left (naming ``max_time`` or ``max_work`` when that limit is projected to stop the point)."""
    rest, el = _where(d["params"], axes) + progress_text(d), f" [{duration_text(d['elapsed_s'])}]"
    return _bar(d["done"], d["total"], _bar_width(d["done"], d["total"], rest + el)) + rest, el


def _bar_width(done: int, total: int, rest: str) -> int:
    """The bar's width on a terminal: 30, narrowed (to 10 at least) where its line, ``rest`` after it, would not fit
    the terminal's width (:func:`~dryfric_jax.api.status_line` then cuts what is left over)."""
    cols = terminal_columns()
    return 30 if cols is None else max(10, min(30, cols - 1 - len(_bar(done, total, 0)) - len(rest)))


def progress_bar(done: int, total: int, rec, axes=("Gamma", "tau")) -> None:
    """A one-line bar on stderr (terminal), one line per point otherwise; a point is shown by its
    parameters ``axes`` (:func:`progress_bar_for` picks those that vary in a grid)."""
    last = ""
    if rec is not None:
        last = _where(rec["params"], axes)
        if status(rec) == "ok":
            last += f"D={rec['result']['D']:.4g}±{rec['result']['D_ci']:.2g}"
            le = rec.get(DURATIONS)
            if le is not None:
                last += (f" LE={le['mean']:.4g}±{le['ci']:.2g}s" if "mean" in le
                         else f" LE: none ({_first_clause(le['reason'])})")
        else:
            last += f"{status(rec)} ({_first_clause(rec['reason'])})"
        if _time_limited(rec):
            last += " [stopped by max_time]"
    if sys.stderr.isatty():
        line = _bar(done, total, _bar_width(done, total, last)) + last
        print(status_line(line), end="" if done < total else "\n", file=sys.stderr, flush=True)
    elif rec is not None:
        print(_bar(done, total) + last, file=sys.stderr, flush=True)
