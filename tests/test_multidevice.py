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


SAME = textwrap.dedent("""
    import json, warnings, jax
    import dryfric_jax as dj
    warnings.simplefilter("ignore")
    p, q = dj.Params(**dj.FIG3), dj.Params.from_nondim(0.3, 0.5, 0.1)
    # what a device split may change: the time, and the slots the devices paid (idle and pad lanes)
    machine = {"wall_s", "lane_steps_per_s", "events_per_s", "work", "lane_utilization", "warnings"}
    keep = lambda r: {k: v for k, v in r.to_dict().items() if k not in machine}
    out = dict(devices=jax.device_count(),
               di=keep(dj.estimate_diffusivity(p, 5, n_excursions=2000)),  # 512 lanes
               pdmp=keep(dj.estimate_diffusivity(p, 6, method="pdmp", n_excursions=400, lanes=100)),
               # rounds until a CI target, cut by max_work after final rounds
               rtol=keep(dj.estimate_diffusivity(p, 7, n_excursions=300, lanes=64, rtol=0.01, max_work=3e7)),
               # 2 lanes: one per device on 3 (XLA:CPU compiled a one-lane shard to other arithmetic)
               few=keep(dj.estimate_diffusivity(q, 5, h=0.02 * q.tau0, n_excursions=300, lanes=2, block=32)))
    print(json.dumps(out))
""")


def test_three_devices_give_the_one_device_estimate_bit_for_bit():
    """A device count that does not divide the lanes (512 DI lanes and 100 PDMP lanes on 3 devices)
    pads them with copies that are dropped: every number of the estimate is the one-device number (the PDMP's at
    this point and seed: its "branch" layout rounds to other last bits at some others, README).
    So do 2 lanes on 3 devices: each device runs at least 2 lanes (a one-lane shard compiled to
    other arithmetic, changing the last bits of M0 and the CIs).
    Before, 512 lanes became 513 live ones on 3 devices: another sample, so a 6- or 12-core
    machine gave other numbers for the same seed than a 2- or 4-core one.  (Brute force and the
    path scenes pad and drop the same way, :func:`dryfric_jax.sharding.over_lanes`, equal up to
    the last bits.)"""
    def run(n):
        env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={n}")
        p = subprocess.run([sys.executable, "-c", SAME], env=env, capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, p.stderr[-2000:]
        return json.loads(p.stdout.strip().splitlines()[-1])

    one, three = run(1), run(3)
    assert (one.pop("devices"), three.pop("devices")) == (1, 3)
    assert one["rtol"]["stopped_by"] == "work_bound" and one["rtol"]["n_excursions"] > 300
    assert one == three


COUNT = textwrap.dedent("""
    import json, warnings, jax
    import dryfric_jax as dj
    warnings.simplefilter("ignore")
    p = dj.Params(Gamma=10.0, Delta=3.84, tau=0.125, tau_L=0.067, gamma_bar=0.342)
    out = []
    for kw in (dict(n_excursions=300, n_lanes=37), dict(n_excursions=200, n_lanes=64, bridge=False),
               dict(n_excursions=128, n_lanes=128, max_steps=5000)):
        d = dj.di_long_excursion_duration(p, 11, **kw)
        out.append([d.mean, d.ci, d.n_excursions, d.n_truncated, d.lane_steps, d.loop_steps])
    print(json.dumps(dict(devices=jax.device_count(), out=out)))
""")


def test_the_long_excursion_count_split_over_devices_is_the_one_device_count():
    """durations._run splits the lanes over the devices, its stopping rule and loop condition summed over them
    (psum): the same lanes must give the one-device numbers to the bit, with 37 lanes padded to 38 and 39 by
    lanes that count nothing, the raw count, and a bound that cuts LEs in flight.  A lane counted twice, a
    device's rule of its own (it stops on its share of the total) or a loop ended by one device changes N, the
    steps or the mean."""
    runs = []
    for n in (1, 2, 3):
        env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={n}")
        p = subprocess.run([sys.executable, "-c", COUNT], env=env, capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, p.stderr[-2000:]
        runs.append(json.loads(p.stdout.strip().splitlines()[-1]))
    assert [r["devices"] for r in runs] == [1, 2, 3]
    assert runs[0]["out"] == runs[1]["out"] == runs[2]["out"]
    assert runs[0]["out"][2][3] > 0  # the bound cut some
