"""Pooling independent runs (dryfric_jax.combine): exact against white noise, refusals, and two
processes of a jax.distributed job on the CPU."""
import dataclasses
import itertools
import json
import math
import os
import re
import socket
import subprocess
import sys
import textwrap
import warnings

import pytest

import dryfric_jax as dj
from dryfric_jax.combine import combine_estimates, gather_hosts

Z = 2.81  # as test_di_exact
P = dj.Params.from_nondim(1e-5, 1.0, 0.3)  # white noise, viscous + bias: light tails


@pytest.fixture(scope="module")
def runs():
    return [dj.estimate_diffusivity(P, s, n_excursions=10_000) for s in (41, 42, 43)]


def test_pooled_runs_match_the_exact_white_noise_values(runs):
    c = combine_estimates(runs)
    assert c.n_excursions == sum(r.n_excursions for r in runs)
    assert c.combined_from == [41, 42, 43] and c.seed is None and c.stopped_by == "combined"
    assert c.sums["n"] == c.n_excursions
    # the CI shrinks like N^-1/2: pooling the sums averages the runs' variance estimates, up to
    # O(1/n) terms (the runs' means differ), so the pooled CI is the runs' CIs scaled by n_i / N,
    # combined in quadrature.  Measured over 10 triples of seeds 41..70 at this point: D 1.0006 +-
    # 0.0010 (sd; largest 0.29% off), M0 1.0001 +- 0.0001.  1% is > 3x the largest
    N = sum(r.n_excursions for r in runs)
    for ci in ("D_ci", "M0_ci"):
        scaled = math.sqrt(sum((getattr(r, ci) * r.n_excursions) ** 2 for r in runs)) / N
        assert getattr(c, ci) == pytest.approx(scaled, rel=0.01), ci
    assert abs(c.D - dj.theory.exact_D(P)) <= Z / 1.96 * c.D_ci, (c.D, c.D_ci)
    assert abs(c.M0 - dj.theory.exact_M0(P)) <= Z / 1.96 * c.M0_ci, (c.M0, c.M0_ci)
    # the pooled estimate lies within the runs' range, weighted by their excursions
    assert min(r.D for r in runs) <= c.D <= max(r.D for r in runs)


def test_one_run_combines_to_itself_and_round_trips_through_json(runs):
    r = runs[0]
    c = combine_estimates([r])
    assert (c.D, c.D_ci, c.M0, c.M0_ci, c.mean_duration) == (r.D, r.D_ci, r.M0, r.M0_ci, r.mean_duration)
    via_json = combine_estimates([json.loads(json.dumps(x.to_dict())) for x in runs])
    assert (via_json.D, via_json.D_ci) == (combine_estimates(runs).D, combine_estimates(runs).D_ci)
    pooled = combine_estimates(runs)
    assert pooled.version == runs[0].version != "" and pooled.n_requested == sum(r.n_requested for r in runs)
    # a combined result combines further, keeping its seeds: the pool of all, to rounding (each pooling rounds its
    # sums once, exactly: so the pool of a pool may differ in the last bit, but not with the order of the runs)
    again = combine_estimates([combine_estimates(runs[:2]), runs[2]])
    assert again.D == pytest.approx(combine_estimates(runs).D, rel=1e-13) and again.combined_from == [41, 42, 43]


