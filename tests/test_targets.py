"""Precision targets, time limits and Ctrl-C: rounds until the CI is small enough; nothing lost."""
import warnings

import pytest

import dryfric_jax as dj

P = dj.Params.from_nondim(0.3, 0.5, 0.1)  # viscous: a calibrated CI (README)


def _quiet(**kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        return dj.estimate_diffusivity(P, 7, h=0.02 * P.tau0, **kw)


def test_rtol_target_is_reached():
    r = _quiet(n_excursions=500, rtol=0.06)
    assert r.stopped_by == "target" and r.D_ci <= 0.06 * r.D and r.n_excursions > 500


def test_max_time_stops_and_is_reported():
    r = _quiet(n_excursions=500, rtol=1e-4, max_time=1.0)
    assert r.stopped_by == "max_time" and r.D_ci > 1e-4 * r.D
    assert any("max_time" in w for w in r.warnings)


def test_ctrl_c_keeps_completed_rounds():
    calls = []

    def progress(d):
        calls.append(d["n_excursions"])
        if len(calls) == 3:
            raise KeyboardInterrupt

    r = _quiet(n_excursions=500, rtol=1e-4, progress=progress)
    assert r.stopped_by == "interrupted"
    # the three completed rounds, none lost, and the in-flight excursions finished (unbiased); the report after the
    # final round has the result's N
    assert r.n_excursions > calls[2] > 0 and len(calls) == 4 and calls[-1] == r.n_excursions
    assert r.D > 0 and r.D_ci > 0 and not any("dropped" in w for w in r.warnings)


@pytest.mark.parametrize("ctrl_c_at", [1, 2])
def test_one_ctrl_c_in_the_final_round_still_finishes_the_excursions_in_flight(monkeypatch, ctrl_c_at):
    """A single Ctrl-C that comes during a final round (between its calls) is the run's first: the
    in-flight excursions are still finished, giving the same excursions as without it (the round
    runs again from its start); it was taken for a second Ctrl-C, dropping 512 of them and biasing D
    low (audit).  A second Ctrl-C in the rerun drops them, as documented."""
    from dryfric_jax import rounds

    want = _quiet(n_excursions=2000)
    real, seen = rounds.Lanes.finish, []

    def finish(self, *a, **k):
        seen.append(1)
        if len(seen) <= ctrl_c_at:
            raise KeyboardInterrupt
        return real(self, *a, **k)

    monkeypatch.setattr(rounds.Lanes, "finish", finish)
    r = _quiet(n_excursions=2000)
    assert r.stopped_by == "interrupted"
    if ctrl_c_at == 1:
        assert (r.D, r.D_ci, r.M0, r.n_excursions) == (want.D, want.D_ci, want.M0, want.n_excursions)
        assert not any("dropped" in w for w in r.warnings)
    else:
        assert r.n_excursions < want.n_excursions and any("dropped (a second interrupt)" in w for w in r.warnings)
        # the dropped ones are counted as truncated (a pool of this run was exit 0, as if unbiased)
        assert r.n_truncated > 0 and r.n_excursions + r.n_truncated >= 2000


@pytest.mark.parametrize("kw,match", [(dict(rtol=0.0), "rtol"), (dict(rtol=1.5), "rtol"),
                                      (dict(max_time=-1), "max_time")])
def test_bad_targets(kw, match):
    with pytest.raises(ValueError, match=match):
        dj.estimate_diffusivity(P, 0, **kw)


def test_the_projection_is_the_engines_rate_after_the_first_round(monkeypatch):
    """The time left is projected from the engine's rate over the rounds after the first (which
    compiled it), not counting the time spent between rounds (the estimator compiles at its first
    snapshot; a progress callback may be slow): both had made a short run's projection ~8x too
    long.  A fake clock in the API, one second per reading: a callback that takes 100 s more at
    every round leaves every projection exactly as it was; none is made after the first round, nor in the report
    after the final one."""
    import types

    from dryfric_jax import api

    def run(delay):
        clock = [0.0]

        def now():
            clock[0] += 1.0
            return clock[0]

        seen = []

        def progress(d):
            seen.append(d["left_s"])
            clock[0] += delay

        monkeypatch.setattr(api, "time", types.SimpleNamespace(perf_counter=now))
        _quiet(n_excursions=20_000, progress=progress, lanes=64)
        return seen

    fast, slow = run(0.0), run(100.0)
    assert len(fast) >= 5 and fast[0] is None and fast[-1] is None
    assert all(x is not None and x > 0 for x in fast[1:-2])
    assert slow == fast


def test_time_left_projects_to_the_first_limit():
    """The projection behind the progress line: 10 excursions closed after 10 s and 1e6
    lane-steps (1e5 per excursion at 1e5 lane-steps/s); hand-computed values."""
    tl = dj.api.time_left
    assert tl(10.0, 1e6, 0, 0, 100) == (None, None)  # nothing started yet: unknown
    assert tl(10.0, 1e6, 0, 10, 100) == (90.0, "n_excursions")  # 10 running, none closed yet
    assert tl(10.0, 1e6, 10, 0, 100) == (90.0, "n_excursions")  # 90 more excursions, 1 s each
    # in-flight excursions count one each: 8 closed + 2 running -> 1e5 per excursion, 90 left
    assert tl(10.0, 1e6, 8, 2, 100) == (90.0, "n_excursions")
    assert tl(10.0, 1e6, 10, 0, 100, max_work=5e6) == (40.0, "max_work")  # 4e6 lane-steps left
    assert tl(10.0, 1e6, 10, 0, 100, max_work=5e6, max_time=30.0) == (20.0, "max_time")
    assert tl(10.0, 1e6, 10, 0, 100, max_work=2e7, max_time=300.0) == (90.0, "n_excursions")
    # precision target: half-width 2% now, 1% wanted -> N x 4 = 400 excursions, 300 more
    left, to = tl(10.0, 1e6, 100, 0, 50, rtol=0.01, rel=0.02)  # 1e4 lane-steps per excursion
    assert left == pytest.approx(300 * 1e4 / 1e5) and to == "target"
    assert tl(10.0, 1e6, 100, 0, 50, rtol=0.01, rel=None) == (None, None)


def test_progress_reports_the_projection():
    """Every round's report carries the time so far and, once excursions close, the projected
    time left; far below the default max_work, no ProjectionWarning."""
    seen = []
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always", dj.DryfricWarning)
        dj.estimate_diffusivity(P, 7, h=0.02 * P.tau0, n_excursions=500, progress=seen.append)
    assert not any("projected" in str(w.message) for w in ws)  # the default max_work is far away
    assert [d["elapsed_s"] for d in seen] == sorted(d["elapsed_s"] for d in seen)
    known = [d for d in seen if d["left_s"] is not None]
    assert known and all(d["left_s"] >= 0 and d["left_to"] == "n_excursions" for d in known)


def test_progress_line_names_the_limit(capsys):
    from dryfric_jax.cli import _progress_line
    d = dict(n_excursions=120, D=2.0, D_ci=0.1, target=1000, rtol=None, elapsed_s=75.0)
    _progress_line(dict(d, left_s=None, left_to=None))
    _progress_line(dict(d, left_s=600.0, left_to="n_excursions"))
    _progress_line(dict(d, left_s=40.0, left_to="max_work"))
    err = capsys.readouterr().err.split("\r")[1:]
    assert "5.00%" in err[0] and "75 s" in err[0] and "left" not in err[0]
    assert "~10.0 min left" in err[1] and "stops at" not in err[1]
    assert "~40 s left (stops at --max-work)" in err[2]
