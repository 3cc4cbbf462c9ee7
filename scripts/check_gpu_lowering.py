"""Lower the engine's round for a CUDA GPU without one: checks that the ``"fused"`` layout's
Pallas kernel (``dryfric_jax.fused``) builds into Triton IR, in both dtypes.

jax 0.10 lowers for CUDA without its CUDA plugin (2026-11-27, jax 0.10.2 on a CPU-only machine: one
Triton kernel per dtype).  An older jax needs the plugin of the same version (no GPU, no driver),
best in a separate environment, since the plugin makes every jax import look for a GPU:

    python -m venv /tmp/cv && /tmp/cv/bin/pip install "jax==X" "jaxlib==X" "jax-cuda12-plugin==X" \\
        "jax-cuda12-pjrt==X" equinox absl-py   # X: the installed jax's version
    PYTHONPATH=$PWD /tmp/cv/bin/python scripts/check_gpu_lowering.py

Compiling the Triton IR to PTX happens on the device (``scripts/device_check.sh``); this only
checks the lowering.  Prints one line per dtype with the number of Triton kernels; exit 1 if
one failed.
"""
from __future__ import annotations

import sys
from functools import partial


def main() -> int:
    import jax
    import jax.numpy as jnp
    jax.config.update("jax_enable_x64", True)
    import dryfric_jax as dj
    from dryfric_jax import excursions as ex
    from dryfric_jax.di import make_di_model
    from dryfric_jax.params import FIG3

    p, n, bad = dj.Params(**FIG3), 1024, 0
    for dt in ("float32", "float64"):
        m = make_di_model(p, dj.default_h(p), dt)
        i64 = lambda v: jnp.asarray(v, jnp.int64)
        args = (m, ex.init_lanes(m, n), jax.random.split(jax.random.key(0), n), jnp.zeros(n, jnp.int64),
                i64(1000), i64(10**6), jnp.asarray(True), i64(0), jnp.asarray(True), i64(10))
        f = jax.jit(partial(ex._round_impl, block=256, events="fused"))
        try:
            exp = jax.export.export(f, platforms=["cuda"], disabled_checks=[
                jax.export.DisabledSafetyCheck.custom_call("__gpu$xla.gpu.triton")])(*args)
            k = exp.mlir_module().count("xla.gpu.triton")
            print(f"{dt}: lowered for cuda, {k} Triton kernel call(s)")
            bad += k == 0
        except Exception as exc:  # report and go on to the other dtype
            print(f"{dt}: FAILED {type(exc).__name__}: {str(exc)[:2000]}")
            bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
