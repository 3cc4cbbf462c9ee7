"""A Ctrl-C or SIGTERM that comes once a run is over never throws its result away (an interrupt audit: a signal in
the ~0.17 s after an estimate's simulation, or in the write of ``--out``, ended ``dryfric estimate`` with exit 143
and nothing printed or written; a count's Ctrl-C before 2 were counted ended with no reason).  The signals are
raised in this thread (``signal.raise_signal``) at the moment named, so they are taken at once."""
import json
import signal
import warnings

import pytest

import dryfric_jax as dj
from dryfric_jax import api, cli, durations, interrupts, rounds

FAST = dj.Params(10.0, 3.84, 0.125, 0.067, 0.342)  # Fig. 3's fastest point


def _ctrl_c_then(f):
    """``f`` with a Ctrl-C raised at its first call."""
    calls = []

    def g(*a, **kw):
        if not calls:
            calls.append(1)
            signal.raise_signal(signal.SIGINT)
        return f(*a, **kw)

    return g


def _kept(call):
    """``call()``, a Ctrl-C that goes on up from it a failure of the test (not the end of the test session)."""
    try:
        return call()
    except KeyboardInterrupt as e:
        pytest.fail(f"the Ctrl-C went on up and the result was lost: {e!r}")


def test_held_interrupts_with_second_acts(capsys):
    """The first signal is held and said, and delivered as the block ends; a second acts at once (SIGTERM's handler
    where either was SIGTERM), and nothing is delivered again as the block ends; without second_acts both are held
    (mutants: the second held too; the first delivered again after the second acted)."""
    seen = []

    def on_int(signum, frame):
        seen.append("int")
        raise KeyboardInterrupt("int")

    def on_term(signum, frame):
        seen.append("term")
        raise KeyboardInterrupt("term")

    before = signal.signal(signal.SIGINT, on_int), signal.signal(signal.SIGTERM, on_term)
    try:
        with pytest.raises(KeyboardInterrupt, match="^int$"):
            with interrupts.held_interrupts(second_acts=True, said=lambda: "held one"):
                signal.raise_signal(signal.SIGINT)
                seen.append("went on")
        assert seen == ["went on", "int"] and capsys.readouterr().err == "held one\n"
        seen.clear()
        with pytest.raises(KeyboardInterrupt, match="^term$"):
            with interrupts.held_interrupts(second_acts=True):
                signal.raise_signal(signal.SIGTERM)
                signal.raise_signal(signal.SIGINT)
                seen.append("not reached")
        assert seen == ["term"]
        assert signal.getsignal(signal.SIGINT) is on_int and signal.getsignal(signal.SIGTERM) is on_term
        seen.clear()
        with pytest.raises(KeyboardInterrupt, match="^term$"):
            with interrupts.held_interrupts():
                signal.raise_signal(signal.SIGINT)
                signal.raise_signal(signal.SIGTERM)
                seen.append("went on")
        assert seen == ["went on", "term"]
    finally:
        signal.signal(signal.SIGINT, before[0])
        signal.signal(signal.SIGTERM, before[1])


def test_interrupt_noted_notes_a_signal_and_passes_the_blocks_own_interrupt():
    with interrupts.interrupt_noted() as late:
        pass
    assert late == []
    with interrupts.interrupt_noted() as late:
        signal.raise_signal(signal.SIGINT)
    assert late == [True]
    with pytest.raises(KeyboardInterrupt, match="^its own$"):
        with interrupts.interrupt_noted():
            raise KeyboardInterrupt("its own")


