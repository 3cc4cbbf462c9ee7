"""Plumbing audit: the per-point claims (outfiles.claim), their use by the sweep and the figure points,
lane sharding and the XLA flags.  Each test fails on the mutants its docstring names: ones the targeted
tests let through, or caught only after a child's 120 s deadline.  No estimator runs (fakes stand in):
the file took 4 s on 2 shared CPU cores; a wait has a deadline, so a regression fails, never hangs."""
import dataclasses
import os
import threading

import jax.numpy as jnp
import pytest

from dryfric_jax import outfiles, sharding, sweep, xla_flags
from dryfric_jax.outfiles import claim, claims_dir
from test_sweep_mutants import stand_in_result


def _held_now(path, key):
    """Whether a claim of ``key`` made now (without ``wait``) is held, from a thread with a 5 s deadline:
    ``"blocked"`` if the claim waited instead of answering (a claim without LOCK_NB; the thread is left
    waiting, the test fails rather than hangs)."""
    got = []

    def probe():
        with claim(path, key) as c:
            got.append(c.held)

    t = threading.Thread(target=probe, daemon=True)
    t.start()
    t.join(5)
    return got[0] if got else "blocked"


def test_a_claim_excludes_only_its_own_point_of_its_own_file(tmp_path):
    """A held claim makes another claim of the same point and file not held, and leaves every other
    point, and the same point of another file in the directory, free.  Mutants: a claims directory
    shared by every file of the directory; the key's hash cut to one hex digit (16 names, so 40
    points collide); a claim that waits for the holder without ``wait`` (the sweep's first pass then
    blocked on the other's point instead of computing its own first); another point's finish removing
    the whole claims directory (a held point's file with it)."""
    a, b = str(tmp_path / "a.jsonl"), str(tmp_path / "b.jsonl")
    with claim(a, "k") as x:
        assert x.held
        assert _held_now(a, "k") is False
        with claim(b, "k") as other_file:
            assert other_file.held
        for i in range(40):
            with claim(a, f"k{i}") as other_point:
                assert other_point.held
        with claim(a, "done") as done:
            done.finish()  # its file and the directory, if empty, removed: not the held point's file
        assert _held_now(a, "k") is False


def test_an_unfinished_claim_is_released_and_its_file_kept(tmp_path):
    """A claim left without ``finish()`` (a point interrupted in a sweep, which leaves the ``with`` by
    ``break``) releases the lock: the next claim is held.  And it keeps the file, so a process that was
    waiting on it and now holds it still excludes a third one: removing it let the third make a new file
    and compute the point too.  Mutants: the descriptor never closed (the lock kept); the file removed
    whether or not the point finished."""
    p = str(tmp_path / "r.jsonl")
    with claim(p, "k") as c:
        assert c.held
    with claim(p, "k") as again:
        assert again.held
    got, release = threading.Event(), threading.Event()

    def waiter():
        with claim(p, "k", wait=True) as w:
            assert w.held
            got.set()
            release.wait(10)  # a deadline: a regression fails, never hangs

    t = threading.Thread(target=waiter, daemon=True)
    with claim(p, "k") as first:
        assert first.held
        t.start()
        t.join(0.3)  # the waiter blocks on first's lock meanwhile
        assert not got.is_set()
    try:
        assert got.wait(10)
        assert _held_now(p, "k") is False
    finally:
        release.set()
        t.join(10)


def test_a_claims_directory_removed_meanwhile_is_made_again(tmp_path, monkeypatch):
    """Another process may remove the empty claims directory between making it and opening the claim
    file (FileNotFoundError): the file is tried again, so the point is still claimed.  Mutant: that
    race gave an unclaimed point (held, excluding nobody)."""
    p = str(tmp_path / "r.jsonl")
    real, raced = os.open, []

    def racing_open(name, *a, **kw):
        if not raced and os.path.dirname(name) == claims_dir(p):
            raced.append(name)
            os.rmdir(claims_dir(p))
            raise FileNotFoundError(2, "No such file or directory", name)
        return real(name, *a, **kw)

    monkeypatch.setattr(outfiles.os, "open", racing_open)
    with claim(p, "k") as c:
        assert raced and c.held
        with claim(p, "k") as other:
            assert not other.held


