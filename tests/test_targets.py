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
    # the three completed rounds, none lost, and the in-flight excursions finished (unbiased)
    assert r.n_excursions > calls[-1] > 0
    assert r.D > 0 and r.D_ci > 0 and not any("dropped" in w for w in r.warnings)


@pytest.mark.parametrize("kw,match", [(dict(rtol=0.0), "rtol"), (dict(rtol=1.5), "rtol"),
                                      (dict(max_time=-1), "max_time")])
def test_bad_targets(kw, match):
    with pytest.raises(ValueError, match=match):
        dj.estimate_diffusivity(P, 0, **kw)