def test_a_stream_pooled_twice_is_refused_whatever_made_it(runs):
    """A key-made run records its key (api.key_id), so its stream is known: seed 5 runs on jax.random.key(5),
    and a pool remembers the keys it holds. Both pairs below were pooled with only the "assumed independent"
    note, counting excursions twice (a sweep audit: key(5) with N = 1000 against seed 5 with N = 3000, and a
    pool of two key-made runs pooled again with one of them)."""
    import jax

    p = P
    k5 = dj.estimate_diffusivity(p, jax.random.key(5), n_excursions=600)
    assert k5.seed is None and k5.key == dj.api.key_id(jax.random.key(5)) == "key<fry>:00000000:00000005"
    assert k5.sums == dj.estimate_diffusivity(p, 5, n_excursions=600).sums  # the same stream, to the bit
    s5 = dj.estimate_diffusivity(p, 5, n_excursions=1200)  # more excursions: other sums, the same stream
    assert s5.key is None and "key " not in s5.summary() and "key key<fry>" in k5.summary()
    with pytest.raises(ValueError, match=r"^results must draw different random streams: seed 5 \(results\[0\]\) and key "
                                         r"key<fry>:00000000:00000005 \(results\[1\]\) are the same stream"):
        combine_estimates([s5, k5])
    # a raw PRNGKey is the same key
    raw = dj.estimate_diffusivity(p, jax.random.PRNGKey(7), n_excursions=600)
    other = dj.estimate_diffusivity(p, jax.random.split(jax.random.key(7))[1], n_excursions=600)
    with warnings.catch_warnings():
        warnings.simplefilter("error", dj.DryfricWarning)  # different keys are independent streams: no note
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        pool = combine_estimates([raw, other])
    assert pool.combined_from == [raw.key, other.key] and raw.key.endswith(":00000000:00000007")
    with pytest.raises(ValueError, match="are the same stream"):
        combine_estimates([pool, other])
    with pytest.raises(ValueError, match="are the same stream"):
        combine_estimates([pool, dj.estimate_diffusivity(p, 7, n_excursions=600)])
    # through JSON too
    assert combine_estimates([json.loads(json.dumps(pool.to_dict())), runs[0]]).combined_from == [*pool.combined_from, 41]


def test_refusals_name_what_differs(runs):
    with pytest.raises(ValueError, match="seeds must differ .*41"):
        combine_estimates([runs[0], runs[0]])
    # a run made from a key has no seed: the same run twice (the same key, or seed 41 and its key) is
    # seen by its sums (it was pooled, its excursions counted twice)
    keyed = dataclasses.replace(runs[0], seed=None)
    for pair in ([keyed, keyed], [runs[0], keyed], [runs[1], keyed, runs[0]]):
        with pytest.raises(ValueError, match=r"^results must be different runs: results\[\d\] and results\[\d\] "
                                             "have the same excursion sums"):
            combine_estimates(pair)
    with pytest.warns(dj.DryfricWarning, match="assumed independent"):
        combine_estimates([runs[1], keyed])
    with pytest.raises(ValueError, match="must share h"):
        combine_estimates([runs[0], dataclasses.replace(runs[1], h=2 * runs[1].h)])
    with pytest.raises(ValueError, match="must share params"):
        combine_estimates([runs[0], dataclasses.replace(runs[1], params={**runs[1].params, "tau": 2e-5})])
    # parameters equal to 1e-12 (relative), as h is compared: Params.from_nondim gives tau = 0.49999999999999994
    # for 0.5, the same run to the last bit, and such a pair was refused (found by a user audit); 1e-9 apart, not
    tau = runs[1].params["tau"]
    ulp = dataclasses.replace(runs[1], params={**runs[1].params, "tau": math.nextafter(tau, 0.0)})
    assert combine_estimates([runs[0], ulp]).n_excursions == runs[0].n_excursions + runs[1].n_excursions
    with pytest.raises(ValueError, match="must share params"):
        combine_estimates([runs[0], dataclasses.replace(runs[1], params={**runs[1].params, "tau": tau * (1 + 1e-9)})])
    with pytest.raises(ValueError, match="no excursion sums"):
        combine_estimates([{**runs[0].to_dict(), "sums": {}}])
    with pytest.raises(ValueError, match="at least one"):
        combine_estimates([])


