r"""Resumable scenes: each finished estimate of a scene is kept, so an interrupted figure resumes.

The scenes of many estimates (Fig. 3: 80 runs of N = 1e5, ~1.5 h on a 2-core CPU; Fig. 8; Fig. 9 (b))
call :func:`~dryfric_jax.api.estimate_diffusivity` and
:func:`~dryfric_jax.api.bruteforce_diffusivity` through :class:`Points`, and Fig. 3 its long-excursion counts
(:func:`~dryfric_jax.di_long_excursion_duration`) too.  Each finished run is
appended to ``<out_dir>/<scene>.points.jsonl`` (one JSON line per run: what was asked, the
package version, the result), the file re-read under a lock first
(:func:`~dryfric_jax.outfiles.put_record`), so a kill at any moment loses no finished run (it may cut short the
line being written, which is skipped and removed) and two runs of a scene into one directory keep each other's
runs.  Each run is claimed while computed
(:func:`~dryfric_jax.outfiles.claim`): a second run of the scene waits for it and reuses it, so
the two share the scene's runs instead of computing each twice.
Running the same scene again into the same directory reuses every run already there (same
kind, parameters, seed, settings and package version) instead of computing it: the seeds are
fixed by the scene, so the resumed figure is bit-identical to an uninterrupted one (tested).

A Ctrl-C inside a run would make :func:`~dryfric_jax.api.estimate_diffusivity` finish the
excursions in flight and return what it reached (``stopped_by = "interrupted"``).  A scene must
not plot such a point as if it were finished, so :class:`Points` runs it under
:func:`~dryfric_jax.rounds.abandon_on_interrupt` (the ``KeyboardInterrupt`` comes at once) and
keeps no interrupted result: the scene stops, and the runs already written stay.  Delete the file
to recompute from scratch.

While a scene computes, :func:`reporting` may name a callback that hears of each run: what it is, the runs the
scene has had so far, and the run's own progress (:func:`~dryfric_jax.api.estimate_diffusivity`'s and the count's
``progress``); the scenes without runs (Figs. 1-2, 4-7, Table 1) name each stage they start with
:func:`report_step`.  ``dryfric figures`` shows it as a status line on a terminal.  It changes no run or record.
"""
from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import json
import os
import time
import warnings

import numpy as np

from .._version import __version__
from ..api import (
    BruteForceResult, DryfricWarning, EstimateResult, bruteforce_diffusivity, estimate_diffusivity, missing_fields,
)
from ..durations import LEDuration, di_long_excursion_duration
from ..outfiles import claim, locked, put_record, read_records
from ..rounds import abandon_on_interrupt

_KINDS = {"estimate": (estimate_diffusivity, EstimateResult), "bruteforce": (bruteforce_diffusivity, BruteForceResult),
          "duration": (di_long_excursion_duration, LEDuration)}


#: the callback of :func:`reporting`, or None
_REPORT = contextvars.ContextVar("dryfric_figures_report", default=None)


@contextlib.contextmanager
def reporting(report):
    """Within the block, every :class:`Points` run calls ``report(dict)`` as it starts and as it goes on: ``kind``
    (``"estimate"``, ``"bruteforce"`` or ``"duration"``), its ``method`` (None where the run does not name it),
    ``params`` (the run's, as a dict), ``runs`` (the scene's runs so far: reused and computed) and ``run``, the run's
    own progress dict (None as it starts, and for brute force, which has none).  None reports nothing."""
    token = _REPORT.set(report)
    try:
        yield
    finally:
        _REPORT.reset(token)


def report_step(what: str) -> None:
    """Tell :func:`reporting`'s callback, if any, the stage a scene without runs starts now, as ``{"step": what}``
    (e.g. ``"PDMP stationary paths, tau=0.5 s (5 of 6)"``); nothing where none is set."""
    report = _REPORT.get()
    if report is not None:
        report({"step": what})


