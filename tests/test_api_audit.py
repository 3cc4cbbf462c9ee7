"""What :func:`estimate_diffusivity` and :func:`bruteforce_diffusivity` make of the engine's output,
with the engine replaced by a fake that returns hand-made sums (no simulation, deterministic).

The estimate, its CI and every count in the result against values derived here; the precision
rule ``more`` and the progress projection against hand arithmetic; each warning's threshold on
both sides.  Units: Gamma = 2, Delta = 3 make D0, v0 and tau0 all different (with the default
Gamma = Delta = 1 they are all 1, and a D0 taken for v0 passed).  Helper mutation audit of the
API's round logic: these cases killed the mutants the engine tests left alive (the round-loop
tests run the real engine and cannot pin an exact number).
"""
import math
import types
import warnings

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import api
from dryfric_jax.estimators import long_excursion_estimates, sums_from_samples
from dryfric_jax.excursions import STAT_NAMES
from dryfric_jax.rounds import ExcursionStats

P = dj.Params.from_nondim(0.3, 0.5, 0.1, Gamma=2.0, Delta=3.0)  # viscous: no weak-damping warning
U5 = np.array([1.0, -2.0, 3.0, 0.5, 2.5])
T5 = np.array([1.0, 2.0, 3.0, 2.0, 0.5])
_rng = np.random.default_rng(11)
T40 = np.round(_rng.exponential(1.0, 40) + 0.1, 3)
U40 = np.round(0.3 * T40 + np.sqrt(T40) * _rng.normal(size=40), 3)  # D's CI is 39% of D, M0's 101% of M0
Z95 = 1.959963984540054  # the two-sided 95% normal quantile, written out


def _stats(U, t, *, truncated=0, useful=600, slot=1000, unfinished=0, in_flight=0):
    """One lane's sums over the excursions (U, t), in the engine's own record."""
    s = sums_from_samples(U, t)
    return ExcursionStats(np.array([[s[k] for k in STAT_NAMES]]), truncated, useful, slot, unfinished, in_flight)


def _by_hand(U, t):
    r"""D, its 95% half-width, M0 and its half-width from the empirical influence values of the
    ratio estimators (the delta method with divisor n is their mean square; test_estimators derives
    them): :math:`\mathrm{IF}^{M_0} = r/\bar t`, :math:`\mathrm{IF}^D = (r^2 - Dt - 2cr)/\bar t`."""
    n, tb = U.size, t.mean()
    m = U.sum() / t.sum()
    r = U - m * t
    D, c = (r**2).mean() / tb, (r * t).mean() / tb
    if_D, if_M = (r**2 - D * t - 2 * c * r) / tb, r / tb
    return D, Z95 * np.sqrt((if_D**2).mean() / n), m, Z95 * np.sqrt((if_M**2).mean() / n)


def _fake_engine(monkeypatch, outcome, calls=None):
    """Replace the engine: ``outcome(kw)`` gives ``(stats, stopped_by)``; the clock reads 1, 2, 3, ..."""
    clock = [0.0]

    def now():
        clock[0] += 1.0
        return clock[0]

    def engine(model, key, n, **kw):
        if calls is not None:
            calls.append(dict(kw, n=n))
        return outcome(kw)

    monkeypatch.setattr(api, "simulate_long_excursions", engine)
    monkeypatch.setattr(api, "time", types.SimpleNamespace(perf_counter=now))


def _run(**kw):
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        r = dj.estimate_diffusivity(P, 7, h=0.02 * P.tau0, **{"n_excursions": 40, **kw})
    return r, [str(w.message) for w in ws if issubclass(w.category, dj.DryfricWarning)]


