"""Scenes: every figure and table of the paper, each by one function ``scene(out_dir, quick, seed)``
that writes ``<name>.png``, ``<name>.pdf`` and ``<name>.json`` (the numbers behind it).

``dryfric figures --fig all --quick --out DIR`` runs them all on a 2-core CPU in minutes;
without ``--quick`` the paper's settings (README "Reproducing the paper").
"""
from __future__ import annotations

import os

from ..api import MAX_FIGURE_SEED, check_seed
from ..outfiles import check_writable_dir
from .covariance import fig4
from .diffusivity import fig3, fig5, fig8
from .excursion import fig1_2
from .speed_error import fig9
from .touchette import fig6, fig7, table1

SCENES = {"1": fig1_2, "3": fig3, "4": fig4, "5": fig5, "6": fig6, "table1": table1, "7": fig7, "8": fig8, "9": fig9}


def run_figures(which: str, out_dir: str, quick: bool = False, seed: int = 0) -> dict:
    """Run one scene (``which`` a key of :data:`SCENES`) or ``"all"``; returns their numbers."""
    if which != "all" and which not in SCENES:
        raise ValueError(f"fig must be one of {['all', *SCENES]} (got {which!r})")
    seed = check_seed(seed, MAX_FIGURE_SEED, "2^62 - 2^20 (the scenes add offsets)")
    check_writable_dir(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    names = list(SCENES) if which == "all" else [which]
    return {n: SCENES[n](out_dir, quick, seed) for n in names}