def _canon(x):
    """``x`` as JSON that names its value, not its type: a numpy float64 or int64 setting is the run of
    the Python number it holds (numpy 2's repr of a float64 is ``np.float64(0.1)``)."""
    if isinstance(x, (float, np.floating)):
        return repr(float(x))  # 'inf', '-inf', 'nan' as JSON text
    if isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_)):
        return int(x)
    if isinstance(x, dict):
        return {k: _canon(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_canon(v) for v in x]
    return x


def _ident(kind: str, params, seed: int, kw: dict) -> str:
    """Canonical text of one run: its kind, parameters, seed, settings and the package version."""
    return json.dumps([kind, _canon(params.as_dict()), int(seed), _canon(kw), __version__], sort_keys=True)


def _check_record(rec: dict) -> None:
    """Raise (TypeError) unless ``rec`` has a finished run's shape (an ident list made a TypeError)."""
    if not (isinstance(rec["ident"], str) and rec["kind"] in _KINDS and isinstance(rec["result"], dict)):
        raise TypeError("not a finished-run record")
    if rec.get("version") == __version__ and missing_fields(_KINDS[rec["kind"]][1], rec["result"]):
        raise TypeError("not a finished-run record")  # a record this version may reuse has its result's fields


def _read(path: str) -> list[dict]:
    """The points file's records, read under its lock: a run another process is appending is never seen half
    written (a review: a scene's first run read so refused the file as foreign)."""
    with locked(path):
        return read_records(path, ("ident", "kind", "result"),
                            "out must be a directory of dryfric figure outputs; {path!r} line {line} is "
                            "not a finished-run record (move the file away)", check=_check_record)


def _stamp(path: str):
    """What identifies a version of the file: every write appends to it (a new size) or replaces it (a new
    inode), so another process's write changes this (None while there is no file)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns, st.st_size


def points_path(out_dir: str, scene: str) -> str:
    return os.path.join(out_dir, f"{scene}.points.jsonl")


def check_points_file(out_dir: str, scene: str) -> None:
    """Refuse (``ValueError``, as :class:`Points` does) a ``<scene>.points.jsonl`` in ``out_dir`` that is not one,
    or that is read-only (a run is appended to it once computed: a review); no file is fine."""
    path = points_path(out_dir, scene)
    _read(path)
    if os.path.isfile(path) and not (os.stat(path).st_mode & 0o222 and os.access(path, os.W_OK)):  # another's too
        raise ValueError(f"out must be a directory of dryfric figure outputs where each scene's points file can be "
                         f"written ({path!r} is read-only)")


def other_versions(out_dir: str, scene: str) -> dict:
    """``{version: count}`` of the runs in the scene's points file made by another package version
    (empty without a file): this version does not reuse them, since their numbers may differ, but
    leaves them in the file."""
    return _other_versions(_read(points_path(out_dir, scene)))


def _other_versions(records: list[dict]) -> dict:
    out: dict = {}
    for rec in records:
        if rec.get("version") != __version__:
            v = str(rec.get("version"))
            out[v] = out.get(v, 0) + 1
    return out


class Points:
    """The finished runs of one scene in ``out_dir`` (read at creation, appended after each run).

    ``reused`` and ``computed`` count the runs taken from the file and the runs made.  A file
    that is not a points file is refused (``ValueError`` naming it) rather than overwritten.
    """

    def __init__(self, out_dir: str, scene: str):
        self.path = points_path(out_dir, scene)
        self.reused, self.computed, self.runs_wall_s, self.n_truncated = 0, 0, 0.0, 0
        # the stamp before the read: a write between the two makes the next run read the file again
        self._seen = _stamp(self.path)
        records = _read(self.path)
        self._done = {rec["ident"]: rec for rec in records}
        self.other_versions = _other_versions(records)

    def estimate(self, params, seed: int, **kw) -> EstimateResult:
        """:func:`~dryfric_jax.api.estimate_diffusivity` ``(params, seed, **kw)``, or its kept result."""
        return self._run("estimate", params, seed, kw)

    def bruteforce(self, params, seed: int, **kw) -> BruteForceResult:
        """:func:`~dryfric_jax.api.bruteforce_diffusivity` ``(params, seed, **kw)``, or its kept result."""
        return self._run("bruteforce", params, seed, kw)

    def duration(self, params, seed: int, **kw) -> LEDuration:
        """:func:`~dryfric_jax.di_long_excursion_duration` ``(params, seed, **kw)``, or its kept result.  Its
        ``ValueError`` (fewer than 2 long excursions within the bound) keeps nothing.  Its truncated excursions are
        not in :meth:`summary`'s ``n_truncated`` (Fig. 3 reports them as ``le_dur_truncated``)."""
        return self._run("duration", params, seed, kw)

    def kept(self, params, seed: int, kind: str = "estimate", **kw) -> bool:
        """Whether the run ``(params, seed, **kw)`` of ``kind`` is already in the file (read at creation)."""
        return _ident(kind, params, seed, kw) in self._done

    def _run(self, kind, params, seed, kw):
        fn, cls = _KINDS[kind]
        ident = _ident(kind, params, seed, kw)
        if ident in self._done:
            return self._reuse(ident, cls)
        # claimed while computed, so another run of the scene into this directory waits for the run
        # and reuses it instead of computing it again (the two then share the scene's runs)
        with claim(self.path, ident, wait=True) as c:
            if self._changed():  # another process wrote the file since it was read here
                self._seen = _stamp(self.path)
                self._done = {rec["ident"]: rec for rec in _read(self.path)}
                if ident in self._done:
                    c.finish()
                    return self._reuse(ident, cls)
            report, extra = _REPORT.get(), {}
            if report is not None:  # not part of the run's identity: it changes nothing a run gives
                where = dict(kind=kind, method=kw.get("method"), params=params.as_dict(),
                             runs=self.reused + self.computed)
                report(dict(where, run=None))
                if kind != "bruteforce":
                    extra = dict(progress=lambda d: report(dict(where, run=d)))
            with warnings.catch_warnings():  # a scene reports its numbers; the notes stay in the record
                warnings.simplefilter("ignore", DryfricWarning)
                with abandon_on_interrupt():  # a run stopped short is not kept: no grace spent finishing it
                    r = fn(params, seed, **kw, **extra)
            if getattr(r, "stopped_by", None) == "interrupted":  # Ctrl-C inside the run: not a finished point
                raise KeyboardInterrupt
            rec = dict(ident=ident, kind=kind, version=__version__, finished_at=time.strftime("%Y-%m-%dT%H:%M:%S"),
                       result=r.to_dict())
            # keeps what others wrote there; the stamp is not taken again (another process may write the
            # file between this write and a stamp), so the next run reads the file once more.  A Ctrl-C or SIGTERM
            # during the write acts after it (put_record): the run is kept
            put_record(self.path, rec, lambda old: old["ident"] == ident, _read)
            c.finish()
        self._done[ident] = rec
        self.computed += 1
        self.runs_wall_s += r.wall_s
        self.n_truncated += 0 if kind == "duration" else getattr(r, "n_truncated", 0)
        return r

    def _reuse(self, ident, cls):
        self.reused += 1
        names = {f.name for f in dataclasses.fields(cls)}
        r = cls(**{k: v for k, v in self._done[ident]["result"].items() if k in names})
        self.runs_wall_s += r.wall_s
        self.n_truncated += 0 if cls is LEDuration else getattr(r, "n_truncated", 0)
        return r

    def _changed(self) -> bool:
        return _stamp(self.path) != self._seen

    def summary(self) -> dict:
        """For the scene's JSON: the file, the runs reused and computed, and the wall time of the
        runs the scene used, reused ones included (the scene's own ``wall_s`` counts this call only), and their
        truncated excursions (biased low where > 0; ``dryfric figures`` then exits 3), and the runs in the
        file made by other versions, not reused (``{version: count}``, read at creation)."""
        return dict(file=os.path.basename(self.path), reused=self.reused, computed=self.computed,
                    runs_wall_s=self.runs_wall_s, n_truncated=self.n_truncated, other_versions=self.other_versions)
