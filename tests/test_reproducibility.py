"""Reproducibility: the same seed and settings give bit-identical numbers in separate processes;
different lane layouts give different (independent) samples whose estimates agree within the CI."""
import json
import math
import os
import subprocess
import sys
import warnings

import pytest

import dryfric_jax as dj

TIMING = {"wall_s", "lane_steps_per_s", "events_per_s"}


def _cli_json(argv):
    p = subprocess.run([sys.executable, "-m", "dryfric_jax.cli", *argv, "--json"], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    return {k: v for k, v in out.items() if k not in TIMING}


@pytest.mark.parametrize("argv", [
    ["estimate", "--n-excursions", "300", "--seed", "7"],
    ["estimate", "--method", "pdmp", "--dtype", "float32", "--n-excursions", "300", "--seed", "8"],
    ["bruteforce", "--t", "2", "--n-paths", "200", "--seed", "9"],
])
def test_same_seed_bit_identical_in_two_processes(argv):
    a, b = _cli_json(argv), _cli_json(argv)
    assert a == b  # every number, to the last bit (JSON floats round-trip exactly)
    assert math.isfinite(a.get("D", a.get("D_t")))


def test_an_estimates_json_holds_what_reproduces_it(tmp_path):
    """``--out`` records the N asked for (``n_requested``; ``n_excursions`` is what closed, more),
    the time limit and the package version besides seed, lanes and block: a run with those
    settings gives the same sums.  It recorded only the N closed, and a rerun with it differed
    (audit)."""
    out = tmp_path / "r.json"
    _cli_json(["estimate", "--n-excursions", "300", "--seed", "7", "--out", str(out)])
    r = json.loads(out.read_text())
    assert r["n_requested"] == 300 < r["n_excursions"] and r["max_time"] is None and r["version"] == dj.__version__
    again = _cli_json(["estimate", "--n-excursions", str(r["n_requested"]), "--seed", str(r["seed"]),
                       "--lanes", str(r["lanes"]), "--block", str(r["block"])])
    assert again["sums"] == r["sums"]


def _xla_flags_seen(flags):
    """XLA_FLAGS after importing dryfric_jax in a fresh process that then computes (so the backend
    started with them: an unknown flag would abort it)."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    if flags is not None:
        env["XLA_FLAGS"] = flags
    code = ("import os, dryfric_jax, jax; jax.numpy.ones(3).sum().block_until_ready(); "
            "print(os.environ['XLA_FLAGS'], len(jax.devices('cpu')))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    flags, n_cpu_devices = p.stdout.strip().rsplit(" ", 1)
    return flags, int(n_cpu_devices)


def test_import_asks_xla_for_deterministic_gpu_sums_and_a_device_per_core():
    # on a GPU, sums by atomic adds changed D_ci's last bit in 1 of 5 runs (dryfric_jax.xla_flags);
    # on a CPU, one device per core: a notebook used one core where the CLI used all (the numbers
    # do not depend on the device count, tests/test_multidevice.py)
    from dryfric_jax.xla_flags import cpu_cores

    n = cpu_cores()
    assert _xla_flags_seen(None) == (
        f"--xla_gpu_deterministic_ops=true --xla_force_host_platform_device_count={n}", n)
    assert (_xla_flags_seen("--xla_force_host_platform_device_count=1")  # the user's flag wins
            == ("--xla_force_host_platform_device_count=1 --xla_gpu_deterministic_ops=true", 1))
    assert _xla_flags_seen("--xla_gpu_deterministic_ops=false") == (
        f"--xla_gpu_deterministic_ops=false --xla_force_host_platform_device_count={n}", n)


def test_other_seed_differs(capsys):
    """In this process (two more subprocesses cost ~40 s of compiling in CI)."""
    from dryfric_jax.cli import main

    def run(seed):
        assert main(["estimate", "--n-excursions", "300", "--seed", str(seed), "--json"]) == 0
        return json.loads(capsys.readouterr().out)

    a, b = run(7), run(70)
    assert (a["seed"], b["seed"]) == (7, 70) and a["D"] != b["D"] and a["sums"] != b["sums"]


def test_a_legacy_prngkey_is_the_same_stream_as_its_seed():
    """jax.random.PRNGKey(s) (raw uint32[2]) and the seed s give bit-identical results; before, the
    raw key reached the engine unwrapped and failed there with a broadcasting error."""
    import jax

    p = dj.Params(**dj.FIG3)
    run = lambda k: _quiet_run(p, k)
    a, b, c = run(3), run(jax.random.PRNGKey(3)), run(jax.random.key(3))
    assert a.D == b.D == c.D and a.D_ci == b.D_ci == c.D_ci and a.M0 == b.M0 == c.M0
    assert a.seed == 3 and b.seed is None


@pytest.mark.parametrize("key,word", [(-1, "seed"), (2**62 + 1, "seed"), (True, "key"), (1.5, "key"), ("7", "key")])
def test_bad_keys_are_refused_by_name(key, word):
    """A seed out of [0, 2^62] or anything that is not a seed or one key: a ValueError naming it
    (before: OverflowError for 2^70, JAX's TypeError for 1.5 and "7")."""
    with pytest.raises(ValueError, match=f"^{word} must be"):
        dj.estimate_diffusivity(dj.Params(**dj.FIG3), key, n_excursions=100)


def test_a_batch_of_keys_is_refused():
    import jax

    with pytest.raises(ValueError, match=r"^key must be .* \(got an array of shape \(2,\)"):
        dj.estimate_diffusivity(dj.Params(**dj.FIG3), jax.random.split(jax.random.key(0)), n_excursions=100)


def _quiet_run(p, key):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        return dj.estimate_diffusivity(p, key, n_excursions=300)


@pytest.mark.parametrize("method", ["di", "pdmp"])
def test_lane_layouts_agree_within_ci(method):
    """128 and 1024 lanes: different chunking of the same law.  Other seeds, so the samples are
    independent (split(key, 128) is the first 128 keys of split(key, 1024)).

    Four comparisons (D and M0, two methods), each at 3 standard errors of the difference (the
    95% half-widths are 1.96 SE, so 3 SE = 1.53 hypot(ci1, ci2)): false-alarm rate ~1% in all,
    where a 95% level per comparison would fail ~19% of seeds.  N = 1e4 is where the delta-method
    CI is reliable (MIN_RELIABLE_N).

    K is fixed at 128 so that every device draws these same samples: the DI's default K is 256 on
    a GPU, a different draw, and an H100 drew the K = 256 runs bit for bit as a CPU does (D of
    the 128-lane run equal to 16 digits).  There these seeds fell 1.64 hypot(ci) (3.2 SE) apart;
    ten other seeds at 128 lanes gave D = 2.640e-3 +- 0.021e-3 (SE of their mean) at K = 256 and
    2.675e-3 +- 0.021e-3 at K = 128, both within 2 SE of the large runs' 2.64e-3: no sign of a
    K bias, a rare draw (2026-11-27)."""
    p = dj.Params(**dj.FIG3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        r1 = dj.estimate_diffusivity(p, 11, method=method, n_excursions=10_000, lanes=128, block=128)
        r2 = dj.estimate_diffusivity(p, 12, method=method, n_excursions=10_000, lanes=1024, block=128)
    assert r1.D != r2.D  # really different samples
    k = 3.0 / 1.96
    assert abs(r1.D - r2.D) <= k * math.hypot(r1.D_ci, r2.D_ci)
    assert abs(r1.M0 - r2.M0) <= k * math.hypot(r1.M0_ci, r2.M0_ci)


def test_a_ctrl_c_swallowed_in_a_callback_is_delivered_again(monkeypatch):
    """A KeyboardInterrupt raised where Python cannot propagate it (a garbage-collection callback,
    here a ``__del__``) was printed as 'Exception ignored' and lost: ``dryfric estimate`` given a
    Ctrl-C ~1 s after its start ran to the end and exited 0 (audit).  The hook the package installs
    on import delivers it to the main thread again (pytest swaps the hook per test: installed
    again here, over pytest's)."""
    import time

    from dryfric_jax.interrupts import keep_ctrl_c

    class Callback:
        def __del__(self):
            raise KeyboardInterrupt

    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)  # restored after the test
    keep_ctrl_c()
    ticks = []
    with pytest.raises(KeyboardInterrupt):
        Callback()  # collected at once: its KeyboardInterrupt is unraisable
        for _ in range(200):  # Python code for 10 s, where a pending interrupt is raised
            ticks.append(1)
            time.sleep(0.05)
    assert len(ticks) < 200
