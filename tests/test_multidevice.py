"""Lanes sharded over 2 forced CPU devices: the same lanes give the same estimate, no recompilation.

Runs in a subprocess because the device count must be fixed before JAX starts.
"""
import json
import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import json, warnings, jax
    import dryfric_jax as dj
    from dryfric_jax.excursions import compiled_round
    from dryfric_jax.di import DIModel
    warnings.simplefilter("ignore")
    p = dj.Params.from_nondim(0.3, 0.5, 0.1)
    r1 = dj.estimate_diffusivity(p, 5, h=0.02 * p.tau0, n_excursions=20000)
    f = compiled_round(DIModel)  # the round the estimate ran (default block)
    n = f._cache_size()
    r2 = dj.estimate_diffusivity(p, 6, h=0.03 * p.tau0, n_excursions=5000)
    print(json.dumps(dict(devices=jax.device_count(), D=r1.D, M0=r1.M0, n=r1.n_excursions,
                          compiled=n, recompiled=f._cache_size() != n)))
""")


def _run(n_devices):
    env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={n_devices}")
    p = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(p.stdout.strip().splitlines()[-1])


def test_two_devices_agree_with_one_and_do_not_recompile():
    """Same seed, same lanes: lane i gets split(key, lanes)[i] and fold_in(., block) wherever it
    runs, so sharding must reproduce the one-device chains (measured: bit-identical).  A sharding
    bug (a device's lanes duplicated, keys reused, sums lost in the reduction) changes N or D."""
    one, two = _run(1), _run(2)
    assert one["devices"] == 1 and two["devices"] == 2
    assert one["n"] == two["n"]
    assert two["D"] == pytest.approx(one["D"], rel=1e-12) and two["M0"] == pytest.approx(one["M0"], rel=1e-12)
    assert two["compiled"] >= 1 and not two["recompiled"]  # the counted function is the one that ran
