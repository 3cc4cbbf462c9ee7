"""The XLA flags the package sets: deterministic GPU reductions (at import) and, through the same
helper, the CLI's CPU flags (:func:`dryfric_jax.cli._use_all_cpu_cores`).

The same seed and settings must give bit-identical results.  On a CPU they do.  On a GPU, XLA may
sum with atomic additions, whose order (and so the last bit of a float sum) changes from run to
run: measured on an H200 (jax 0.11.2), ``test_same_seed_bit_identical_in_two_processes`` failed
once in 5 runs, with ``D_ci`` differing in its 16th digit, and passed 4 of 4 runs with
``--xla_gpu_deterministic_ops=true`` (4 of 4 is weak evidence on its own; the flag is XLA's switch
for exactly this).  CPU backends ignore the flag.

XLA reads ``XLA_FLAGS`` when JAX starts its backend (the first computation), so importing
``dryfric_jax`` sets the flag in time unless the program already computed with JAX; a program
that did can set ``XLA_FLAGS`` itself before its first computation.  A flag the user's
``XLA_FLAGS`` already names (``--xla_gpu_deterministic_ops=false``, say) is kept.
"""
from __future__ import annotations

import os


def default_xla_flag(name: str, value) -> None:
    """Add ``--name=value`` to ``XLA_FLAGS`` unless it names ``name`` already (the user's wins)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if name not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --{name}={value}".strip()


def request_deterministic_gpu_ops() -> None:
    """``--xla_gpu_deterministic_ops=true`` unless ``XLA_FLAGS`` names the flag (module docstring)."""
    default_xla_flag("xla_gpu_deterministic_ops", "true")
