"""Lanes sharded over 2 forced CPU devices: pad lanes, the compaction decision and size, and the
block counts carried between the calls of a final round (:class:`dryfric_jax.rounds.Lanes`).

Each expected value comes from an independent run: the same lanes as one unsharded function
(``_run_round``) on exactly the real lanes, the round without compaction, or the round in one call.
One subprocess (the device count must be fixed before JAX starts) runs every check and prints
JSON; its work is bounded (small ``max_steps``) and so is its time (``timeout``).
"""
import json
import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import json, warnings
    import jax, jax.numpy as jnp, numpy as np
    import dryfric_jax as dj
    from dryfric_jax import rounds as rd
    from dryfric_jax import excursions as ex
    from dryfric_jax.di import make_di_model
    warnings.simplefilter("ignore")
    chain = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)  # excursions of a few hundred steps
    nd = jax.device_count()
    out = dict(devices=nd, COMPACT=rd.COMPACT, COMPACT_MIN_PER_DEVICE=rd.COMPACT_MIN_PER_DEVICE)
    calls, real_call = [], rd.Lanes._call_once

    def logged(self, lane, keys, b0, args):  # each call's lanes and the blocks each device ran
        lane, nb = real_call(self, lane, keys, b0, args)
        calls.append([int(keys.shape[0]), nb.tolist()])
        return lane, nb

    rd.Lanes._call_once = logged
    m = rd.COMPACT_MIN_PER_DEVICE  # lanes just below and at the threshold on each device
    out["compact"] = {k: rd.Lanes(chain, k).compact for k in (m * nd - nd, m * nd)}

    # 15 real lanes, 16 in the layout (a pad lane repeats lane 0; the compacted tail below has the same
    # shape, one compilation less): a paused round, then a final one
    R, BUDGET, MAXS, key = 15, 1000, 300, jax.random.key(1)

    def summary(st):
        return dict(in_flight=st.n_in_flight, trunc=st.n_truncated, stats=st.stats.tolist(),
                    lane_steps=st.lane_steps.tolist(), unfinished=st.n_unfinished)

    def two_rounds():
        ln = rd.Lanes(chain, R, block=8, max_steps=MAXS)
        paused = summary(ln.advance(jax.random.fold_in(key, 0), BUDGET))
        return ln, paused, summary(ln.finish(jax.random.fold_in(key, 1), BUDGET))

    ln, out["paused"], out["final"] = two_rounds()
    out["n_layout"] = ln.n
    # the reference: the same rounds as one unsharded function on exactly the real lanes
    lane, i64, ref = ex.init_lanes(chain, R), (lambda v: jnp.asarray(v, jnp.int64)), []
    for k, finish in ((0, False), (1, True)):
        keys = jax.random.split(jax.random.fold_in(key, k), R)
        lane, _ = ex._run_round(chain, lane, keys, i64(np.zeros(R)), i64(BUDGET), i64(MAXS), jnp.asarray(finish),
                                i64(0), jnp.asarray(True), i64(2**62), block=8, events=ln.events)
        phase, trunc = np.asarray(lane.phase), np.asarray(lane.n_trunc)
        ref.append(dict(in_flight=int((phase != ex.SEEK).sum()), trunc=int(trunc.sum()),
                        stats=np.stack(jax.device_get(lane.stats), axis=1).tolist(),
                        lane0_in_flight=bool(phase[0] != ex.SEEK), lane0_trunc=int(trunc[0])))
    out["ref_paused"], out["ref_final"] = ref

    # the same final round in calls of one block each
    per_call, rd.FINAL_CALL_LANE_STEPS = rd.FINAL_CALL_LANE_STEPS, 1
    calls.clear()
    _, _, out["final_many"] = two_rounds()
    out["calls_many"] = calls[1:]  # the final round's calls (the first is the paused round)
    rd.FINAL_CALL_LANE_STEPS = per_call

    # a compacted final round: 128 lanes, 64 per device; the same round without compaction
    for compact in (True, False):
        ln = rd.Lanes(chain, 128, block=8, max_steps=MAXS, compact=compact)
        calls.clear()
        st = ln.finish(jax.random.key(2), 300)
        out[f"compact_{compact}"] = dict(calls=[c[0] for c in calls], stats=st.stats.tolist(),
                                         trunc=st.n_truncated, unfinished=st.n_unfinished,
                                         lane_steps=st.lane_steps.tolist(), slots=ln.slot_steps)
    print(json.dumps(out))
