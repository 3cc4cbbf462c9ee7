"""``--out`` never replaces what is not an earlier result of the same kind of command (an audit: a sweep's records
and one of combine's own inputs were overwritten, exit 0).  Checked before anything is simulated: exit 2, one line
naming --out, the file untouched."""
import json

import pytest

import dryfric_jax as dj
from dryfric_jax.cli import main
from dryfric_jax.params import FIG3, Params

SWEEP_LINES = '{"params": {"Gamma": 5.0}, "status": "ok"}\n{"params": {"Gamma": 10.0}, "status": "ok"}\n'


def _fail_if_run(monkeypatch):
    from dryfric_jax import api, durations

    monkeypatch.setattr(api, "estimate_diffusivity", lambda *a, **k: pytest.fail("ran"))
    monkeypatch.setattr(api, "bruteforce_diffusivity", lambda *a, **k: pytest.fail("ran"))
    monkeypatch.setattr(durations, "di_long_excursion_duration", lambda *a, **k: pytest.fail("ran"))


@pytest.mark.parametrize("text", [SWEEP_LINES, '{"edges": [1, 2], "version": "0.2.11"}', "notes\n", "[1, 2]",
                                  b"\xff\xfe\x00", "{" * 100_000])
@pytest.mark.parametrize("cmd", [["estimate"], ["bruteforce", "--t", "1", "--n-paths", "10"], ["duration"]])
def test_a_file_that_holds_no_earlier_result_is_refused_and_kept(tmp_path, monkeypatch, capsys, cmd, text):
    _fail_if_run(monkeypatch)
    out = tmp_path / "x.json"
    (out.write_bytes if isinstance(text, bytes) else out.write_text)(text)
    assert main([*cmd, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dryfric: error: --out must be a new file, an empty one or one that holds an earlier result")
    assert err.count("\n") == 1 and "Traceback" not in err
    assert (out.read_bytes() if isinstance(text, bytes) else out.read_text()) == text


def test_an_earlier_result_or_an_empty_file_is_replaced(tmp_path):
    """The usual case: the same command run again with the same --out (estimate's, combine's, bruteforce's and
    duration's results are recognised by their keys)."""
    p = Params(**FIG3)
    out = tmp_path / "e.json"
    out.write_text("")
    assert main(["estimate", "--n-excursions", "200", "--seed", "1", "--json", "--out", str(out)]) == 0
    first = json.loads(out.read_text())
    assert main(["estimate", "--n-excursions", "200", "--seed", "2", "--json", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["seed"] == 2 != first["seed"]
    d = tmp_path / "d.json"
    d.write_text(dj.di_long_excursion_duration(p, 0, n_excursions=32, n_lanes=32).to_json())
    assert main(["duration", "--n-excursions", "32", "--n-lanes", "32", "--seed", "1", "--json", "--out", str(d)]) == 0
    assert json.loads(d.read_text())["seed"] == 1


def test_combine_refuses_to_write_over_one_of_its_inputs(tmp_path, capsys):
    p = Params(**FIG3)
    files = []
    for s in (0, 1):
        f = tmp_path / f"e{s}.json"
        f.write_text(dj.estimate_diffusivity(p, s, n_excursions=200).to_json())
        files.append(str(f))
    before = [open(f).read() for f in files]
    assert main(["combine", *files, "--out", files[0]]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dryfric: error: --out must not be one of the files combined") and err.count("\n") == 1
    assert [open(f).read() for f in files] == before
    assert main(["combine", *files, "--json", "--out", str(tmp_path / "pooled.json")]) == 0
    assert json.loads((tmp_path / "pooled.json").read_text())["combined_from"] == [0, 1]


def test_combine_replaces_an_earlier_pooled_result_but_not_a_run_left_out(tmp_path, capsys):
    """A run's result not among the files combined (a typo, or another host's run left out of the list) holds the
    only copy of its sums: combine refuses it (it was replaced, exit 0: a stop-92 note).  An earlier pooled result
    is replaced, as is the usual rerun with one more host's file."""
    p = Params(**FIG3)
    files = []
    for s in (0, 1, 2):
        f = tmp_path / f"e{s}.json"
        f.write_text(dj.estimate_diffusivity(p, s, n_excursions=200).to_json())
        files.append(str(f))
    kept = open(files[2]).read()
    assert main(["combine", *files[:2], "--out", files[2]]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dryfric: error: --out must be a new file, an empty one or one that holds an earlier pooled "
                          "result") and "(seed 2) not among the files combined, and would be lost" in err
    assert err.count("\n") == 1 and err.endswith("list its file among those combined and write the pool elsewhere)\n")
    assert open(files[2]).read() == kept
    # as that says: listed, and the pool written elsewhere (listed and written over, it is refused as an input)
    assert main(["combine", *files, "--out", files[2]]) == 2
    assert "--out must not be one of the files combined" in capsys.readouterr().err
    pool = str(tmp_path / "pool.json")
    assert main(["combine", *files[:2], "--json", "--out", pool]) == 0
    assert main(["combine", *files, "--json", "--out", pool]) == 0
    assert json.loads(open(pool).read())["combined_from"] == [0, 1, 2]
    bare = tmp_path / "b.json"
    bare.write_text(json.dumps({"D_t_ci": [1.0, 2.0]}))  # a bruteforce result: a run too, and not poolable
    assert main(["combine", *files, "--out", str(bare)]) == 2
    assert "which holds a run's result not among" in capsys.readouterr().err


def test_a_sweep_file_given_to_estimate_stays_a_sweep_file(tmp_path, monkeypatch):
    """A real sweep file: refused by estimate, then resumed by the sweep with nothing lost."""
    out = tmp_path / "s.jsonl"
    assert main(["sweep", "--Gamma", "5,10", "--n-excursions", "200", "--out", str(out)]) == 0
    text = out.read_text()
    assert main(["estimate", "--n-excursions", "200", "--out", str(out)]) == 2
    assert out.read_text() == text and len(dj.sweep.rows(str(out))) == 2


def test_a_path_that_is_not_utf8_is_printed_escaped(tmp_path, capsys):
    """A results path that is not UTF-8 (a byte 0xe9 from a Latin-1 system: a surrogate escape in Python) is printed
    with a backslash escape; with a strict stdout its summary was an encoding error, exit 2, after the sweep had
    finished (an audit)."""
    out = str(tmp_path / "d\udce9.jsonl")
    assert main(["sweep", "--Gamma", "5", "--n-excursions", "200", "--out", out]) == 0
    said = capsys.readouterr().out
    assert said.endswith("1 point computed, 0 already in " + str(tmp_path) + "/d\\udce9.jsonl, 1 in the grid\n")
    assert len(dj.sweep.rows(out)) == 1
