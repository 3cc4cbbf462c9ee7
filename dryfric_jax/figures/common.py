"""Shared by the scenes: output files (PNG, PDF and the JSON of the numbers behind the figure)."""
from __future__ import annotations

import os
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ..outfiles import dumps  # noqa: E402


def save(fig, out_dir: str, name: str, numbers: dict, t0: float) -> dict:
    """Write ``name.png``, ``name.pdf`` and ``name.json`` (numbers, wall time) into ``out_dir``."""
    numbers = dict(numbers, wall_s=time.perf_counter() - t0)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, f"{name}.png"), dpi=120)
    fig.savefig(os.path.join(out_dir, f"{name}.pdf"))
    plt.close(fig)
    with open(os.path.join(out_dir, f"{name}.json"), "w") as f:
        f.write(dumps(numbers, indent=1))
    return numbers