@pytest.mark.parametrize("edit,field", [
    (dict(wall_s="x"), "wall_s"), (dict(seed=[1]), "seed"), (dict(warnings=5), "warnings"),
    (dict(combined_from=5), "combined_from"), (dict(n_truncated=-1), "n_truncated"), (dict(ci_level=2.0), "ci_level"),
    (dict(params={"Gamma": 5.0}), "params"), (dict(params=[1, 2]), "params"),
    (dict(sums={"t": 0.0}), "finite excursion sums"), (dict(sums={"n": math.nan}), "finite excursion sums"),
    (dict(sums={"U2": -5.0}), "finite excursion sums"),
    (dict(sums={"t": "x"}), "finite excursion sums"),
    (dict(n_requested=-3), "n_requested"), (dict(max_time=0.0), "max_time"), (dict(version=1), "version"),
    (dict(max_work="x"), "max_work"), (dict(max_work=None), "max_work"), (dict(max_work=-5.0), "max_work"),
    (dict(lane_utilization=1.5), "lane_utilization"),
])
def test_a_malformed_result_is_refused_by_name(runs, edit, field):
    """A hand-edited or foreign file: a TypeError or OverflowError before, or D = nan (t = 0) and
    a negative D (U2 < 0) with exit 0."""
    d = runs[1].to_dict()
    d.update({k: ({**d["sums"], **v} if k == "sums" else v) for k, v in edit.items()})
    with pytest.raises(ValueError, match=f"^run-b.json must have {field}"):
        combine_estimates([runs[0].to_dict(), d], labels=["run-a.json", "run-b.json"])
    with pytest.raises(ValueError, match=rf"^results\[1\] must have {field}"):
        combine_estimates([runs[0], d])


@pytest.mark.parametrize("other,what", [({"sums": {}}, r"run-b.json lacks \['D'"), ({"D": "x"}, "run-b.json lacks"),
                                        (5, r"\(run-b.json is of type int\)")])
def test_a_foreign_result_is_named(runs, other, what):
    """A file without an estimate's fields was refused without its name ('a dict lacks ...')."""
    with pytest.raises(ValueError, match=f"^results must .*{what}"):
        combine_estimates([runs[0].to_dict(), other], labels=["run-a.json", "run-b.json"])


@pytest.mark.parametrize("bad", [None, 5, "r.json", {}])
def test_results_must_be_a_list(bad):
    with pytest.raises(ValueError, match="^results must"):
        combine_estimates(bad)


def test_gather_hosts_in_one_process_is_the_run_itself(runs):
    g = gather_hosts(runs[0])
    assert (g.D, g.D_ci, g.n_excursions, g.combined_from) == (runs[0].D, runs[0].D_ci, runs[0].n_excursions, [41])
    # seeds past 2^53 and a pooled result's seeds come through exactly (2^62 - 1 came back as 2^62, a
    # pooled result's seeds as [None] with a key warning), and so do the integer counts
    big = dataclasses.replace(runs[0], seed=2**62 - 1, work=2**53 + 1)
    assert gather_hosts(big).combined_from == [2**62 - 1] and gather_hosts(big).work == 2**53 + 1
    pooled = combine_estimates(runs)
    with warnings.catch_warnings():
        warnings.simplefilter("error", dj.DryfricWarning)
        g = gather_hosts(pooled)
    assert g.combined_from == pooled.combined_from and (g.D, g.D_ci) == (pooled.D, pooled.D_ci)
    # the pool's work bound is the sum of the runs' bounds, as its work is (it was the first run's)
    assert pooled.max_work == sum(r.max_work for r in runs) and pooled.work == sum(r.work for r in runs)
    with pytest.raises(ValueError, match="result has no excursion sums"):  # was a TypeError
        gather_hosts({**runs[0].to_dict(), "sums": None})
    with pytest.raises(ValueError, match="result must have max_work a number >= 0"):
        gather_hosts(dataclasses.replace(runs[0], max_work="x"))