""")


@pytest.fixture(scope="module")
def two():
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu")
    p = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out["devices"] == 2 and out["n_layout"] == 16
    return out


def test_compaction_is_decided_per_device(two):
    """Mutant E4 (the decision from the total lane count).  The final round compacts only where
    each device has at least COMPACT_MIN_PER_DEVICE lanes: 126 lanes on 2 devices (63 each) do
    not, 128 (64 each) do.  Decided on the total, every device count would compact at 64 lanes
    in all (one per device on 64 cores): a tail batch too small to gain, and one more shape to
    compile (seconds) in every final round."""
    m = two["COMPACT_MIN_PER_DEVICE"]
    assert two["compact"] == {str(2 * m - 2): False, str(2 * m): True}


def test_paused_round_counts_in_flight_excursions_of_real_lanes_only(two):
    """Mutant E9 (pad lanes counted in ``n_in_flight``).  15 lanes on 2 devices run 16, the pad lane
    a copy of lane 0, which is in flight when the round pauses: the reported in-flight count (the
    run's stopping rule adds it to the closed excursions) must be the 15 real lanes' one, as
    unsharded on 15 lanes, not one more."""
    ref = two["ref_paused"]
    assert ref["lane0_in_flight"]  # the pad lane's copy is in flight: a pad lane counted would show
    assert two["paused"]["in_flight"] == ref["in_flight"] > 0
    assert two["paused"]["stats"] == ref["stats"]  # the same 15 chains, lane by lane


def test_truncated_excursions_are_counted_on_real_lanes_only(two):
    """Mutant E10 (pad lanes counted in ``n_truncated``).  With max_steps = 300, excursions of a
    few hundred steps are often cut; lane 0 has cut ones, and so has its pad copy.  The reported
    truncated count (a warning, the CLI's exit status 3, part of the run's stopping rule) must
    be the 15 real lanes' one, in the paused and in the final round, as unsharded on 15 lanes."""
    for got, ref in ((two["paused"], two["ref_paused"]), (two["final"], two["ref_final"])):
        assert ref["lane0_trunc"] > 0  # the pad lane's copy has truncated excursions
        assert got["trunc"] == ref["trunc"]
    final = two["final"]
    assert final["stats"] == two["ref_final"]["stats"] and final["unfinished"] == 0
    assert sum(row[0] for row in final["stats"]) > 0  # complete excursions too, not only cut ones


def test_compacted_tail_runs_on_an_eighth_of_each_devices_lanes(two):
    """Mutant E3 (the tail's size from the total lane count).  128 lanes on 2 devices: the final
    round stops once at most 64 / COMPACT lanes per device are in flight and finishes them on
    a batch of that many per device, 128 / COMPACT in all; sized from the total it would stop
    earlier and run the tail on twice the lanes, paying for idle ones.  Compaction changes no
    number: the round without it gives the same sums."""
    on, off = two["compact_True"], two["compact_False"]
    assert on["calls"] == [128, 128 // two["COMPACT"]] and off["calls"] == [128]
    assert on["stats"] == off["stats"] and on["lane_steps"] == off["lane_steps"]
    assert (on["trunc"], on["unfinished"]) == (off["trunc"], off["unfinished"]) and on["slots"] < off["slots"]


def test_final_round_in_one_block_calls_keeps_each_devices_block_count(two):
    """Mutant E6 (``np.tile`` for ``np.repeat`` of the devices' block counts).  A final round in
    calls of one block each: after a call, each lane continues at its own device's block count.
    Once one device is done (it runs no block) and the other is not, a wrong mapping gives half
    of the running lanes a block index they already used, so they redraw the same numbers: other
    chains, another estimate.  The sums must be those of the round in one call."""
    many, one = two["final_many"], two["final"]
    assert len(two["calls_many"]) > 50 and all(c[0] == 16 for c in two["calls_many"])
    assert any(nb in ([1, 0], [0, 1]) for _, nb in two["calls_many"])  # one device done, the other not
    assert many["stats"] == one["stats"] and many["lane_steps"] == one["lane_steps"]
    assert (many["trunc"], many["in_flight"], many["unfinished"]) == (one["trunc"], one["in_flight"], one["unfinished"])
