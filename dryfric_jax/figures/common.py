"""Shared by the scenes: output files (PNG, PDF and the JSON of the numbers behind the figure)."""
from __future__ import annotations

import io
import json
import math
import os
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ..outfiles import dumps, write_atomic  # noqa: E402
from ..params import real_or_none  # noqa: E402


def exact_steps(t: float, h: float) -> int:
    """The number of steps h in the time t, which must be a whole number of them: a rounded count
    simulates another time than the one compared or plotted (Table 1's quick t' = 0.125 at h' =
    2e-3 ran 0.124; Fig. 4's DI recorded every 0.0494 tau0 against the PDMP's 0.05).  Numpy scalars
    count as the numbers they hold; a bool is no time."""
    tf, hf = real_or_none(t), real_or_none(h)
    if not all(a is not None and math.isfinite(a) and a > 0 for a in (tf, hf)) or tf / hf > 2**62:
        raise ValueError(f"t and h must be finite numbers > 0 with t / h <= 2^62 (got t = {t!r}, h = {h!r})")
    t, h = tf, hf
    n = round(t / h)
    if n < 1 or abs(n * h - t) > 1e-9 * t:
        raise ValueError(f"t = {t!r} must be a whole number of steps h = {h!r}")
    return n


def save(fig, out_dir: str, name: str, numbers: dict, t0: float, *, quick: bool, seed: int) -> dict:
    """Write ``name.png``, ``name.pdf`` and, last, ``name.json`` into ``out_dir``: the numbers, the wall
    time and what made them (seed, quick, the package's and JAX's versions: :func:`finished` reads them).
    Each file is drawn in memory and written by :func:`~dryfric_jax.outfiles.write_atomic`, so an interrupted
    write leaves the old file or none, never a torn one (a Ctrl-C inside ``savefig`` left a PDF cut at 848 bytes)."""
    numbers = dict(numbers, wall_s=time.perf_counter() - t0, **_meta(quick, seed, name))
    fig.tight_layout()
    try:
        for ext, kw in (("png", dict(dpi=120)), ("pdf", {})):
            buf = io.BytesIO()
            fig.savefig(buf, format=ext, **kw)
            write_atomic(os.path.join(out_dir, f"{name}.{ext}"), buf.getvalue())
    finally:
        plt.close(fig)
    write_atomic(os.path.join(out_dir, f"{name}.json"), dumps(numbers, indent=1))  # never a torn file
    return numbers


#: a scene's JSON layout, raised when a scene gains numbers without a new package version (its points, D and M0,
#: unchanged): a JSON of an older layout is not taken as finished.  2: Fig. 3's DI durations by counting releases
#: (``le_dur``), Fig. 6's velocity atom at 0 (``p_zero``); both came in 0.2.7.  Figs. 1-2: 2 since the DI row is one
#: of the paper's long excursions (it was a regeneration cycle) and the JSON holds the plotted arrays; Fig. 5: 2 since
#: its JSON holds the plotted U(t) paths (both 2026-12-07, 0.3.0); Fig. 8: 2 since its b = 0 case holds the exact
#: white-noise D^t its brute force estimates (``exact_bf``, 2026-12-07)
SCENE_LAYOUT = {"fig1_2": 2, "fig3": 2, "fig5": 2, "fig6": 2, "fig8": 2}


def _meta(quick: bool, seed: int, name: str) -> dict:
    import jax

    from .._version import __version__
    return dict(seed=int(seed), quick=bool(quick), version=__version__, jax_version=jax.__version__,
                layout=SCENE_LAYOUT.get(name, 1))


def finished(out_dir: str, name: str, quick: bool, seed: int) -> dict | None:
    """The numbers of scene ``name`` if ``out_dir`` holds its PNG, PDF and JSON, written by this version
    with the same seed, ``quick`` and :data:`SCENE_LAYOUT` (a rerun then skips it); else None."""
    paths = [os.path.join(out_dir, f"{name}.{ext}") for ext in ("png", "pdf", "json")]
    if not all(os.path.isfile(p) for p in paths):
        return None
    try:
        with open(paths[2]) as f:
            nums = json.load(f)
    except (OSError, ValueError):
        return None
    want = _meta(quick, seed, name)
    # of the same type too: Python's == took a JSON true for seed 1 and 2.0 for layout 2 (an audit)
    same = lambda k, got: type(got) is type(want[k]) and got == want[k]  # noqa: E731
    if not isinstance(nums, dict) or not all(same(k, nums.get(k, 1 if k == "layout" else None))
                                             for k in ("seed", "quick", "version", "layout")):
        return None
    return nums