_HOST = textwrap.dedent("""
    import json, sys
    import jax
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=sys.argv[2], num_processes=2, process_id=int(sys.argv[1]))
    import dryfric_jax as dj
    from dryfric_jax.combine import gather_hosts
    p = dj.Params.from_nondim(1e-5, 1.0, 0.3)
    i = jax.process_index()  # runs of other sizes and layouts: each host's own counts must reach every host
    r = dj.estimate_diffusivity(p, 100 + i, n_excursions=3000 + 1000 * i, lanes=64 * (1 + i),
                                max_work=(5e5 if i == 0 else 1e11))  # process 0's run ends at its work bound
    g = gather_hosts(r)
    # runs combine_estimates refuses (other dtypes) are refused on every process (they were pooled, each process
    # labelling the pool with its own dtype)
    r2 = dj.estimate_diffusivity(p, 200 + i, n_excursions=300, dtype=("float64", "float32")[i])
    try:
        gather_hosts(r2)
        refused = None
    except ValueError as e:
        refused = str(e)
    print(json.dumps(dict(local=r.to_dict(), pooled=g.to_dict(), refused=refused)))
""")


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::dryfric_jax.DryfricWarning")
def test_two_processes_pool_their_runs(tmp_path):
    """A jax.distributed job of 2 CPU processes: both return the pool of both runs, which is
    what combining the two runs' results in one process gives."""
    with socket.socket() as s:
        s.bind(("localhost", 0))
        addr = f"localhost:{s.getsockname()[1]}"
    script = tmp_path / "host.py"
    script.write_text(_HOST)
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=1"}
    procs = [subprocess.Popen([sys.executable, str(script), str(i), addr], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=env) for i in range(2)]
    outs = []
    for p in procs:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err[-2000:]
        outs.append(json.loads(out.strip().splitlines()[-1]))
    local = [o["local"] for o in outs]
    pooled = [o["pooled"] for o in outs]
    assert pooled[0]["D"] == pooled[1]["D"] and pooled[0]["combined_from"] == [100, 101]
    ref = combine_estimates(local)
    assert (pooled[0]["D"], pooled[0]["D_ci"], pooled[0]["n_excursions"]) == (ref.D, ref.D_ci, ref.n_excursions)
    # the per-host counts too (each host copied its own n_requested, max_work, lanes: 6000 on one, 8000 on the other)
    for name in ("n_requested", "max_work", "lanes", "block", "work", "n_truncated", "wall_s", "predicted_work"):
        assert pooled[0][name] == pooled[1][name] == getattr(ref, name), name
    assert ref.n_requested == 7000 and ref.lanes == 0  # the runs' sizes and lanes differ
    # every field, not the sums and counts alone: process 1 copied its own warnings and max_steps for both hosts
    # (an audit saw its pool of a run with truncated excursions without the warning of the bias)
    assert pooled[0] == pooled[1], [k for k in pooled[0] if pooled[0][k] != pooled[1][k]]
    assert local[0]["stopped_by"] == "work_bound" and local[0]["max_steps"] != local[1]["max_steps"]
    assert pooled[1]["warnings"] == ref.warnings and pooled[1]["max_steps"] == ref.max_steps == 0
    assert any(w.startswith("work bound reached") for w in pooled[1]["warnings"])
    for o in outs:
        assert o["refused"].startswith("results must share dtype: process 0's result has 'float64', process 1's "
                                       "result has 'float32'")


def test_a_sweep_record_combines_with_a_new_run(tmp_path, runs):
    """A point of a sweep's results file pools with a later run of the same point."""
    from dryfric_jax import sweep

    out = tmp_path / "s.jsonl"
    sweep.run_sweep(sweep.grid(**{k: [v] for k, v in P.as_dict().items()}), str(out), seed=7, n_excursions=2000)
    rec = json.loads(out.read_text().splitlines()[0])
    c = combine_estimates([rec, runs[0]])
    assert c.n_excursions == rec["result"]["n_excursions"] + runs[0].n_excursions
    assert c.combined_from == [rec["seed"], 41]


