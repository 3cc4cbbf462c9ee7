import math

import pytest

from dryfric_jax import FIG3, Params


def test_reference_units_and_nondim_numbers():
    p = Params(**FIG3)
    assert p.tau0 == pytest.approx(5 / 3.84**2, rel=1e-15)
    assert p.u0 == pytest.approx(25 / 3.84**3, rel=1e-15)
    assert p.tau_nd == pytest.approx(0.5 * 3.84**2 / 5, rel=1e-15)  # 1.47456, the paper's 1.47
    assert p.gamma_bar_nd == pytest.approx(0.342 / 3.84, rel=1e-15)
    assert p.D0 == pytest.approx(p.u0**2 / p.tau0, rel=1e-14)
    assert p.v0 == pytest.approx(p.u0 / p.tau0, rel=1e-14)


def test_nondim_round_trip():
    p = Params(Gamma=0.16, Delta=3.84, tau=1e-5, tau_L=0.067, gamma_bar=0.342)
    nd = p.nondim()
    assert (nd.Gamma, nd.Delta) == (1.0, 1.0)
    back = Params.from_nondim(nd.tau, nd.tau_L, nd.gamma_bar, Gamma=p.Gamma, Delta=p.Delta)
    for k, v in p.as_dict().items():
        assert getattr(back, k) == pytest.approx(v, rel=1e-14)


def test_tau_L_inf_is_proper():
    p = Params(1.0, 1.0, 0.1)
    assert p.tau_L == math.inf and p.inv_tau_L == 0.0 and p.nondim().tau_L == math.inf


@pytest.mark.parametrize("field,bad", [
    ("Gamma", 0.0), ("Gamma", -1.0), ("Gamma", math.nan), ("Gamma", math.inf),
    ("Delta", 0.0), ("Delta", math.nan), ("tau", -1e-3), ("tau", math.inf),
    ("tau_L", 0.0), ("tau_L", -1.0), ("tau_L", math.nan), ("gamma_bar", math.nan), ("gamma_bar", math.inf),
])
def test_validation_names_parameter(field, bad):
    kw = dict(Gamma=1.0, Delta=1.0, tau=1.0, tau_L=1.0, gamma_bar=0.0)
    kw[field] = bad
    with pytest.raises(ValueError, match=field):
        Params(**kw)


def test_thresholds():
    p = Params(Gamma=4.0, Delta=2.0, tau=1.0, gamma_bar=0.5)
    xp, xm = p.x_thresholds
    assert xp == pytest.approx((2.0 - 0.5) / 2.0) and xm == pytest.approx((-2.0 - 0.5) / 2.0)