@pytest.mark.parametrize("stopped", ["n_excursions", "target", "max_time", "work_bound", "interrupted"])
def test_the_result_is_the_engines_sums_in_physical_units(monkeypatch, stopped):
    """D, M0, the mean duration and their CIs in m^2/s, m/s and s; N the complete excursions, N asked
    for kept apart, truncated ones plus those the final round's deadline cut; work, utilisation
    (useful / paid = 0.6) and speed (useful / wall, the fake clock's 1 s); stopped_by as the engine
    said (a "target" relabelled, or the counts swapped, passed every engine test).  The 2 excursions the
    deadline cut are still in flight: they are not "dropped by a second Ctrl-C"."""
    _fake_engine(monkeypatch, lambda kw: (_stats(U5, T5, truncated=3, unfinished=2, in_flight=2), stopped))
    r, ws = _run(max_time=50.0)
    D, D_ci, M, M_ci = _by_hand(U5, T5)
    got = (r.D, r.D_ci, r.M0, r.M0_ci, r.mean_duration, r.mean_duration_ci)
    want = (D * P.D0, D_ci * P.D0, M * P.v0, M_ci * P.v0, T5.mean() * P.tau0,
            Z95 * T5.std() / math.sqrt(5) * P.tau0)
    assert got == pytest.approx(want, rel=1e-12)
    assert (r.n_excursions, r.n_requested, r.n_truncated, r.stopped_by) == (5, 40, 5, stopped)
    assert (r.work, r.lane_utilization, r.lane_steps_per_s, r.wall_s, r.max_time) == (1000, 0.6, 600.0, 1.0, 50.0)
    assert r.warnings == ws and r.sums == pytest.approx(sums_from_samples(U5, T5), rel=1e-15)
    # the deadline cut 2 of the 5 truncated; 3 hit the work bound, of 3 + 2 + 5 excursions in all
    cut = ("cut 20 s after the interrupt (or at 2 x max_time): 2 excursions" if stopped == "interrupted"
           else "cut at 2 x max_time: 2 excursions")  # after a Ctrl-C, either deadline may have cut it
    assert sum(cut in w for w in ws) == 1
    assert sum(w.startswith("3 of 10 excursions hit the work bound") for w in ws) == 1
    assert sum(w.startswith("n_excursions = 5 < 10000") for w in ws) == 1
    assert not any("dropped" in w for w in ws)  # the 2 left in flight are the 2 the deadline cut
    said = {"max_time": "max_time reached (50.0 s) before the 40 excursions: result of 5 excursions",
            "work_bound": "work bound reached (max_work = ", "interrupted": "interrupted: result of the 5"}
    assert [w for w in ws if "result of" in w] == [w for w in ws if stopped in said and w.startswith(said[stopped])]
    assert sum(w.startswith(said.get(stopped, "-")) for w in ws) == (stopped in said)


def test_without_max_time_nothing_is_cut_and_in_flight_drops_are_said(monkeypatch):
    """No time limit: nothing counted as cut, max_time recorded as None (inf too); in-flight excursions
    left (a second Ctrl-C) are said, not taken for a cut nor for the work bound, and counted as truncated
    (they were not: 'dryfric combine' then pooled the run as unbiased, exit 0; a sweep audit)."""
    _fake_engine(monkeypatch, lambda kw: (_stats(U5, T5, truncated=3, in_flight=4), "interrupted"))
    for max_time in (None, math.inf):
        r, ws = _run(max_time=max_time)
        assert (r.n_truncated, r.max_time, r.stopped_by) == (3 + 4, None, "interrupted")
        assert sum(w.startswith("3 of 12 excursions hit the work bound") for w in ws) == 1
        assert sum(w.startswith("4 in-flight excursions dropped (a second interrupt) and counted as truncated")
                   for w in ws) == 1
        assert not any("cut at" in w for w in ws)


@pytest.mark.parametrize("max_time", [None, 50.0])
def test_a_final_round_cut_after_an_interrupt_is_said_as_such(monkeypatch, max_time):
    """A first Ctrl-C gives the final round a grace deadline (rounds.INTERRUPT_GRACE_S); the excursions it
    cut are counted as truncated and said to be cut after the interrupt, not "dropped (a second interrupt)"
    nor "hit the work bound" (both were printed, at Gamma = 1e8 with no max_time: a hard-cases audit)."""
    _fake_engine(monkeypatch, lambda kw: (_stats(U5, T5, truncated=3, unfinished=2, in_flight=2), "interrupted"))
    r, ws = _run(max_time=max_time)
    assert (r.n_truncated, r.stopped_by) == (5, "interrupted")
    said = [w for w in ws if "was cut" in w]
    assert said == ["the final round, which finishes the excursions in flight, was cut 20 s after the interrupt"
                    + (" (or at 2 x max_time)" if max_time else "") + ": 2 excursions still running are excluded "
                    "and counted as truncated: the estimate is biased low"]
    assert sum(w.startswith("3 of 10 excursions hit the work bound") for w in ws) == 1
    assert not any("dropped" in w for w in ws)