def test_the_cli_pools_a_sweep_file_line_by_line(tmp_path, runs, capsys):
    """``dryfric combine`` reads a sweep's JSON Lines file as one result per line (it failed with
    'Extra data' past the first line, audit): the same point swept with two seeds pools to the
    API's pool of the two records; a line of another point is refused, named by its line."""
    from dryfric_jax import sweep
    from dryfric_jax.cli import main

    out = tmp_path / "s.jsonl"
    grid = sweep.grid(**{k: [v] for k, v in P.as_dict().items()})
    for seed in (7, 8):
        sweep.run_sweep(grid, str(out), seed=seed, n_excursions=500)
    recs = [json.loads(x) for x in out.read_text().splitlines()]
    assert main(["combine", str(out), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    want = combine_estimates(recs)
    assert (got["D"], got["D_ci"], got["n_excursions"]) == (want.D, want.D_ci, want.n_excursions)
    sweep.run_sweep(sweep.grid(**{**{k: [v] for k, v in P.as_dict().items()}, "Gamma": [2 * P.Gamma]}), str(out),
                    seed=7, n_excursions=500)
    assert main(["combine", str(out)]) == 2
    assert f"{out}:3 has" in capsys.readouterr().err
    # a line that is not JSON is named by its number (the message said line 1 of the file)
    out.write_text("".join(x + "\n" for x in out.read_text().splitlines()[:2]) + "garbage{\n")
    assert main(["combine", str(out)]) == 2
    assert f"from {str(out)!r} line 3 (not a JSON object)" in capsys.readouterr().err


def test_a_file_saved_with_a_byte_order_mark_is_read(tmp_path, runs, capsys):
    """An ``--out`` file re-saved by an editor that writes a UTF-8 byte-order mark (Windows Notepad)
    is read as the same result (it was refused as 'Unexpected UTF-8 BOM'), and so is a sweep file."""
    from dryfric_jax import sweep
    from dryfric_jax.cli import main
    from dryfric_jax.outfiles import dumps

    files = []
    for i, r in enumerate(runs[:2]):
        files.append(tmp_path / f"r{i}.json")
        files[-1].write_bytes(b"\xef\xbb\xbf" + dumps(r.to_dict(), indent=1).encode())
    assert main(["combine", *map(str, files), "--json"]) == 0
    got, want = json.loads(capsys.readouterr().out), combine_estimates(runs[:2])
    assert (got["D"], got["D_ci"], got["n_excursions"]) == (want.D, want.D_ci, want.n_excursions)
    # a sweep resumes from such a file: the point is found done, not refused as a foreign file
    out = tmp_path / "s.jsonl"
    grid = sweep.grid(**{k: [v] for k, v in P.as_dict().items()})
    sweep.run_sweep(grid, str(out), seed=7, n_excursions=500)
    out.write_bytes(b"\xef\xbb\xbf" + out.read_bytes())
    got = sweep.run_sweep(grid, str(out), seed=7, n_excursions=500)
    assert (got["computed"], got["skipped"]) == (0, 1)


def test_runs_of_other_versions_are_refused_unless_allowed(runs):
    """A version may change a seed's numbers or fix a result (a sweep reruns older points), so pooling
    versions is refused by name unless asked for; then it is said, and the pool's version is "mixed"
    (it was pooled with a warning only: a sweep audit)."""
    old, v = dataclasses.replace(runs[1], version="0.1.0"), re.escape(dj.__version__)
    with pytest.raises(ValueError, match=rf"^results must share version: results\[0\] has '{v}', results\[1\] has "
                                         r"'0\.1\.0'.*allow_mixed_versions=True"):
        combine_estimates([runs[0], old])
    with pytest.warns(dj.DryfricWarning, match=rf"versions '0\.1\.0', '{v}'"):
        c = combine_estimates([runs[0], old], allow_mixed_versions=True)
    assert c.version == "mixed" and c.D == combine_estimates(runs[:2]).D
    with pytest.raises(ValueError, match="results must share version"):  # a mixed pool is a version of its own
        combine_estimates([c, runs[2]])


def test_the_cli_says_and_keeps_the_pools_own_notes(tmp_path, runs, capsys):
    """``dryfric combine`` silences the library's warnings and prints the result's ``warnings``
    instead: the two notes combine makes of the pool itself (runs of other versions, runs made
    from a key) must be among them, on stderr and in the JSON (they were warned only, so the
    command said neither)."""
    from dryfric_jax.cli import main
    from dryfric_jax.outfiles import dumps

    files = [tmp_path / "old.json", tmp_path / "keyed.json"]
    files[0].write_text(dumps(dataclasses.replace(runs[0], version="0.1.0").to_dict()))
    files[1].write_text(dumps(dataclasses.replace(runs[1], seed=None).to_dict()))
    assert main(["combine", *map(str, files), "--json"]) == 2  # versions: refused by name
    assert "results must share version" in capsys.readouterr().err
    assert main(["combine", *map(str, files), "--json", "--out", str(tmp_path / "pool.json"),
                 "--allow-mixed-versions"]) == 0
    cap = capsys.readouterr()
    got = json.loads(cap.out)
    notes = [w for w in got["warnings"] if f"versions '0.1.0', '{dj.__version__}'" in w or "assumed independent" in w]
    assert len(notes) == 2 and got["version"] == "mixed", got["warnings"]
    assert all(f"dryfric: warning: {w}" in cap.err for w in notes)
    assert json.loads((tmp_path / "pool.json").read_text())["warnings"] == got["warnings"]
    # the pool pooled again with a third run: the key note, the same words again, is kept once
    (tmp_path / "third.json").write_text(dumps(runs[2].to_dict()))
    assert main(["combine", str(tmp_path / "pool.json"), str(tmp_path / "third.json"), "--json",
                 "--allow-mixed-versions"]) == 0
    again = json.loads(capsys.readouterr().out)["warnings"]
    assert sum("assumed independent" in w for w in again) == 1 and notes[0] in again, again


def test_files_parsed_by_json_load_pool_with_tau_L_inf(runs):
    """The package writes tau_L = inf as the string "inf" (strict JSON); a user who reads its files
    with ``json.load`` and pools them in Python gets the float back (it was refused: "tau_L must be
    a real number (got 'inf')"), and so do a sweep's records read line by line."""
    from dryfric_jax.outfiles import dumps

    inf = [dataclasses.replace(r, params={**r.params, "tau_L": math.inf}) for r in runs[:2]]
    parsed = [json.loads(dumps(r.to_dict())) for r in inf]
    assert parsed[0]["params"]["tau_L"] == "inf"
    want, got = combine_estimates(inf), combine_estimates(parsed)
    assert got.params["tau_L"] == math.inf and (got.D, got.D_ci, got.M0, got.sums) == (want.D, want.D_ci, want.M0, want.sums)
    record = json.loads(dumps({"params": inf[0].params, "seed": inf[0].seed, "status": "ok",
                               "result": {k: v for k, v in inf[0].to_dict().items() if k != "params"}}))
    assert combine_estimates([record, parsed[1]]).D == want.D


def test_the_pool_does_not_depend_on_the_order_of_the_runs(runs):
    # more runs than the fixture's three, so that there are orders whose float sums differ: with sum() the
    # last digit of the pooled M0 and D followed the order of the files given to 'dryfric combine'
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)  # the small-N note
        more = runs + [dj.estimate_diffusivity(P, s, n_excursions=2_000) for s in (44, 45)]
    first = combine_estimates(more)
    for order in itertools.permutations(range(len(more))):
        c = combine_estimates([more[i] for i in order])
        assert (c.D, c.D_ci, c.M0, c.M0_ci, c.mean_duration, c.sums) == \
            (first.D, first.D_ci, first.M0, first.M0_ci, first.mean_duration, first.sums), order


def test_runs_whose_params_differ_within_rounding_pool_the_same_in_any_order(runs):
    """Runs whose parameters agree to 1e-12 (the same run; 'Params.from_nondim' and SI input differ in the last
    bit) pool: the pool's params, its D and M0 (scaled by them) and its key were the first run's, so its last
    digits followed the order of the files (an audit: Gamma 5.000000000000001 first gave D ...608, second ...6062).
    Every field but the list of seeds and the runs' notes, which keep the order given, is now the same in every
    order, also with a ci_level that differs within rounding (a review: the first run's ci_level was the pool's)."""
    a, b, c = runs
    p = dict(b.params, Gamma=b.params["Gamma"] * (1 + 8e-16), Delta=b.params["Delta"] * (1 - 8e-16))
    assert p != b.params
    odd = [dataclasses.replace(b, params=p, key="key<fry>:00000000:0000002a", seed=None, method_reason="other"),
           dataclasses.replace(b, ci_level=0.95 * (1 + 6e-16))]  # ties with a and c but for its ci_level
    for b in odd:
        pools = [combine_estimates(list(order)).to_dict() for order in itertools.permutations([a, b, c])]
        for pool in pools:
            assert {k: v for k, v in pool.items() if k not in ("combined_from", "warnings")} == \
                {k: v for k, v in pools[0].items() if k not in ("combined_from", "warnings")}
        assert pools[0]["key"] is None and pools[0]["seed"] is None  # a pool is named by combined_from
        assert sorted(map(str, pools[0]["combined_from"])) == sorted(map(str, [a.seed, b.key or b.seed, c.seed]))


@pytest.mark.parametrize("field,other", [("method", "pdmp"), ("delta", 0.01), ("L_X", 0.5), ("dtype", "float32")])
def test_every_setting_of_the_law_must_be_shared(runs, field, other):
    """Runs of another method, step or dtype sample another law: each one alone is refused, naming it
    (only h and params were tested here, ci_level in test_bad_input)."""
    with pytest.raises(ValueError, match=f"^results must share {field}: results\\[0\\] has"):
        combine_estimates([runs[0], dataclasses.replace(runs[1], **{field: other})])


def test_the_small_n_note_is_the_pools(runs):
    """The pool says N < MIN_RELIABLE_N once, for its own N: two runs of ~2000 excursions give one
    note naming their sum, and a small run pooled with a large one (N >= 10^4) gives none."""
    from dryfric_jax.api import small_n_note

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)  # the runs' own small-N notes
        small = [dj.estimate_diffusivity(P, s, n_excursions=2_000) for s in (51, 52)]
    pooled = combine_estimates(small)
    assert [w for w in pooled.warnings if "n_excursions = " in w] == [small_n_note(pooled.n_excursions)]
    assert not [w for w in combine_estimates([runs[0], small[0]]).warnings if "n_excursions = " in w]