def _record(status, **what):
    from dryfric_jax.params import FIG3
    from dryfric_jax.plan import check_settings

    pt = {**FIG3, "Gamma": 5.0}
    settings = check_settings(n_excursions=50)
    rec = sweep._record(0, pt, settings, status, **what)
    return rec, sweep._rec_ident(rec)


_RESULT = stand_in_result()  # at Fig. 3's point, as _record's


@pytest.mark.parametrize("case", ["max_time", "version", "refused", "ok"])
def test_a_record_written_elsewhere_is_taken_only_if_this_sweep_would_not_rerun_it(tmp_path, case):
    """Once it holds a point's claim the sweep reads the file again and takes a record another sweep
    wrote, unless it would rerun that record: one stopped by a max_time smaller than this sweep's,
    one of another package version, a refused one.  Mutants: each of those three conditions dropped
    from ``_finished_elsewhere`` (the point was then counted done, with a short or old result)."""
    out = str(tmp_path / "s.jsonl")
    if case == "refused":
        rec, ident = _record("refused", reason="refused: max_work")
    else:
        stop = "max_time" if case == "max_time" else "n_excursions"
        rec, ident = _record("ok", max_time=2.0, result=dict(_RESULT, stopped_by=stop))
    if case == "version":
        rec["version"] = "0.0.1"
    outfiles.write_records(out, [rec])
    got = sweep._finished_elsewhere(out, ident, 5.0)
    assert got == (rec if case == "ok" else None)
    if case == "max_time":  # no more time than it had: taken
        assert sweep._finished_elsewhere(out, ident, 2.0) == rec