@pytest.mark.parametrize("stopped", ["target", "n_excursions"])
def test_a_target_stop_with_weak_damping_says_the_stop_rule_biases_d(monkeypatch, stopped):
    """An audit (2000 + 1000 replicates, white noise, tau_L = inf, b = 0, against the exact chain law): runs that
    the rtol target stopped had D 1.9% (0.9%) low and coverage 0.90 (0.92) at N ~ 8e3 (2e4), against 0.2% and
    0.93-0.94 at fixed N; at the damped calibration point no difference.  The note comes with a target stop and
    weak damping only (P here is viscous: no note)."""
    _fake_engine(monkeypatch, lambda kw: (_stats(U40, T40), stopped))
    weak = dj.Params.from_nondim(0.3, math.inf, 0.1, Gamma=2.0, Delta=3.0)
    for params, said in ((weak, stopped == "target"), (P, False)):
        with warnings.catch_warnings(record=True) as ws:
            warnings.simplefilter("always")
            dj.estimate_diffusivity(params, 7, h=0.02 * params.tau0, n_excursions=40, rtol=0.5)
        assert sum(str(w.message) == dj.api.TARGET_STOP_NOTE for w in ws) == said


@pytest.mark.parametrize("n,warned", [(9_999, True), (10_000, False)])
def test_small_n_warning_is_below_min_reliable_n_only(monkeypatch, n, warned):
    rng = np.random.default_rng(0)
    t = rng.exponential(1.0, n) + 0.1
    _fake_engine(monkeypatch, lambda kw: (_stats(rng.normal(0.2 * t, np.sqrt(t)), t), "n_excursions"))
    r, ws = _run()
    assert any(w.startswith(f"n_excursions = {n} < 10000") for w in ws) is warned and r.warnings == ws


def test_a_sweep_at_small_n_silences_the_small_n_warning_alone(monkeypatch):
    """The small-N note carries each point's N, so Python's once-per-text rule showed it at every point of
    a sweep, and the notebook silenced all DryfricWarnings for it, truncation included (a user audit).  It is
    a SmallSampleWarning (a DryfricWarning); silencing that class keeps the truncation and weak-damping ones."""
    _fake_engine(monkeypatch, lambda kw: (_stats(U5, T5, truncated=3), "n_excursions"))
    p = dj.Params.from_nondim(0.3, math.inf, 0.1, Gamma=2.0, Delta=3.0)
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        r = dj.estimate_diffusivity(p, 7, h=0.02 * p.tau0, n_excursions=40)
    shown = [str(w.message) for w in ws]
    assert any(w.startswith("n_excursions = 5 < 10000") for w in r.warnings)  # in the result, not shown
    assert not any(w.startswith("n_excursions = ") for w in shown)
    assert any("hit the work bound" in w for w in shown) and any("weak or no viscous damping" in w for w in shown)
    assert all(w.category is dj.DryfricWarning for w in ws)
    assert issubclass(dj.SmallSampleWarning, dj.DryfricWarning) and "SmallSampleWarning" in dj.__all__


def test_a_bruteforce_run_with_few_paths_warns_in_the_small_sample_class():
    from dryfric_jax.api import category, small_n_note
    with warnings.catch_warnings(record=True) as ws:  # a real run (the note's own wording decides its class)
        warnings.simplefilter("always")
        dj.bruteforce_diffusivity(P, 1, t=P.tau0, n_paths=8)
    assert [w.category for w in ws if str(w.message).startswith("n_paths = 8 < ")] == [dj.SmallSampleWarning]
    assert category(small_n_note(5)) is dj.SmallSampleWarning
    assert category("n_paths = 10 < 100: the delta-method CI of D_t under-covers at this size") is dj.SmallSampleWarning
    assert category("3 of 10 excursions hit the work bound (max_steps = 4)") is dj.DryfricWarning
    assert category("tau_L/tau0 = 2 > 1 (weak or no viscous damping): the 95% CI for D covers only ~90%") \
        is dj.DryfricWarning