def test_more_than_2_62_excursions_together_are_refused(runs):
    """Each run within [1, 2^62] excursions, their pool beyond: refused (its count would not be exact).
    The sums are scaled together, so every ratio, and D, stays that of a real run."""
    big = []
    for r in runs[:2]:
        scale = 2.0**61 * 1.5 / r.sums["n"]
        big.append(dataclasses.replace(r, sums={k: v * scale for k, v in r.sums.items()}))
    assert all(b.sums["n"] <= 2**62 for b in big)
    with pytest.raises(ValueError, match=r"^results must hold at most 2\^62 excursions together"):
        combine_estimates(big)


def test_sums_that_give_a_negative_d_are_refused(runs):
    """U2 = 0 passes the field checks (a sum of squares >= 0) but gives D = -0.15 with a finite CI at
    this point (measured): a hand-edited file, refused rather than pooled into a negative D."""
    bad = dataclasses.replace(runs[0], sums={**runs[0].sums, "U2": 0.0})
    with pytest.raises(ValueError, match=r"^results must hold consistent excursion sums: they give D = -"):
        combine_estimates([bad])


def test_the_rounding_note_is_the_pools_and_an_estimate_carries_it(runs, monkeypatch):
    """A D interval that rounding has spoiled (drift per excursion far above its spread:
    ``estimators.rounding_note``) is flagged on the pool, once, for the pool's sums (a run's own note
    is not repeated); real runs at the white-noise point carry no such note.  ``estimate_diffusivity``
    appends the note of its sums to its warnings and warns."""
    import numpy as np

    from dryfric_jax import api
    from dryfric_jax.estimators import rounding_note, sums_from_samples

    rng = np.random.default_rng(0)
    t = rng.gamma(2.0, 1.0, 100_000)
    drifted = sums_from_samples(3e3 * t + np.sqrt(t) * rng.normal(0.0, 1.5, t.size), t, t / 2)
    note = rounding_note(drifted)
    assert note is not None and all(rounding_note(r.sums) is None for r in runs)
    bad = dataclasses.replace(runs[0], sums=drifted, warnings=[note])
    assert [w for w in combine_estimates([bad]).warnings if "not reliable" in w] == [note]
    assert not [w for w in combine_estimates(runs).warnings if "not reliable" in w]
    monkeypatch.setattr(api, "rounding_note", lambda T: "rounding note of N = %d" % T["n"])
    with pytest.warns(dj.DryfricWarning, match="rounding note of N"):
        r = dj.estimate_diffusivity(P, 7, n_excursions=2_000)
    assert f"rounding note of N = {r.n_excursions}" in r.warnings