def _points_run(seed):
    """A figure points record of the Fig. 3 point with ``seed`` and a dummy result (what reuse reads)."""
    from dryfric_jax.api import EstimateResult
    from dryfric_jax.figures import points
    from dryfric_jax.params import FIG3, Params

    result = {f.name: 0.0 for f in dataclasses.fields(EstimateResult)
              if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
    return dict(ident=points._ident("estimate", Params(**FIG3), seed, {}), kind="estimate",
                version=points.__version__, result=dict(result, wall_s=0.0))


def _never_computed(monkeypatch):
    """The figure points' estimator replaced by one that fails the test (a run computed again)."""
    from dryfric_jax.api import EstimateResult
    from dryfric_jax.figures import points

    monkeypatch.setitem(points._KINDS, "estimate", (lambda *a, **k: pytest.fail("computed again"), EstimateResult))


def test_points_see_a_rewrite_with_the_same_size_and_mtime(tmp_path, monkeypatch):
    """A points file another process rewrote is read again before a run is computed, even when the
    new file has the old one's size and modification time (coarse time stamps, two writes within one
    tick): every write is a new file, so the inode tells.  Mutant: ``_stamp`` without the inode
    (the run was computed a second time)."""
    from dryfric_jax.figures import points
    from dryfric_jax.params import FIG3, Params

    path = points.points_path(str(tmp_path), "s")
    outfiles.write_records(path, [_points_run(1)])
    pts = points.Points(str(tmp_path), "s")
    st = os.stat(path)
    outfiles.write_records(path, [_points_run(2)])  # one digit changed: the same size
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert os.stat(path).st_size == st.st_size
    _never_computed(monkeypatch)
    pts.estimate(Params(**FIG3), 2)
    assert (pts.reused, pts.computed) == (1, 0)


@pytest.mark.parametrize("when", ["after_its_own_write", "after_the_first_read"])
def test_points_see_a_write_made_right_after_they_read_or_wrote(tmp_path, monkeypatch, when):
    """Another process's run written just after this Points read the file (at creation) or wrote its
    own run, before it noted the file's stamp, is still seen: the run is reused, not computed a second
    time.  Before, the stamp was taken after the read or the write, so it already included the other's
    write, and that run was computed again (a race of two runs of a scene).  Mutant: a computed run's
    claim not finished (its claim file left in the directory)."""
    from dryfric_jax.figures import points
    from dryfric_jax.params import FIG3, Params

    path = points.points_path(str(tmp_path), "s")
    outfiles.write_records(path, [_points_run(1)])
    other = _points_run(2)
    real_read, real_put = points._read, points.put_record

    def the_other_writes():
        real_put(path, other, lambda old: False, real_read)

    if when == "after_the_first_read":
        def read_then_the_other_writes(p):
            recs = real_read(p)
            the_other_writes()
            return recs

        monkeypatch.setattr(points, "_read", read_then_the_other_writes)
        pts = points.Points(str(tmp_path), "s")
        monkeypatch.setattr(points, "_read", real_read)
    else:
        pts = points.Points(str(tmp_path), "s")
        pts._done.pop(_points_run(1)["ident"])  # to be computed here, as if the file had not had it
        monkeypatch.setitem(points._KINDS, "estimate", (lambda p, seed, **kw: _result(seed), points.EstimateResult))
        monkeypatch.setattr(points, "put_record", lambda *a: [real_put(*a), the_other_writes()])
        pts.estimate(Params(**FIG3), 1)
        monkeypatch.setattr(points, "put_record", real_put)
    _never_computed(monkeypatch)
    pts.estimate(Params(**FIG3), 2)
    assert pts.reused == 1
    assert not os.path.exists(claims_dir(path))  # each claim finished: its file and the directory removed


def _result(seed):
    from dryfric_jax.api import EstimateResult

    return EstimateResult(**_points_run(seed)["result"])


def _scaled(x, *, k):
    return x * k


def test_over_lanes_compiles_each_static_value_apart(key):
    """The compile cache is keyed by the static values too: ``k = 3`` then ``k = 4`` gives each its own
    result.  Mutant: a cache keyed without them (the second call ran the first's code)."""
    x = jnp.arange(5.0)
    for k in (3, 4):
        assert jnp.array_equal(sharding.over_lanes(_scaled, (x,), (True,), k=k), x * k)


def test_an_xla_flag_named_without_a_value_is_the_users(monkeypatch):
    """A flag the user's XLA_FLAGS names in any form (a bare boolean ``--xla_gpu_deterministic_ops``)
    is not added again.  Mutants: the check looking for ``--name=`` only; the flag always added."""
    monkeypatch.setenv("XLA_FLAGS", "--xla_gpu_deterministic_ops")
    xla_flags.request_deterministic_gpu_ops()
    assert os.environ["XLA_FLAGS"] == "--xla_gpu_deterministic_ops"


def test_a_ctrl_c_while_waiting_for_another_sweeps_point_stops_the_sweep(tmp_path, monkeypatch):
    """Two points of the grid are claimed elsewhere (here: by this test), so the sweep computes the third
    and then waits for them; a Ctrl-C in that wait ends the sweep (``interrupted``), without waiting for
    the next.  Mutant: the wait's KeyboardInterrupt caught and the loop going on (each Ctrl-C then
    skipped one point, and the sweep said it was not interrupted)."""
    import contextlib
    import types

    from dryfric_jax.params import FIG3
    from dryfric_jax.plan import check_settings

    waits = []

    @contextlib.contextmanager
    def ctrl_c_in_wait(path, key, wait=False):
        if wait:
            waits.append(key)
            raise KeyboardInterrupt
        with claim(path, key) as c:
            yield c

    def fake(p, seed, **kw):
        return types.SimpleNamespace(stopped_by="rtol", to_dict=lambda: dict(stand_in_result(p.as_dict()), params={},
                                                                              seed=seed))

    monkeypatch.setattr(sweep, "claim", ctrl_c_in_wait)
    monkeypatch.setattr(sweep, "estimate_diffusivity", fake)
    out = str(tmp_path / "s.jsonl")
    settings = check_settings(n_excursions=50)
    held = [sweep._ident(0, {**FIG3, "Gamma": g}, settings) for g in (2.0, 4.0)]
    with claim(out, held[0]) as a, claim(out, held[1]) as b:
        assert a.held and b.held
        r = sweep.run_sweep(sweep.grid(Gamma=[2.0, 3.0, 4.0]), out, n_excursions=50)
    assert r["interrupted"] and (r["computed"], r["skipped"]) == (1, 0) and waits == held[:1]


def test_a_claim_where_flock_is_refused_is_held(tmp_path, monkeypatch):
    """On a file system without ``flock`` (some network ones: OSError, not BlockingIOError) the point
    is computed unclaimed, as on Windows.  Mutant: such a claim not held (the sweep then waited for a
    point nobody computes)."""
    if outfiles.fcntl is None:
        pytest.skip("no fcntl (Windows)")

    def no_flock(fd, op):
        raise OSError(37, "No locks available")

    monkeypatch.setattr(outfiles.fcntl, "flock", no_flock)
    with claim(str(tmp_path / "r.jsonl"), "k") as c:
        assert c.held


def _fake_estimate(p, seed, **kw):
    import types

    _fake_estimate.calls.append(p.Gamma)
    return types.SimpleNamespace(stopped_by="rtol", to_dict=lambda: dict(stand_in_result(p.as_dict()), params={},
                                                                          seed=seed))


def test_a_point_claimed_elsewhere_is_computed_after_the_others_once_released(tmp_path, monkeypatch):
    """A point another process holds is left for after the sweep's other points, then waited for; its
    holder released it without a record, so it is computed here.  The hold is released from the progress
    callback once the other point is done; the sweep runs in a thread with a 10 s deadline, so a sweep
    that waits in its first pass fails the test (the thread waits until the hold is released).  Mutants:
    the first pass waiting; the second pass not waiting, or no second pass (the point never computed)."""
    from dryfric_jax.params import FIG3
    from dryfric_jax.plan import check_settings

    _fake_estimate.calls = []
    monkeypatch.setattr(sweep, "estimate_diffusivity", _fake_estimate)
    out = str(tmp_path / "s.jsonl")
    hold = claim(out, sweep._ident(0, {**FIG3, "Gamma": 2.0}, check_settings(n_excursions=50)))
    assert hold.__enter__().held

    def progress(done, total, rec):
        if rec is not None and rec["params"]["Gamma"] == 3.0:
            hold.__exit__(None, None, None)

    got = []
    t = threading.Thread(target=lambda: got.append(sweep.run_sweep(sweep.grid(Gamma=[2.0, 3.0]), out,
                                                                   n_excursions=50, progress=progress)), daemon=True)
    t.start()
    t.join(10)
    if not got:
        hold.__exit__(None, None, None)
    assert got and _fake_estimate.calls == [3.0, 2.0]
    assert (got[0]["computed"], got[0]["skipped"], got[0]["interrupted"]) == (2, 0, False)
    assert sorted(r["params"]["Gamma"] for r in sweep.read_results(out)) == [2.0, 3.0]


def test_a_point_interrupted_in_a_sweep_keeps_its_claim_file_for_the_waiting_one(tmp_path, monkeypatch):
    """A sweep interrupted (Ctrl-C) in a point another process is waiting for releases the claim but keeps
    its file: the waiter now holds the point, so a third claimant is not held.  Mutant: ``finish()`` also
    on interruption (the file removed: the third made a new one and computed the point as well)."""
    from dryfric_jax.params import FIG3
    from dryfric_jax.plan import check_settings

    out = str(tmp_path / "s.jsonl")
    ident = sweep._ident(0, {**FIG3, "Gamma": 2.0}, check_settings(n_excursions=50))
    got, release = threading.Event(), threading.Event()

    def waiter():
        with claim(out, ident, wait=True):
            got.set()
            release.wait(10)

    t = threading.Thread(target=waiter, daemon=True)

    def interrupted(*a, **kw):
        t.start()
        t.join(0.3)  # the waiter blocks on the sweep's claim meanwhile
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep, "estimate_diffusivity", interrupted)
    try:
        assert sweep.run_sweep([dict(Gamma=2.0)], out, n_excursions=50)["interrupted"]
        assert got.wait(10) and _held_now(out, ident) is False
    finally:
        release.set()
        t.join(10)


def test_an_empty_claims_directory_left_behind_is_removed_by_the_next_sweep(tmp_path):
    """A process killed between making the claims directory and its claim file leaves it empty; the next
    sweep of the file removes it at its end, even with nothing to compute.  Mutant: no removal at the
    sweep's end (only each finished claim removed it)."""
    out = str(tmp_path / "s.jsonl")
    os.makedirs(claims_dir(out))
    sweep.run_sweep([], out)
    assert not os.path.exists(claims_dir(out))