@pytest.mark.parametrize("tau_L,warned", [(1.0, False), (math.nextafter(1.0, 2.0), True), (math.inf, True)])
def test_weak_damping_warning_is_above_tau_l_one_only(monkeypatch, tau_L, warned):
    p = dj.Params.from_nondim(0.3, tau_L, 0.1, Gamma=2.0, Delta=3.0)
    _fake_engine(monkeypatch, lambda kw: (_stats(U5, T5), "n_excursions"))
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        dj.estimate_diffusivity(p, 7, h=0.02 * p.tau0, n_excursions=40)
    assert any("weak or no viscous damping" in str(w.message) for w in ws) is warned


@pytest.mark.parametrize("n,stopped,error", [(1, "max_time", dj.NoEstimateError), (0, "work_bound", dj.NoEstimateError),
                                             (1, "interrupted", KeyboardInterrupt)])
def test_fewer_than_two_excursions_is_no_estimate_and_says_why(monkeypatch, n, stopped, error):
    """One complete excursion is no estimate: NoEstimateError with the engine's stopped_by (a sweep
    reruns only a "max_time" point), or the Ctrl-C going on up; not a ValueError from the estimator."""
    _fake_engine(monkeypatch, lambda kw: (_stats(U5[:n], T5[:n]), stopped))
    with pytest.raises(error) as exc:
        _run()
    if error is dj.NoEstimateError:
        assert exc.value.stopped_by == stopped
        assert ("within max_time" in str(exc.value)) is (stopped == "max_time")


def test_precision_rule_asks_for_the_excursions_its_ci_scaling_predicts(monkeypatch):
    r"""``more`` (the engine asks it for further excursions once N is reached): none once the D
    half-width is at most rtol |D| (equal included: "at most"); else :math:`\lceil N((rel/rtol)^2
    1.1 - 1)\rceil` more, from D's relative half-width (not M0's, which differs here by 2.6x);
    before 2 excursions closed, 2 more than closed so far."""
    D, D_ci, M, M_ci = _by_hand(U40, T40)
    rel = D_ci / D
    assert abs(M_ci / M / rel - 1) > 1
    asked = []

    def outcome(kw):
        more = kw["more"]
        asked.extend([more(_stats(U40[:1], T40[:1])), more(_stats(U40[:0], T40[:0])), more(_stats(U40, T40))])
        return _stats(U40, T40), "target"

    e = long_excursion_estimates(_stats(U40, T40).total())  # the very rel the rule computes: a tie
    for rtol in (e["D_ci"] / e["D"], rel * (1 + 1e-9), rel / 2, rel / 10):
        _fake_engine(monkeypatch, outcome)
        assert _run(rtol=rtol)[0].stopped_by == "target"
    assert asked[0::3] == [3] * 4 and asked[1::3] == [2] * 4
    # ceil(40 (4 x 1.1 - 1)) = ceil(136), ceil(40 (100 x 1.1 - 1)) = ceil(4360): (rel / rtol)^2 rounds, ceil may add 1
    assert asked[2::3][:2] == [0, 0] and asked[8] in (136, 137) and asked[11] in (4360, 4361)


def test_without_rtol_the_engine_gets_no_precision_rule(monkeypatch):
    calls = []
    _fake_engine(monkeypatch, lambda kw: (_stats(U40, T40), "n_excursions"), calls)
    _run(max_time=3.0, max_work=5e9)
    assert calls[0]["more"] is None and calls[0]["max_time"] == 3.0 and calls[0]["max_work"] == 5e9
    assert calls[0]["n"] == 40


