r"""Pooling independent long-excursion runs: more seeds later, or one run per host.

A run's estimate is a function of its sums over complete excursions (``EstimateResult.sums``,
:data:`~dryfric_jax.excursions.STAT_NAMES`): the ratio estimators of paper section 4,

.. math::
    \hat M_0 = \frac{\sum_k U_k}{\sum_k T_k}, \qquad
    \hat D = \frac{\sum_k (U_k - \hat M_0 T_k)^2}{\sum_k T_k},

with the delta-method CI of :mod:`dryfric_jax.estimators`.  Runs with independent random
streams (different seeds) are independent sets of i.i.d. excursions of the same law, and each
run's excursion count is a stopping time (every lane finishes its in-flight excursion), so the
pooled sums give the estimate of the pooled excursions, with its CI.  :func:`combine_estimates`
adds them; :func:`gather_hosts` does it across the processes of a ``jax.distributed`` job.
"""
from __future__ import annotations

import dataclasses
import json
import math
import warnings
from typing import Sequence

import jax
import numpy as np

from .api import MAX_SEED, DryfricWarning, EstimateResult, key_id, missing_fields, small_n_note
from .estimators import MIN_RELIABLE_N, ROUNDING_NOTE, long_excursion_estimates, rounding_note
from .excursions import STAT_NAMES
from .outfiles import from_strict
from .params import Params, check_flag, require_x64
from .plan import DTYPES, MAX_COUNT

# what must agree for two runs to sample the same law (the engine layout does not matter), and to
# pool their CIs (the level)
_SAME = ("params", "method", "h", "delta", "L_X", "dtype", "ci_level")