def test_a_result_writes_strict_json_that_combine_reads_back():
    """to_dict() keeps tau_L = inf a float, which json.dumps wrote as Infinity (refused by strict readers; a user
    audit): to_json() writes "inf", as the CLI does, and combine_estimates reads the parsed dicts back."""
    import json
    p = dj.Params.from_nondim(1e-5, math.inf, 0.2)
    r1, r2 = (dj.estimate_diffusivity(p, s, n_excursions=200, max_steps=10**6) for s in (1, 2))
    text = r1.to_json()
    assert '"tau_L": "inf"' in text and "Infinity" not in text
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict constant {c}"))
    pooled = dj.combine_estimates([json.loads(r1.to_json()), json.loads(r2.to_json())])
    assert pooled.params["tau_L"] == math.inf and pooled.n_excursions == r1.n_excursions + r2.n_excursions
    bf = dj.bruteforce_diffusivity(p, 3, t=1.0 * p.tau0, n_paths=8)
    assert '"tau_L": "inf"' in bf.to_json()


def test_gather_hosts_of_a_key_made_run_gathers_its_own_key():
    """gather_hosts gathers each host's whole result, its key (text) too: a key-made run is pooled under its own key,
    with no "assumed independent" note (before, every host's key was None, pooled with that note; copying this host's
    key to every host's entry would refuse every multi-host pool of key-made runs as one stream used twice)."""
    import jax

    from dryfric_jax.combine import gather_hosts

    r = dj.estimate_diffusivity(P, jax.random.key(3), n_excursions=300)
    with warnings.catch_warnings():
        warnings.simplefilter("error", dj.DryfricWarning)
        g = gather_hosts(r)
    assert g.combined_from == [r.key] and g.D == r.D and g.n_excursions == r.n_excursions


def test_the_pools_max_steps_does_not_depend_on_the_order_of_the_runs(runs):
    """max_steps was the first run's: pooling a run of another bound gave either bound by the order of the runs.
    Now the runs' shared bound, or 0 where they differ (as lanes and block)."""
    other = dataclasses.replace(runs[1], max_steps=runs[0].max_steps + 1)
    assert combine_estimates(runs).max_steps == runs[0].max_steps > 0
    assert combine_estimates([runs[0], other]).max_steps == combine_estimates([other, runs[0]]).max_steps == 0
