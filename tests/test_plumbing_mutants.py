"""Mutation audit of the plumbing: lanes over devices (sharding.over_lanes), the XLA flags, the
Ctrl-C handlers and the per-point claims.  Each test here killed a mutant the other tests let
through (named in its docstring); all are exact (no tolerance) and fast (< 2 s each)."""
import os
import signal
import sys
import threading
import types

import jax
import jax.numpy as jnp
import numpy as np

from dryfric_jax import interrupts, outfiles, sharding, xla_flags


def _scaled(scale, keys, x, *, n, shift=0.0):
    """A lane function whose first argument is not a lane argument and is not a scalar."""
    return x[:, None] * scale[None, :n] + shift + jax.vmap(lambda k: jax.random.normal(k, (n,)))(keys)


_scaled_jit = jax.jit(_scaled, static_argnames=("n", "shift"))


def _compiles():
    """A list that the XLA compilations made while ``listening[0]`` is True are appended to."""
    seen, listening = [], [True]
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, _s, **_kw: seen.append(event) if listening[0] and "backend_compile" in event else None)
    return seen, listening


def test_over_lanes_pads_to_a_multiple_of_three_devices_and_drops_the_pads(monkeypatch, key):
    """Padding for a device count that is not 2 (on 2 devices ``n % 2 == -n % 2``: the mutant
    ``pad = n % len(devices)`` survived): three stand-in devices, and a stand-in compiled
    function that refuses a lane count they do not divide.  The real lanes' outputs are the
    unpadded function's, bit for bit, whatever the lane count; the non-lane first argument (a
    vector) is neither used for the lane count nor padded (mutants: the lane count read from
    ``args[0]``; every argument with a lane axis padded)."""
    seen = []

    def fake(fn, static, lane_args, devices):
        def f(*args):
            for a, flag in zip(args, lane_args):
                if flag:
                    assert a.shape[0] % len(devices) == 0
                    seen.append(a.shape[0])
                else:
                    assert a.shape == scale.shape
            return _scaled_jit(*args, **dict(static))
        return f

    monkeypatch.setattr(sharding.jax, "local_devices", lambda: ["d0", "d1", "d2"])
    monkeypatch.setattr(sharding, "_compiled", fake)
    scale = jnp.asarray([2.0, -1.0, 0.5, 7.0])
    for lanes in (1, 2, 4, 5):
        keys, x = jax.random.split(key, lanes), jnp.arange(lanes, dtype=jnp.float64)
        got = sharding.over_lanes(_scaled, (scale, keys, x), (False, True, True), n=3)
        ref = _scaled_jit(scale, keys, x, n=3)
        assert got.shape == (lanes, 3)
        np.testing.assert_array_equal(np.asarray(got), np.asarray(ref))
    assert seen == [3, 3, 3, 3, 6, 6, 6, 6]  # both lane arguments, padded to the next multiple of 3


def test_over_lanes_splits_the_lanes_over_every_device_and_keys_its_cache_by_the_static_values(key):
    """On the local devices (2 in the tests): the outputs are spread over all of them (mutant: one
    device's plain jit for 2 devices, the same numbers); a second static value gets its own
    executable (mutant: a cache keyed without the static values reused n=3's for n=4); the same
    static values passed in another order compile nothing (mutant: the key not sorted)."""
    devices = set(jax.local_devices())
    keys, x, scale = jax.random.split(key, 8), jnp.arange(8.0), jnp.asarray([1.0, 2.0, 3.0, 4.0])
    three = sharding.over_lanes(_scaled, (scale, keys, x), (False, True, True), n=3, shift=1.0)
    assert three.sharding.device_set == devices
    four = sharding.over_lanes(_scaled, (scale, keys, x), (False, True, True), shift=1.0, n=4)
    assert four.shape == (8, 4)  # the values: equal to the unsharded ones up to the last bits (sharding docstring)
    compiles, listening = _compiles()
    try:
        again = sharding.over_lanes(_scaled, (scale, keys, x), (False, True, True), shift=1.0, n=3)
        seen = len(compiles)
        jax.jit(lambda v: v * 3.5)(jnp.ones(5))  # a new function compiles: the listener hears it
    finally:
        listening[0] = False
    assert seen == 0 and len(compiles) >= 1
    np.testing.assert_array_equal(np.asarray(again), np.asarray(three))


def test_xla_flags_text_is_added_once_after_the_users_and_never_over_it(monkeypatch):
    """XLA_FLAGS by hand: a flag is appended once (a second request does nothing), after the
    user's text; one the user's text names is kept; the CLI's vector width is 512 bits and only
    asked for with ``vector_width`` (mutant: 256 survived)."""
    monkeypatch.setattr(xla_flags, "cpu_cores", lambda: 5)
    monkeypatch.setenv("XLA_FLAGS", "--xla_user_thing=1")
    xla_flags.use_all_cpu_cores()
    xla_flags.use_all_cpu_cores()
    assert os.environ["XLA_FLAGS"] == "--xla_user_thing=1 --xla_force_host_platform_device_count=5"
    xla_flags.use_all_cpu_cores(vector_width=True)
    assert os.environ["XLA_FLAGS"] == ("--xla_user_thing=1 --xla_force_host_platform_device_count=5 "
                                       "--xla_cpu_prefer_vector_width=512")
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_prefer_vector_width=256")
    xla_flags.use_all_cpu_cores(vector_width=True)
    assert os.environ["XLA_FLAGS"] == "--xla_cpu_prefer_vector_width=256 --xla_force_host_platform_device_count=5"