def _same(a, b) -> bool:
    """Equal, floats to 1e-12 (relative), also each parameter of a ``params`` dict: ``Params.from_nondim``
    gives tau = 0.49999999999999994 for Fig. 3's 0.5, the same run to the last bit, and was refused."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isclose(a, b, rel_tol=1e-12))


def _as_result(r, label: str) -> EstimateResult:
    if isinstance(r, EstimateResult):
        return r
    if isinstance(r, dict):  # parsed with json.load: the strict JSON's "inf" (tau_L = inf), "nan" as floats again
        r = from_strict(r)
    if isinstance(r, dict) and r.get("status", "ok") != "ok" and "params" in r:  # a sweep's refused/failed point
        raise ValueError(f"results must be estimate results: {label} is a sweep record of a {r['status']} point, "
                         f"which has none ({str(r.get('reason', ''))[:200]})")
    if isinstance(r, dict) and isinstance(r.get("result"), dict) and "params" in r:  # a sweep's record
        from .sweep import _check_record  # (sweep imports this module)

        # as the sweep's reader checks it: a hand-edited tau, D or h was pooled as it stood (an audit).  A record
        # without the sweep's identity (its seed, settings) has none to check
        try:
            if "sweep_seed" in r or "settings" in r:
                _check_record(r)
        except (KeyError, TypeError, AttributeError, ValueError):
            raise ValueError(f"results must be estimate results: {label} is not a sweep record as a sweep writes "
                             "it (its seed is not its point's, or its D, M0 or n are not its sums': a hand-edited "
                             "record?)") from None
        r = {**r["result"], "params": r["params"], "seed": r.get("seed")}
    if isinstance(r, dict):  # EstimateResult.to_dict() (the JSON of 'dryfric estimate --out')
        missing = missing_fields(EstimateResult, r)
        if missing:
            raise ValueError(f"results must be estimate results: {label} lacks {missing[:4]} (a brute-force "
                             "result or another file?)")
        names = {f.name for f in dataclasses.fields(EstimateResult)}
        return EstimateResult(**{k: v for k, v in r.items() if k in names})
    raise ValueError(f"results must be EstimateResult objects or their to_dict() ({label} is of type "
                     f"{type(r).__name__})")


def _without_count_twins(results: list, labels: list) -> tuple[list, list, int, tuple | None]:
    """``results`` and ``labels`` without the sweep records that repeat another's D estimate, how many were left
    out, and the labels of the first such pair (None if none). A sweep given a long-excursion count (``durations``)
    after its D writes each point's record again, with the count and the same D (README "Sweeps and notebooks"):
    records of one point (sweep seed, parameters, settings but the count, seed and version) whose counts differ and
    whose sums are equal are one run. They were refused as one seed used twice, so a sweep file that had been given
    a count could not be combined at all (a README audit); records equal in the count too (a file given twice) are
    still refused."""
    keep, kept_labels, seen, first_twin = [], [], {}, None
    for r, label in zip(results, labels):
        res = r.get("result") if isinstance(r, dict) else None
        settings = r.get("settings") if isinstance(res, dict) else None
        count = settings.get("durations") if isinstance(settings, dict) else ""
        # a record of another shape (params null, a count that is not a number) is left for _as_result to refuse
        if isinstance(settings, dict) and isinstance(r.get("params"), dict) and (count is None or type(count) is int):
            settings = {k: v for k, v in settings.items() if k != "durations"}
            run = repr((r.get("sweep_seed"), sorted(r["params"].items()), sorted(settings.items()), r.get("seed"),
                        r.get("version")))
            sums = res.get("sums")
            counts = seen.setdefault(run, {"sums": sums, "counts": set(), "label": label})
            if counts["counts"] and count not in counts["counts"] and sums == counts["sums"]:
                counts["counts"].add(count)
                first_twin = first_twin or (counts["label"], label)
                continue
            counts["counts"].add(count)
        keep.append(r)
        kept_labels.append(label)
    return keep, kept_labels, len(results) - len(keep), first_twin


def _real(x) -> bool:
    try:
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
    except OverflowError:  # an int beyond float range
        return False


def _count(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and x >= 0


def _seed(x) -> bool:
    return x is None or (_count(x) and x <= MAX_SEED)


def _key_text(x) -> bool:
    return x is None or (isinstance(x, str) and 0 < len(x) <= 200)


def _stream(x) -> str | None:
    """The random stream of a run made from seed or key ``x`` (:func:`~dryfric_jax.api.key_id`), None
    when unknown (a key-made run written before keys were recorded)."""
    return key_id(jax.random.key(x)) if isinstance(x, int) else x


def _step(x) -> bool:
    return x is None or (_real(x) and x > 0)


#: the fields combine reads, what they must be, and how to say it
_FIELDS = (
    ("wall_s", lambda x: _real(x) and x >= 0, "a number >= 0"),
    ("lane_steps_per_s", lambda x: _real(x) and x >= 0, "a number >= 0"),
    ("lane_utilization", lambda x: _real(x) and 0 <= x <= 1 + 1e-9, "a number in [0, 1]"),
    ("work", lambda x: _real(x) and x >= 0, "a number >= 0"),
    ("predicted_work", lambda x: _real(x) and x >= 0, "a number >= 0"),
    ("n_truncated", _count, "an integer >= 0"),
    ("ci_level", lambda x: _real(x) and 0 < x < 1, "a number in (0, 1)"),
    ("seed", _seed, "an integer in [0, 2^62] or null"),
    ("combined_from", lambda x: isinstance(x, list) and all(_seed(v) or _key_text(v) for v in x),
     "a list of seeds in [0, 2^62] (or keys)"),
    ("key", _key_text, "a key's text (api.key_id) or null"),
    ("method", lambda x: x in ("di", "pdmp"), "'di' or 'pdmp'"),
    ("dtype", lambda x: isinstance(x, str) and x in DTYPES, f"one of {sorted(DTYPES)}"),
    ("h", _step, "a number > 0 (s) or null"),
    ("delta", _step, "a number > 0 (s^-1/2) or null"),
    ("L_X", _step, "a number > 0 (s^-1/2) or null"),
    ("events_per_s", lambda x: x is None or (_real(x) and x >= 0), "a number >= 0 or null"),
    ("warnings", lambda x: isinstance(x, list) and all(isinstance(w, str) for w in x), "a list of strings"),
    ("lanes", _count, "an integer >= 0"),
    ("block", _count, "an integer >= 0"),
    ("n_requested", _count, "an integer >= 0"),
    ("max_time", lambda x: x is None or (_real(x) and x > 0), "a number > 0 (s) or null"),
    ("max_work", lambda x: _real(x) and x >= 0, "a number >= 0"),  # a string was a TypeError in the pooled sum
    ("version", lambda x: isinstance(x, str), "a string"),
)
#: sums that are sums of squares (or of positive times) and must be >= 0; n and t must be > 0
_NONNEGATIVE_SUMS = ("U2", "U4", "t2", "t3", "t4", "U2t", "U2t2", "t_half")


def _check_fields(r: EstimateResult, label: str) -> None:
    """``ValueError`` naming ``label`` and the field unless every field that combining reads has
    its type and range (a hand-edited or foreign file failed with a TypeError, or gave D = nan)."""
    try:
        Params(**r.params)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{label} must have params of a model (got {str(r.params)[:80]}: {e})") from None
    for name, ok, what in _FIELDS:
        v = getattr(r, name)
        if not ok(v):
            raise ValueError(f"{label} must have {name} {what} (got {str(v)[:60]})")
    if not has_sums(r.sums):
        return  # no sums: refused below, with the advice to rerun
    bad = bad_sums(r.sums)
    if bad:
        raise ValueError(f"{label} must have finite excursion sums, n a whole number in [1, 2^62], t > 0 and the "
                         f"sums of squares >= 0 (got {', '.join(f'{k} = {str(r.sums[k])[:24]}' for k in bad[:4])})")


def has_sums(sums) -> bool:
    """``sums`` is a dict of every excursion sum (:data:`~dryfric_jax.excursions.STAT_NAMES`), whatever its values:
    a result made before the sums were recorded has none."""
    return isinstance(sums, dict) and set(sums) == set(STAT_NAMES)


def bad_sums(sums: dict) -> list[str]:
    """The names of the sums in :func:`has_sums`'s ``sums`` that no run can give: not a finite number, t <= 0, n not
    a whole number in [1, 2^62], a sum of squares < 0 (a hand-edited file; also a sweep record's, which
    :mod:`dryfric_jax.sweep` refuses on reading)."""
    bad = [k for k in STAT_NAMES if not _real(sums[k])]
    bad += [k for k in ("t",) if k not in bad and not sums[k] > 0]
    bad += [k for k in ("n",) if k not in bad and not (sums[k] == int(sums[k]) and 1 <= sums[k] <= MAX_COUNT)]
    return bad + [k for k in _NONNEGATIVE_SUMS if k not in bad and not sums[k] >= 0]


def combine_estimates(results: Sequence, *, labels: Sequence[str] | None = None,
                      allow_mixed_versions: bool = False) -> EstimateResult:
    """One estimate from the pooled excursions of independent runs of the same model.

    Args:
        results: :class:`~dryfric_jax.api.EstimateResult` objects (or their ``to_dict()``, or
            records of a sweep's results file, also as ``json.load`` reads them: the strict
            JSON's ``"inf"``, as tau_L = inf is written, is read as the float) of
            :func:`~dryfric_jax.api.estimate_diffusivity` with the same parameters, method,
            step (``h`` or ``delta``) and dtype, and different seeds.
        labels: names of the results for the messages (``dryfric combine`` passes the file
            names); default ``results[i]``.
        allow_mixed_versions: pool runs of different package versions (the pool's ``version`` is
            then ``"mixed"``, and a note says so); refused by default, since a version may change a
            seed's numbers or fix a result.

    Returns an :class:`EstimateResult` whose D, M0, CIs and mean duration are those of all the
    runs' complete excursions together (their sums added by ``math.fsum``, correctly rounded, so
    the same to the last bit in any order of the runs); counts, work and wall time are sums (``wall_s`` is the
    compute spent, not the elapsed time of runs made side by side), ``combined_from`` lists the
    seeds (a key-made run's key).  Raises ``ValueError`` naming what differs, for a field of the wrong
    type or range (a hand-edited file: every field combining reads is checked), for results without
    sums (made before they were recorded), for runs of different versions (unless
    ``allow_mixed_versions``) and for a random stream used twice: a seed twice, a key twice, or a
    key and the seed it is the key of (``jax.random.key(5)`` and seed 5), also inside a pool.  Two
    different keys, like two different seeds, are taken as independent streams.  Results made from
    a key written before keys were recorded carry neither: their independence is the caller's to
    ensure, and a :class:`DryfricWarning` says so.
    """
    require_x64()  # with it off the pool's sums were added and its D formed in float32
    if isinstance(results, (str, bytes, dict, EstimateResult)) or not hasattr(results, "__iter__") \
            or getattr(results, "ndim", 1) == 0:  # a 0-d array: a TypeError from iter
        raise ValueError(f"results must be a list of EstimateResult objects (got {type(results).__name__})")
    allow_mixed_versions = check_flag("allow_mixed_versions", allow_mixed_versions)
    results = list(results)
    if not results:
        raise ValueError("results must hold at least one EstimateResult (got none)")
    if labels is None:
        labels = [f"results[{i}]" for i in range(len(results))]
    else:  # zip cut a short list, and an int failed with a TypeError
        ok = not isinstance(labels, (str, bytes)) and hasattr(labels, "__iter__")
        labels = list(labels) if ok else labels
        if not (ok and len(labels) == len(results) and all(isinstance(x, str) for x in labels)):
            raise ValueError(f"labels must be a list of {len(results)} strings, one per result "
                             f"(got {str(labels)[:60]})")
    results, labels, twins, twin = _without_count_twins(results, labels)
    rs = [_as_result(r, label) for r, label in zip(results, labels)]
    for r, label in zip(rs, labels):
        _check_fields(r, label)
    first = rs[0]
    for i, r in enumerate(rs):
        if not has_sums(r.sums):
            raise ValueError(f"{labels[i]} has no excursion sums (sums = {str(r.sums)[:60]}): rerun it with this "
                             "version")
        for name in _SAME:
            a, b = getattr(first, name), getattr(r, name)
            if not _same(a, b):
                raise ValueError(f"results must share {name}: {labels[0]} has {a!r}, {labels[i]} has {b!r}")
    # what made each run: its seed, or the key of a key-made one (None: a key-made run written before keys were recorded)
    owned = [(s, i) for i, r in enumerate(rs) for s in (r.combined_from or [r.seed if r.seed is not None else r.key])]
    seeds = [s for s, _ in owned]
    first_of: dict = {}  # each seed's first run: a repeated one is named with both runs (an audit)
    for s, i in owned:
        if isinstance(s, int) and s in first_of:
            j = first_of[s]
            by = f"twice by {labels[i]}" if labels[i] == labels[j] else f"by {labels[j]} and by {labels[i]}"
            raise ValueError(f"seeds must differ between the runs combined (seed {s} used {by}): the same seed gives "
                             "the same excursions")
        first_of[s] = i
    # a key-made run against a seed (key(5) is seed 5's key) or against a pool it is part of: its
    # stream counted twice, and pooled with only the "assumed independent" note (a sweep audit).  A dict of the
    # streams seen (a scan of the earlier ones for each took 3 s at 10^4 runs: an audit)
    what = lambda s: f"seed {s}" if isinstance(s, int) else f"key {s}"
    by_stream: dict = {}
    for s, i in owned if any(isinstance(s, str) for s in seeds) else ():  # distinct seeds are distinct streams
        a = _stream(s)  # (0.25 ms a seed: a pool of 10^4 seeds is checked by the seeds alone)
        if a is None:
            continue
        if a in by_stream:
            t, j = by_stream[a]
            raise ValueError(f"results must draw different random streams: {what(t)} ({labels[j]}) and {what(s)} "
                             f"({labels[i]}) are the same stream (a seed s runs on jax.random.key(s)), so pooling "
                             "would count its excursions twice")
        by_stream[a] = (s, i)
    seen = {}
    for i, r in enumerate(rs):  # the same run twice (a key-made run has no seed to compare)
        j = seen.setdefault(tuple(r.sums[k] for k in STAT_NAMES), i)
        if j != i:
            raise ValueError(f"results must be different runs: {labels[j]} and {labels[i]} have the same excursion "
                             "sums (the same run, or the same seed or key): pooling them would count its excursions "
                             "twice")
    # said twice: warned now, and kept in the pool's ``warnings`` (which ``dryfric combine`` prints and writes)
    said = []
    if twins:
        said.append(f"{twins} sweep record(s) repeating a point's D with another long-excursion count (durations) "
                    f"pooled once (the first: {twin[1]} repeats {twin[0]}; records of two sweeps with the same seed "
                    "are one D: a second host needs another --seed)")
    if None in seeds:
        said.append("some results were made from a jax.random key that they do not record (written before keys were "
                    "recorded): their streams are assumed independent")
    versions = sorted({r.version for r in rs})
    if len(versions) > 1 and not allow_mixed_versions:  # a sweep reruns older points for the same reason
        i = next(i for i, r in enumerate(rs) if r.version != first.version)
        raise ValueError(f"results must share version: {labels[0]} has {first.version!r}, {labels[i]} has "
                         f"{rs[i].version!r}: a new version may change a seed's numbers or fix a result (a sweep reruns "
                         "the points of older ones); rerun the older runs, or pool them as the same model with "
                         "allow_mixed_versions=True (dryfric combine --allow-mixed-versions)")
    if len(versions) > 1:  # pooled, but said
        said.append(f"results come from versions {', '.join(map(repr, versions))} of dryfric_jax: pooled as the same "
                    "model (the pool's version is 'mixed'); rerun the older ones for a single-version result")
    for note in said:
        warnings.warn(note, DryfricWarning, stacklevel=2)
    # math.fsum is correctly rounded, so the pooled sums, and all that follows from them, do not depend on the
    # order of the runs (with sum() the last digit of M0 did)
    total = {k: math.fsum(r.sums[k] for r in rs) for k in STAT_NAMES}
    if total["n"] > MAX_COUNT:
        raise ValueError(f"results must hold at most 2^62 excursions together (got {total['n']:.3g})")
    out = _result(_reference(rs), rs, total, seeds, said)
    if not all(map(math.isfinite, (out.D, out.D_ci, out.M0, out.M0_ci))) or out.D < 0:
        raise ValueError(f"results must hold consistent excursion sums: they give D = {out.D:.3g} +- {out.D_ci:.3g}, "
                         f"M0 = {out.M0:.3g} (a hand-edited file?)")
    return out


def _reference(rs) -> EstimateResult:
    """The run whose params, step and settings the pool reports and scales D and M0 by: the least by its params,
    h, delta, L_X, ci_level and method reason, so that the choice does not depend on the order of the runs (the
    first run's made the pool's last digits depend on it where the runs' parameters differ within :func:`_same`'s
    1e-12: an audit).  These are the fields that :func:`_result` takes from it and that the runs may differ in (the
    others must be equal); runs equal in all of them report the same.  (The pool's notes keep the runs' order.)"""
    def order(r):
        return (sorted(r.params.items()), r.h is None, r.h or 0.0, r.delta is None, r.delta or 0.0,
                r.L_X is None, r.L_X or 0.0, r.ci_level, r.method_reason)
    return min(rs, key=order)


def _result(first: EstimateResult, rs, total: dict, seeds, said=()) -> EstimateResult:
    p = Params(**first.params)
    e = long_excursion_estimates(total, first.ci_level)
    wall = math.fsum(r.wall_s for r in rs)
    useful = math.fsum(r.lane_steps_per_s * r.wall_s for r in rs)
    slots = math.fsum(r.lane_steps_per_s * r.wall_s / r.lane_utilization if r.lane_utilization else 0.0 for r in rs)
    # the runs' notes once each, but the small-N and rounding notes for the pool's sums, not each run's
    # (and ``said``, the pool's own notes: key-made runs, mixed versions)
    notes = list(dict.fromkeys([*(w for r in rs for w in r.warnings
                                  if w != small_n_note(r.n_excursions) and not w.startswith(ROUNDING_NOTE)),
                                *said]))
    if e["n_excursions"] < MIN_RELIABLE_N:
        notes.append(small_n_note(e["n_excursions"]))
    if rounding := rounding_note(total):
        notes.append(rounding)
    rate = useful / wall if wall > 0 else 0.0
    return dataclasses.replace(
        first, D=float(e["D"] * p.D0), D_ci=float(e["D_ci"] * p.D0), M0=float(e["M0"] * p.v0),
        M0_ci=float(e["M0_ci"] * p.v0), mean_duration=float(e["mean_duration"]) * p.tau0,
        mean_duration_ci=float(e["mean_duration_ci"]) * p.tau0, n_excursions=e["n_excursions"],
        n_truncated=sum(r.n_truncated for r in rs), seed=None, key=None, wall_s=wall, lane_steps_per_s=rate,
        events_per_s=None if first.events_per_s is None else rate,
        lane_utilization=useful / slots if slots else first.lane_utilization,
        work=sum(r.work for r in rs), predicted_work=math.fsum(r.predicted_work for r in rs),
        max_work=sum(r.max_work for r in rs),  # the pool's bound, as its work (it was the first run's)
        stopped_by="combined", rtol=None, warnings=notes, sums=total, combined_from=list(seeds),
        lanes=_common(rs, "lanes"), block=_common(rs, "block"), n_requested=sum(r.n_requested for r in rs),
        max_steps=_common(rs, "max_steps"),  # the first run's before: the pool's depended on the runs' order
        max_time=None, version=_common(rs, "version") or "mixed")


def _common(rs, name):
    """The runs' shared value of an engine setting or bound (or the version), 0 where they differ."""
    vals = {getattr(r, name) for r in rs}
    return vals.pop() if len(vals) == 1 else 0


def gather_hosts(result: EstimateResult) -> EstimateResult:
    """The estimate of all processes of a ``jax.distributed`` job, on every process.

    Each process runs :func:`~dryfric_jax.api.estimate_diffusivity` on its own devices with its
    own seed (e.g. ``seed + jax.process_index()``) and calls this with its result: every process's whole
    result (its strict JSON, :meth:`~dryfric_jax.api.EstimateResult.to_json`) is all-gathered
    (``multihost_utils.process_allgather``) and pooled by :func:`combine_estimates` in process order, so every
    process returns the same numbers, and runs that :func:`combine_estimates` refuses (other params, dtype, h,
    version, a seed used twice) are refused on every process.  With one process it returns the pooled result of
    that process alone.
    """
    import jax
    from jax.experimental import multihost_utils

    r = _as_result(result, "result")
    _check_fields(r, "result")
    if not has_sums(r.sums):  # None was a TypeError
        raise ValueError("result has no excursion sums: rerun it with this version")

    def gather(x):
        return np.asarray(multihost_utils.process_allgather(x)).reshape(jax.process_count(), -1)

    # the whole result, not its sums and counts alone: the other fields (params, dtype, h, version, warnings,
    # max_steps, key) were this host's, copied for every host, so hosts of other params or dtypes were pooled
    # without a word and each process returned its own pool (a reproducibility audit, 2026-12-06).  Strict JSON
    # writes a float's shortest repr, which reads back to the same float, and ints (seeds past 2^53) exactly
    text = np.frombuffer(r.to_json().encode(), np.uint8)
    width = int(gather(np.array([text.size], np.int64)).max())
    rows = gather(np.concatenate([text, np.zeros(width - text.size, np.uint8)]))
    per_host = [json.loads(bytes(row).rstrip(b"\0").decode()) for row in rows]
    return combine_estimates(per_host, labels=[f"process {i}'s result" for i in range(len(per_host))])
