import os

# the `dryfric` commands the tests run (in this process and in subprocesses, which inherit it) keep no
# compiled code in the user's cache directory; tests/test_compile_cache.py gives them a directory of its own
os.environ["DRYFRIC_CACHE_DIR"] = "off"
# the status lines are fitted to the terminal's width (api.status_line), which a stand-in terminal in a test takes
# from COLUMNS: unset, so that a test's lines do not depend on the shell it runs in (the width tests set it)
os.environ.pop("COLUMNS", None)

from dryfric_jax.xla_flags import use_all_cpu_cores  # noqa: E402

# one XLA host device per core, as importing dryfric_jax and the `dryfric` command do: lanes shard
# over the cores (and the sharded code path is what every test exercises).  Must be set before JAX
# starts its backend.
use_all_cpu_cores()

import math  # noqa: E402
import signal  # noqa: E402
import threading  # noqa: E402

import jax  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)


_approx = pytest.approx


def _nonzero(x) -> bool:
    """Every number in ``x`` (a number, a sequence, a dict's values, an array) is non-zero."""
    if isinstance(x, dict):
        return all(_nonzero(v) for v in x.values())
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        return False
    return a.size > 0 and bool(np.all(a != 0))


def _relative_approx(expected, rel=None, abs=None, nan_ok=False):
    """``pytest.approx`` whose ``rel`` alone means relative: pytest adds its default absolute 1e-12 to
    a ``rel`` given without ``abs``, so ``approx(1e-280, rel=1e-14)`` passed 0.0 (a theory audit's
    M0 test).  An expected 0 (where a relative tolerance means nothing) keeps pytest's default."""
    if rel is not None and abs is None and _nonzero(expected):
        abs = 0.0
    return _approx(expected, rel=rel, abs=abs, nan_ok=nan_ok)


pytest.approx = _relative_approx


@pytest.fixture(autouse=True, scope="session")
def python_handles_ctrl_c():
    """The Ctrl-C tests need Python's own SIGINT handler in this process and in the commands they
    start.  A background job (``pytest ... &`` from a script) starts with SIGINT ignored, and then
    ``_thread.interrupt_main`` does nothing and children inherit the ignored signal:
    test_a_ctrl_c_swallowed_in_a_callback_is_delivered_again failed at every run there (the
    failures an audit saw under load), as the only test of its file.  Restored at the end."""
    before = signal.getsignal(signal.SIGINT)
    main = threading.current_thread() is threading.main_thread()
    if main and before == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    if main and before == signal.SIG_IGN:
        signal.signal(signal.SIGINT, before)


@pytest.fixture
def key():
    return jax.random.key(20261121)


@pytest.fixture
def solve_rounding():
    """The rounding level of a dense Nystrom chain law (dryfric_jax.chain_law) for a mean that is
    zero by symmetry: 100 n eps v_rms with n grid nodes.  Its |M0| measured 2.3 n eps v_rms on
    one CPU (LAPACK's kernels differ by CPU, the old 1e-12 bound failed there by 20%); a drift from
    an asymmetric grid or kernel would be orders of magnitude larger."""
    return lambda law: 100 * law.n_nodes * np.finfo(float).eps * math.sqrt(law.mean_v2)


@pytest.fixture(autouse=True)
def a_machine_of_64_gib(monkeypatch):
    """The plan refuses a layout beyond this machine's memory (plan.check_layout_memory): the tests plan large
    layouts (2^22 lanes, 8.2 GiB by that check) on any machine, so in this process they see 64 GiB
    (tests/test_memory_bounds.py sets its own)."""
    from dryfric_jax import plan
    monkeypatch.setattr(plan, "host_memory", lambda: 64 * 2**30)
