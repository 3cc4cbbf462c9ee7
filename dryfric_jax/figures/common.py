"""Shared by the scenes: output files (PNG, PDF and the JSON of the numbers behind the figure)."""
from __future__ import annotations

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


def save(fig, out_dir: str, name: str, numbers: dict, t0: float) -> dict:
    """Write ``name.png``, ``name.pdf`` and ``name.json`` (numbers, wall time) into ``out_dir``."""
    numbers = dict(numbers, wall_s=time.perf_counter() - t0)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, f"{name}.png"), dpi=120)
    fig.savefig(os.path.join(out_dir, f"{name}.pdf"))
    plt.close(fig)
    write_atomic(os.path.join(out_dir, f"{name}.json"), dumps(numbers, indent=1))  # never a torn file
    return numbers
