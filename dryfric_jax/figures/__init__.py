"""Scenes: every figure and table of the paper, each by one function ``scene(out_dir, quick, seed)``
that writes ``<name>.png``, ``<name>.pdf`` and ``<name>.json`` (the numbers behind it).

``dryfric figures --fig all --quick --out DIR`` runs them all on a 2-core CPU in minutes;
without ``--quick`` the paper's settings (README "Reproducing the paper").
"""
from __future__ import annotations

import os
import time
import warnings

from .._version import __version__
from ..api import MAX_FIGURE_SEED, DryfricWarning, check_progress, check_seed
from ..outfiles import check_writable_dir
from .common import finished
from .covariance import fig4
from .diffusivity import fig3, fig5, fig8
from .excursion import fig1_2
from .points import check_points_file, other_versions, points_path, reporting
from .speed_error import fig9
from .touchette import fig6, fig7, table1

SCENES = {"1": fig1_2, "3": fig3, "4": fig4, "5": fig5, "6": fig6, "table1": table1, "7": fig7, "8": fig8, "9": fig9}


def run_figures(which: str, out_dir: str, quick: bool = False, seed: int = 0, redo: bool = False,
                progress=None) -> dict:
    """Run one scene (``which`` a key of :data:`SCENES`) or ``"all"``; returns their numbers.

    A scene whose PNG, PDF and JSON are already in ``out_dir``, made by this version with the same seed
    and ``quick``, is not run again (its numbers are read back; ``redo=True`` runs it anyway): a rerun
    after an interruption computes only the scenes not yet written, and inside Figs. 3, 8 and 9 only
    the runs not yet kept in their ``*.points.jsonl``.

    ``progress``: optional ``progress(dict)`` with the scene's file stem ``scene`` (``"fig3"``), its place ``index``
    (from 1) of ``total`` and ``stage``: ``"start"`` as a scene starts computing; ``"run"`` as each run of a scene of
    runs (Figs. 3, 8 and 9 (b)) starts and goes on, with :func:`~dryfric_jax.figures.points.reporting`'s keys
    (``kind``, ``method``, ``params``, ``runs``, ``run``) and ``elapsed_s`` (the scene's); ``"step"`` as a scene without
    runs starts a stage, with its text ``step`` (:func:`~dryfric_jax.figures.points.report_step`) and ``elapsed_s``;
    ``"done"`` once it is written, with ``wall_s``, or once it is found finished (``kept = True``, not run again).
    It changes no number.  An exception it raises ends the call and goes on up; the scenes written and the runs kept
    stay, so the same call resumes."""
    if which != "all" and which not in SCENES:
        raise ValueError(f"fig must be one of {['all', *SCENES]} (got {which!r})")
    seed = check_seed(seed, MAX_FIGURE_SEED, "2^62 - 2^20 (the scenes add offsets)")
    check_writable_dir(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    names = list(SCENES) if which == "all" else [which]
    for n in names:  # a points file that is not one is refused before any scene runs, not after the others
        check_points_file(out_dir, SCENES[n].__name__)
    check_progress(progress, live=False)  # its lines are the CLI's (dryfric figures)
    out = {}
    for i, n in enumerate(names, 1):
        scene = SCENES[n].__name__
        say = _Say(progress, dict(scene=scene, index=i, total=len(names)))
        kept = None if redo else finished(out_dir, scene, quick, seed)
        if kept is not None:
            out[n] = kept
            say(stage="done", kept=True)
            continue
        _say_other_versions(out_dir, scene)
        say(stage="start")
        with reporting(say.run if progress else None):
            out[n] = SCENES[n](out_dir, quick, seed)
        say(stage="done", kept=False, wall_s=time.perf_counter() - say.t0)
    return out


class _Say:
    """``run_figures``'s ``progress`` for one scene (``where``: its name and place); nothing where it is None."""

    def __init__(self, progress, where: dict):
        self.progress, self.where, self.t0 = progress, where, time.perf_counter()

    def __call__(self, **d):
        if self.progress is not None:
            self.progress({**self.where, **d})

    def run(self, d: dict):  # a run's or a step's report (points.reporting), with the scene's time so far
        self(**d, stage="step" if "step" in d else "run", elapsed_s=time.perf_counter() - self.t0)


def _say_other_versions(out_dir: str, scene: str) -> None:
    """Warn (``DryfricWarning``) before a scene runs when its points file holds runs of other versions:
    they are computed again (an upgrade would otherwise recompute an 87-minute Fig. 3 without a word)."""
    old = other_versions(out_dir, scene)
    if old:
        n, vs = sum(old.values()), ", ".join(f"{k}: {c}" for k, c in sorted(old.items()))
        name = os.path.basename(points_path(out_dir, scene))
        warnings.warn(f"{name} holds {n} runs made by other versions ({vs}), which "
                      f"version {__version__} does not reuse (their numbers may differ): {scene} computes its runs "
                      "again; the old records stay in the file (delete it to drop them)", DryfricWarning, stacklevel=3)
