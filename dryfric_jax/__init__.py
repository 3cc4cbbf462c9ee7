"""dryfric_jax: diffusivity and mobility of a particle under dry friction and colored noise.

Importing the package enables float64 in JAX (``jax_enable_x64``): the statistics are always
accumulated in float64; the simulation dtype is chosen per call (``dtype="float32"``).  It also
asks XLA for deterministic GPU reductions, so that the same seed gives bit-identical results on a
GPU too, and for one host device per CPU core, so that the lanes use every core (the numbers do
not depend on it; :mod:`dryfric_jax.xla_flags`), and makes sure a Ctrl-C is never swallowed by a
garbage-collection callback, and that a Ctrl-C while the ``dryfric`` command imports it exits 130
quietly (:mod:`dryfric_jax.interrupts`).  Before it imports JAX it checks that the installed JAX,
jaxlib and equinox are recent enough (:mod:`dryfric_jax.requirements`).
"""
from .interrupts import keep_ctrl_c, launched_as_cli, quiet_ctrl_c_while_starting

quiet_ctrl_c_while_starting()  # first: the imports below take 1-2 s (cli.main ends it)
# after it: importlib.metadata alone took > 0.25 s on a loaded 2-core CI machine, and a Ctrl-C there was a traceback
from .requirements import check_requirements  # noqa: E402

try:
    check_requirements()  # before importing JAX or equinox (dryfric_jax.requirements)
except ImportError as exc:
    if launched_as_cli():  # the dryfric command: one line and exit 2, no traceback
        import sys

        print(f"dryfric: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    raise
from .xla_flags import request_deterministic_gpu_ops, use_all_cpu_cores  # noqa: E402

keep_ctrl_c()  # before JAX registers its garbage-collection callback

request_deterministic_gpu_ops()  # before JAX starts its backend
use_all_cpu_cores()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

from . import theory  # noqa: E402
from .api import (  # noqa: E402
    BruteForceResult, DryfricWarning, EstimateResult, FileWarning, NoEstimateError, ProjectionWarning,
    SmallSampleWarning,
    bruteforce_diffusivity, default_h, estimate_diffusivity,
)
from .chain_law import ChainLaw, white_chain_law  # noqa: E402
from .combine import combine_estimates, gather_hosts  # noqa: E402
from .compile_cache import enable as enable_compilation_cache  # noqa: E402
from .di import DIModel, make_di_model  # noqa: E402
from .durations import LEDuration, NoCountError, default_duration_h, di_long_excursion_duration  # noqa: E402
from .estimators import MIN_RELIABLE_N, MIN_RELIABLE_PATHS, delta_method, psi_D, psi_M  # noqa: E402
from .ou import OUStep, ou_moments, ou_step  # noqa: E402
from .params import FIG3, Params  # noqa: E402
from .pdmp import PDMPModel, make_pdmp_model  # noqa: E402
from .plan import Plan, plan_estimate  # noqa: E402
from ._version import __version__  # noqa: E402, F401

__all__ = [
    "Params", "FIG3", "OUStep", "ou_step", "ou_moments", "DIModel", "make_di_model",
    "PDMPModel", "make_pdmp_model",
    "estimate_diffusivity", "bruteforce_diffusivity", "EstimateResult", "BruteForceResult",
    "DryfricWarning", "FileWarning", "ProjectionWarning", "SmallSampleWarning", "NoEstimateError", "default_h", "Plan",
    "plan_estimate",
    "delta_method", "psi_D", "psi_M", "MIN_RELIABLE_N", "MIN_RELIABLE_PATHS",
    "theory", "ChainLaw", "white_chain_law", "LEDuration", "NoCountError", "di_long_excursion_duration",
    "default_duration_h",
    "combine_estimates", "gather_hosts", "enable_compilation_cache",
]