def test_cpu_cores_is_the_affinity_mask_and_falls_back_to_the_cpu_count(monkeypatch):
    """The cores this process may run on (a container or ``taskset`` limits them), not the
    machine's (mutant: ``os.cpu_count()`` survived on a machine where the two agree); an OS
    without the call, or one that refuses it, gives the CPU count."""
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 3, 5}, raising=False)
    assert xla_flags.cpu_cores() == 3

    def refuse(pid):
        raise OSError(38, "Function not implemented")

    monkeypatch.setattr(os, "sched_getaffinity", refuse)
    assert xla_flags.cpu_cores() == 64


class _Timer:
    made = []

    def __init__(self, delay, fn):
        self.delay, self.fn, self.daemon, self.started = delay, fn, None, False
        _Timer.made.append(self)

    def start(self):
        self.started = True


def test_the_ctrl_c_hook_is_installed_once_and_passes_everything_else_on(monkeypatch):
    """The unraisable hook: a KeyboardInterrupt (or a subclass) starts one daemon timer that
    interrupts the main thread after DELAY_S (stand-in timer: nothing is delivered); any other
    exception goes to the hook it replaced, once.  A second ``keep_ctrl_c()`` installs nothing
    (mutant: two hooks, two interrupts per Ctrl-C); mutants that swallowed the other exceptions,
    took only ``KeyboardInterrupt`` itself, or made the timer non-daemon survived."""
    got = []
    monkeypatch.setattr(sys, "unraisablehook", got.append)
    monkeypatch.setattr(interrupts.threading, "Timer", _Timer)
    _Timer.made.clear()
    interrupts.keep_ctrl_c()
    hook = sys.unraisablehook
    interrupts.keep_ctrl_c()
    assert sys.unraisablehook is hook
    other = types.SimpleNamespace(exc_type=ValueError)
    hook(other)
    assert got == [other] and _Timer.made == []

    class Sub(KeyboardInterrupt):
        pass

    hook(types.SimpleNamespace(exc_type=Sub))
    assert got == [other] and len(_Timer.made) == 1
    t = _Timer.made[0]
    assert (t.delay, t.fn, t.daemon, t.started) == (interrupts.DELAY_S, interrupts._thread.interrupt_main, True, True)


def test_a_windows_console_script_is_the_command(monkeypatch):
    """``dryfric.exe`` (pip's launcher on Windows) is the command (mutant: the suffix kept)."""
    monkeypatch.setattr(sys, "argv", ["/venv/Scripts/dryfric.exe", "theory"])
    monkeypatch.setattr(sys, "orig_argv", ["python", "/venv/Scripts/dryfric.exe", "theory"])
    assert interrupts.launched_as_cli()


def test_the_starting_handler_is_set_only_in_the_main_thread_and_removed_only_by_started(monkeypatch):
    """In the command's main thread the quiet handler is installed, and ``started()`` puts
    Python's back; from another thread nothing is installed (``signal.signal`` would raise
    there); ``started()`` leaves any other handler (a background job's ignored SIGINT, a
    program's own) alone (mutant: it always installed Python's)."""
    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(interrupts, "launched_as_cli", lambda: True)
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        errors = []
        t = threading.Thread(target=lambda: errors.append(interrupts.quiet_ctrl_c_while_starting() or "ok"))
        t.start()
        t.join()
        assert errors == ["ok"] and signal.getsignal(signal.SIGINT) is signal.default_int_handler
        interrupts.quiet_ctrl_c_while_starting()
        assert signal.getsignal(signal.SIGINT) is interrupts._stop_while_starting
        interrupts.started()
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        for other in (signal.SIG_IGN, lambda s, f: None):
            signal.signal(signal.SIGINT, other)
            interrupts.started()
            assert signal.getsignal(signal.SIGINT) is other
    finally:
        signal.signal(signal.SIGINT, before)


def test_claims_dir_is_one_per_results_file_whatever_the_path_spelling(tmp_path, monkeypatch):
    """Two sweeps started from other directories share one claims directory for one results file
    (mutant: the path not resolved, a relative spelling got its own), and two results files in one
    directory have their own (mutant: one ``.claims`` per directory)."""
    monkeypatch.chdir(tmp_path)
    os.mkdir("sub")
    absolute = str(tmp_path / "sub" / "r.jsonl")
    assert outfiles.claims_dir("sub/r.jsonl") == outfiles.claims_dir(absolute)
    assert outfiles.claims_dir(absolute) != outfiles.claims_dir(str(tmp_path / "sub" / "q.jsonl"))
    assert os.path.dirname(outfiles.claims_dir(absolute)) == str(tmp_path / "sub")