def test_progress_projection_and_early_max_work_warning(monkeypatch):
    r"""The reports after each round, on the fake clock (1 s per reading; the time spent in the
    report is not the engine's), and once more after the final round with the final sums and no projection
    (mutant: none, the last line a notebook shows short of the result): round 1 has no projection; round 2
    paid 1e9 more lane-steps in 1 s of engine time; 100 closed + 0 running for 2e9 lane-steps = 2e7 per
    excursion; N = 400 wants 300 more, 6 s, but max_work = 2.5e9 leaves 0.5 s: a ProjectionWarning, said
    once.  With rtol = rel/2 the target wants N (rel/rtol)^2 = 4 x 100 = 400 (D's half-width from 40 excursions'
    sums, all rounds)."""
    rounds = [_stats(U40, T40, slot=1e9), _stats(U40, T40, slot=2e9), _stats(U40, T40, slot=3e9)]
    for st, closed in zip(rounds, (50, 100, 200)):  # closed counts truncated too
        st.n_truncated = closed - 40
    seen = []

    def outcome(kw):
        for st in rounds:
            kw["progress"](st)
        return rounds[-1], "work_bound"

    _fake_engine(monkeypatch, outcome)
    r, ws = _run(n_excursions=400, max_work=2.5e9, progress=seen.append)
    said = [w for w in ws if w.startswith("max_work = 2.5e+09 steps is projected to end the run in ~0 s, short of "
                                          "400 excursions: the rounds so far paid >= 2e+07 steps per excursion")]
    assert len(said) == 1, ws
    assert not any("projected" in w for w in r.warnings)  # said once, not kept in the result
    assert [(d["left_s"], d["left_to"]) for d in seen] == [(None, None), (0.5, "max_work"), (0.0, "max_work"),
                                                           (None, None)]
    assert seen[-1]["D"] == seen[-2]["D"] and seen[-1]["n_excursions"] == r.n_excursions == 40
    D, D_ci, _, _ = _by_hand(U40, T40)
    assert seen[0]["D"] == pytest.approx(D * P.D0, rel=1e-12) and seen[0]["D_ci"] == pytest.approx(D_ci * P.D0)
    assert all(type(d["D"]) is float and type(d["D_ci"]) is float for d in seen)  # D_ci was an np.float64
    assert [d["elapsed_s"] for d in seen] == [1.0, 3.0, 5.0, 8.0]  # the final one after the run's wall is read
    # a precision target: rel / rtol = 2 asks 4 x 100 = 400 excursions, 300 more at 2e7 lane-steps / 1e9 per s
    seen.clear()
    _fake_engine(monkeypatch, outcome)
    _run(n_excursions=400, rtol=D_ci / D / 2, progress=seen.append)
    assert seen[1]["left_to"] == "target" and seen[1]["left_s"] == pytest.approx(300 * 2e7 / 1e9, rel=1e-9)


