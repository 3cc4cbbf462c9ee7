"""The XLA flags the package sets: at import, deterministic GPU reductions and one XLA host device
per CPU core (:func:`use_all_cpu_cores`); the CLI adds 512-bit vectors.

One device per core: the lanes' ``while_loop`` runs on one core per device, so with JAX's single
default CPU device a notebook used one core while the ``dryfric`` command used all of them
(measured on 2 cores, Fig. 3 point, N = 2e4, float64: 10.9-11.2 s on one device, 8.6 s on two,
the same D to the last bit).  The estimate does not depend on the device count (pad lanes,
:class:`dryfric_jax.rounds.Lanes`; tested with 1 and 3 devices), so this changes the speed,
not the numbers.  It also makes ``jax.devices("cpu")`` list one device per core for the rest of
the program; ``XLA_FLAGS=--xla_force_host_platform_device_count=1`` (set before importing)
keeps one.

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


def cpu_cores() -> int:
    """The cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def use_all_cpu_cores(vector_width: bool = False) -> None:
    """One XLA host device per core (module docstring), and with ``vector_width`` 512-bit vectors
    where the CPU has them (AVX-512: +5-20% lane steps/s, same results; a hint that CPUs with
    narrower vectors ignore).  Acts only before JAX starts its backend; a flag the user's
    ``XLA_FLAGS`` already sets wins."""
    default_xla_flag("xla_force_host_platform_device_count", cpu_cores())
    if vector_width:
        default_xla_flag("xla_cpu_prefer_vector_width", 512)