def test_a_ctrl_c_as_an_estimate_ends_keeps_the_whole_run(monkeypatch):
    """A Ctrl-C while the estimate is formed from the sums (after the simulation): the result of the whole run,
    marked interrupted, with a note; the numbers those of the run without it (mutant: no hold, the
    KeyboardInterrupt goes on up).  Within ``abandon_on_interrupt`` it goes on up, as the engine's."""
    kw = dict(n_excursions=300, lanes=16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        whole = dj.estimate_diffusivity(dj.Params(**dj.FIG3), 3, **kw)
        monkeypatch.setattr(api, "long_excursion_estimates", _ctrl_c_then(api.long_excursion_estimates))
        with pytest.warns(dj.DryfricWarning, match=r"^interrupted as the run ended \(stopped by n_excursions\): the "
                                                   r"result is the whole run's$"):
            r = _kept(lambda: dj.estimate_diffusivity(dj.Params(**dj.FIG3), 3, **kw))
    assert r.stopped_by == "interrupted" and whole.stopped_by == "n_excursions"
    assert (r.D, r.D_ci, r.M0, r.n_excursions, r.sums) == (whole.D, whole.D_ci, whole.M0, whole.n_excursions,
                                                           whole.sums)
    assert r.warnings[-1].startswith("interrupted as the run ended")
    # a caller that keeps finished runs only (a sweep's point, a figure's run: abandon_on_interrupt) gets the Ctrl-C
    monkeypatch.setattr(api, "long_excursion_estimates", _ctrl_c_then(api.long_excursion_estimates))
    with rounds.abandon_on_interrupt(), pytest.raises(KeyboardInterrupt), warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        dj.estimate_diffusivity(dj.Params(**dj.FIG3), 3, **kw)


def test_a_ctrl_c_as_a_count_ends_keeps_the_whole_count(monkeypatch):
    """The same for the long-excursion count (the Ctrl-C in the CI's Student quantile, after the loop)."""
    kw = dict(n_excursions=100, n_lanes=16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        whole = dj.di_long_excursion_duration(FAST, 5, **kw)
        monkeypatch.setattr(durations, "t_quantile", _ctrl_c_then(durations.t_quantile))
        with pytest.warns(dj.DryfricWarning, match=r"^interrupted as the count ended \(stopped by n_excursions\)"):
            r = _kept(lambda: dj.di_long_excursion_duration(FAST, 5, **kw))
    assert r.stopped_by == "interrupted" and (r.mean, r.ci, r.n_excursions) == (whole.mean, whole.ci,
                                                                                 whole.n_excursions)
    assert r.warnings[-1].startswith("interrupted as the count ended")


def test_a_count_interrupted_before_two_were_counted_says_so(monkeypatch):
    """It raised a bare KeyboardInterrupt, and ``dryfric duration`` said only "terminated (SIGTERM)" after promising
    to finish those in flight (an interrupt audit)."""
    import numpy as np

    one = np.ones(4, np.int64)
    monkeypatch.setattr(durations, "_run", lambda *a, **kw: (one * 0, one * 0, one * 0, one == 0, one == 1, one * 9,
                                                             1, "interrupted"))
    with pytest.raises(KeyboardInterrupt, match=r"^fewer than 2 long excursions counted before the interrupt \(0\)$"):
        dj.di_long_excursion_duration(FAST, 5, n_excursions=100, n_lanes=4)


def test_a_ctrl_c_in_the_write_of_out_comes_after_the_result(monkeypatch, tmp_path, capsys):
    """``dryfric estimate --out``: a Ctrl-C during the file's write acts after the result is written and printed
    (exit 130, saying so), where it lost both (an interrupt audit)."""
    from dryfric_jax import outfiles

    out = tmp_path / "r.json"
    monkeypatch.setattr(cli, "write_atomic", _ctrl_c_then(outfiles.write_atomic))
    rc = cli.main(["estimate", "--n-excursions", "200", "--lanes", "16", "--json", "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == 130 and "dryfric: interrupted" in captured.err
    assert json.loads(out.read_text())["D"] == json.loads(captured.out)["D"] > 0


def test_a_ctrl_c_in_the_final_progress_report_keeps_the_run():
    """The report after the final round calls the caller's callback outside the hold (no Ctrl-C broke a slow one: a
    review); a Ctrl-C in it keeps the whole run's result, marked interrupted."""
    kw = dict(n_excursions=300, lanes=16)

    def slow_at_the_end(d):
        if d["left_s"] is None and d["n_excursions"] >= 300:  # the final report
            signal.raise_signal(signal.SIGINT)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        whole = dj.estimate_diffusivity(dj.Params(**dj.FIG3), 3, **kw)
        with pytest.warns(dj.DryfricWarning, match=r"^interrupted as the run ended"):
            r = _kept(lambda: dj.estimate_diffusivity(dj.Params(**dj.FIG3), 3, progress=slow_at_the_end, **kw))
    assert r.stopped_by == "interrupted" and (r.D, r.n_excursions) == (whole.D, whole.n_excursions)