def test_bruteforce_result_is_the_paths_in_physical_units(monkeypatch):
    """D_t, M0_t and their CIs from the paths' U (hand formulas, test_estimators), the horizon and
    the speed (paths x (t + burn-in) / h steps over the fake clock's 1 s) in physical units."""
    U = np.array([1.0, -2.0, 3.0, 0.5, 2.5, -1.0])
    h = 0.02 * P.tau0
    t_nd = round(0.5 / h) * 0.02

    def fake(model, key, n, n_steps, *, burn_in_steps, block, chunk_lanes):
        assert (n, n_steps, burn_in_steps) == (6, round(0.5 / h), round(0.1 / h))
        return U, t_nd

    monkeypatch.setattr(api, "simulate_bruteforce", fake)
    clock = iter([1.0, 2.0])
    monkeypatch.setattr(api, "time", types.SimpleNamespace(perf_counter=lambda: next(clock)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        r = dj.bruteforce_diffusivity(P, 3, h=h, t=0.5, burn_in=0.1, n_paths=6)
    v = U.var()
    want = (v / t_nd * P.D0, Z95 * np.sqrt((((U - U.mean()) ** 2 - v) ** 2).mean() / 6) / t_nd * P.D0,
            U.mean() / t_nd * P.v0, Z95 * np.sqrt(v / 6) / t_nd * P.v0, t_nd * P.tau0)
    assert (r.D_t, r.D_t_ci, r.M0_t, r.M0_t_ci, r.t) == pytest.approx(want, rel=1e-12)
    # the burn-in recorded and counted is the one simulated, whole steps (it was the one asked for)
    burn = round(0.1 / h) * h
    assert burn != 0.1 and r.burn_in == burn
    assert r.lane_steps_per_s == pytest.approx(6 * (t_nd + burn / P.tau0) / 0.02, rel=1e-12) and r.wall_s == 1.0
    clock = iter([1.0, 2.0])
    monkeypatch.setattr(api, "time", types.SimpleNamespace(perf_counter=lambda: next(clock)))
    with warnings.catch_warnings():  # under h/2: no burn-in step at all, and none recorded
        warnings.simplefilter("ignore", dj.DryfricWarning)
        monkeypatch.setattr(api, "simulate_bruteforce", lambda model, key, n, n_steps, *, burn_in_steps, **kw:
                            (U, t_nd) if burn_in_steps == 0 else pytest.fail("a burn-in step"))
        assert dj.bruteforce_diffusivity(P, 3, h=h, t=0.5, burn_in=0.45 * h, n_paths=6).burn_in == 0.0


def test_bruteforce_says_when_whole_steps_miss_the_horizon(monkeypatch):
    """The DI runs round(t/h) steps: a t that misses a whole number of steps by more than 1% is said
    (t = 1.5 h ran 2 steps, t = 2h, silently; the result's t showed it), within 1% it is not."""
    monkeypatch.setattr(api, "simulate_bruteforce", lambda model, key, n, steps, **kw: (np.arange(3.0), steps * 0.02))
    h = 0.02 * P.tau0
    for t, said in ((1.5 * h, True), (1.4 * h, True), (100.9 * h, False), (101.5 * h, False), (10 * h, False)):
        with warnings.catch_warnings(record=True) as ws:
            warnings.simplefilter("always", dj.DryfricWarning)
            r = dj.bruteforce_diffusivity(P, 3, h=h, t=t, n_paths=3)
        notes = [w for w in r.warnings if "the horizon simulated is" in w]
        assert len(notes) == said and sum("the horizon simulated is" in str(w.message) for w in ws) == said, t
        assert r.t == pytest.approx(round(t / h) * h, rel=1e-12)
        if said:
            assert notes[0].endswith(f"is t = {round(t / h) * h:.4g} s = {round(t / h)} h (the result's t)")


def test_bruteforce_takes_a_horizon_of_one_step(monkeypatch):
    """t = h is one step, allowed; below h it is refused (the message says t >= h)."""
    monkeypatch.setattr(api, "simulate_bruteforce", lambda model, key, n, steps, **kw: (np.arange(3.0), steps * 1.0))
    h = 0.02 * P.tau0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        assert dj.bruteforce_diffusivity(P, 3, h=h, t=h, n_paths=3).n_paths == 3
        with pytest.raises(ValueError, match=r"^t must be >= h"):
            dj.bruteforce_diffusivity(P, 3, h=h, t=h * (1 - 1e-12), n_paths=3)


def test_pdmp_speed_is_the_useful_events_per_second(monkeypatch):
    """The PDMP's events_per_s, like lane_steps_per_s, counts the events that advanced an excursion
    (600), not those paid for idle lanes (1000)."""
    _fake_engine(monkeypatch, lambda kw: (_stats(U5, T5), "n_excursions"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        r = dj.estimate_diffusivity(P, 7, method="pdmp", n_excursions=40)
    assert (r.events_per_s, r.lane_steps_per_s, r.lane_utilization, r.h) == (600.0, 600.0, 0.6, None)


def test_bruteforce_work_limits_at_their_boundaries(monkeypatch):
    """A run of exactly max_work steps is taken (refused only past it: the message says "max_work
    must be >="); a PDMP horizon whose default max_events (10x the expected events per path) passes
    2^62 is refused by name, even where the expected events alone would fit."""
    from dryfric_jax.plan import choose

    h = 0.02 * P.tau0
    monkeypatch.setattr(api, "simulate_bruteforce", lambda model, key, n, n_steps, **kw: (np.arange(n * 1.0), 0.5))
    work = 1000 * (0.5 + 0.1) / P.tau0 * choose(P, "di", h, None, "float64").per_tau0
    with pytest.raises(ValueError, match=r"^max_work must be >= "):
        dj.bruteforce_diffusivity(P, 3, h=h, t=0.5, burn_in=0.1, n_paths=1000, max_work=math.nextafter(work, 0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        assert dj.bruteforce_diffusivity(P, 3, h=h, t=0.5, burn_in=0.1, n_paths=1000, max_work=work).n_paths == 1000
    per_tau0 = choose(P, "pdmp", None, None, "float64").per_tau0
    t = 2.0**62 / 2 / per_tau0 * P.tau0  # 2^61 expected events per path, 10x that is past 2^62
    with pytest.raises(ValueError, match=r"^t must keep t \+ burn_in below 2\^62 events"):
        dj.bruteforce_diffusivity(P, 3, method="pdmp", t=t, n_paths=3, max_work=1e300)


def test_a_run_near_the_runaway_bias_says_how_little_its_d_interval_covers(monkeypatch):
    """|gamma_bar'| >= 0.9 where the damping does not stop the drift (tau_L' (1 - |gamma_bar'|)^2 >= 1, tau_L = inf
    included): measured coverage of the D interval 0.83 at 0.9 Delta down to 0.24 at 0.99 Delta (README), while
    the only warning said "~90%" (an audit saw single runs at 0.99 Delta miss by 3-29 half-widths, all low).
    The warning is graded by this rule, on both sides of each bound, and reaches the result's warnings."""
    from dryfric_jax.estimators import near_runaway_note

    inf = math.inf
    said = [(tl, g) for tl in (inf, 400.0, 99.0, 1e4) for g in (0.899, 0.9, -0.95, 0.99, 0.999999, 1.0, 1.5)
            if near_runaway_note(tl, g)]
    # 1/(1 - 0.9)^2 = 100 (<= 400, > 99); 1/(1 - 0.95)^2 = 400 (<= 400); 1/(1 - 0.99)^2 = 1e4 (<= 1e4)
    assert said == [(inf, 0.9), (inf, -0.95), (inf, 0.99), (inf, 0.999999), (400.0, 0.9), (400.0, -0.95),
                    (1e4, 0.9), (1e4, -0.95), (1e4, 0.99), (1e4, 0.999999)]  # the last: damping-limited, below
    note = near_runaway_note(inf, 0.99)
    assert note.startswith("|gamma_bar|/Delta = 0.99, near the runaway bias") and "0.24 with N = 2e3" in note
    _fake_engine(monkeypatch, lambda kw: (_stats(U40, T40), "n_excursions"))
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        r = dj.estimate_diffusivity(dj.Params.from_nondim(1e-5, inf, -0.95), 7, n_excursions=40)
    assert note.replace("0.99", "0.95", 1) in r.warnings
    assert note.replace("0.99", "0.95", 1) in [str(w.message) for w in ws]
    assert not any("runaway" in w for w in _run()[0].warnings)  # the viscous P


def test_a_run_near_the_runaway_bias_with_damping_that_sets_the_excursions_is_warned_too():
    """DEFECT (a hard-cases audit): at tau_L' = 1e5, gamma_bar = 0.999 Delta (tau_L' (1 - g)^2 = 0.1: the damping,
    not the drift, ends the excursions) 0 of 6 D intervals covered the white-noise D, misses of 4-68 half-widths,
    and 2 of 6 at (5e3, 0.99); only the mild "~90%" note was shown.  Now a second note from tau_L' >= 3e3
    (DAMPED_RUNAWAY_TAU_L; 60 runs each covered 0.90 and 0.88 at (1e3, 0.99) and (200, 0.95), like the mild note
    says).  On both sides of each bound; the drift-limited note is unchanged."""
    from dryfric_jax.estimators import DAMPED_RUNAWAY_TAU_L, near_runaway_note

    assert DAMPED_RUNAWAY_TAU_L == 3e3
    for tl, g, said in ((2999.0, 0.99, False), (3000.0, 0.99, True), (3000.0, -0.99, True), (1e5, 0.999, True),
                        (1e5, 0.899, False), (1e5, 1.0, False), (1e3, 0.99, False)):
        note = near_runaway_note(tl, g)
        assert (note is not None) is said, (tl, g)
        if said:
            assert note.startswith(f"|gamma_bar|/Delta = {abs(g):.4g}, near the runaway bias (|gamma_bar| = Delta), "
                                   f"with damping so weak (tau_L/tau0 = {tl:.3g}) that it sets") and "0 of 6" in note
    assert "with damping so weak" not in near_runaway_note(1e4, 0.99)  # (1 - g)^2 tau_L' = 1: drift-limited


def test_max_time_that_ended_the_rounds_is_no_shortfall_where_n_was_reached(monkeypatch):
    """The final round finishes the lanes' excursions in flight, which can bring N past the count asked after
    max_time ended the rounds: the warning then said "max_time reached (60 s) before the 300 excursions: result of
    428 excursions", and the duration count "stopped the count at 257 of the 200 asked" (a hard-cases audit).
    Replayed here by runs that reach their N, reported as ended by max_time: no shortfall is said, and stopped_by
    still says what ended the rounds."""
    from dryfric_jax import durations

    real_sim, real_count = api.simulate_long_excursions, durations._run
    monkeypatch.setattr(api, "simulate_long_excursions", lambda *a, **k: (real_sim(*a, **k)[0], "max_time"))
    monkeypatch.setattr(durations, "_run", lambda *a, **k: (*real_count(*a, **k)[:-1], "max_time"))
    p = dj.Params.from_nondim(1e-5, 1.0, 0.3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        r = dj.estimate_diffusivity(p, 0, n_excursions=200, max_time=100.0)
        d = dj.di_long_excursion_duration(dj.Params.from_nondim(0.5), 0, n_excursions=20, max_time=100.0)
    assert r.stopped_by == "max_time" and r.n_excursions >= 200 and r.n_truncated == 0
    assert not [w for w in r.warnings if "max_time" in w], r.warnings
    assert d.stopped_by == "max_time" and d.n_excursions >= 20 and d.n_truncated == 0
    assert not [w for w in d.warnings if "max_time" in w], d.warnings


def test_near_the_runaway_bias_messages_tell_the_bias_from_1_and_name_the_drift():
    """A hard-cases audit: at gamma_bar' = 0.999999 a work refusal printed "gamma_bar' = 1" (refused as having no
    stationary state) and blamed "slow weak noise" at tau' = 1e-6, the near-runaway note said |gamma_bar|/Delta =
    1, and a sweep labelled 0.999999 and 1.000001 both gamma_bar=1.  The estimate there was 18 orders of magnitude
    low (D 2.8e6 against 4e24), which the note's coverage figures (measured up to 0.99 Delta) did not suggest."""
    from dryfric_jax import limits, sweep
    from dryfric_jax.estimators import near_runaway_note
    from dryfric_jax.params import brief

    assert [brief(x) for x in (0.999999, 1.000001, -0.99999, 0.5, 0.342, 1.0, math.inf, 1e-6, -0.0890625, 2e-7)] \
        == ["0.999999", "1.000001", "-0.99999", "0.5", "0.342", "1", "inf", "1e-06", "-0.08906", "2e-07"]
    # widened by the fewest digits that show it is not whole (it went to 12: tau' = 1170.28571429); whole floats, as
    # every float past 2^53 is, are never widened
    assert [brief(x) for x in (1170.2857142857, 156.818285714, 7.3728e30)] == ["1170.3", "156.8", "7.373e+30"]
    with pytest.raises(ValueError) as e:
        limits.check_work(1e-6, math.inf, 0.999999, 100.0, 20_000)
    assert "gamma_bar' = 0.999999)" in str(e.value) and "keeps the particle drifting" in str(e.value)
    with pytest.raises(ValueError, match="slow weak noise"):
        limits.check_work(100.0, math.inf, 0.3, 100.0, 20_000)
    note = near_runaway_note(math.inf, 0.999999)
    assert note.startswith("|gamma_bar|/Delta = 0.999999, ") and "low by orders of magnitude" in note
    assert "orders of magnitude" not in near_runaway_note(math.inf, 0.99)
    a, b = (sweep._where(dict(Gamma=1.0, tau=1e-6, gamma_bar=g), ("Gamma", "tau", "gamma_bar")) for g in
            (0.999999, 1.000001))
    assert a != b and "gamma_bar=0.999999" in a
