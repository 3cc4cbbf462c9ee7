r"""The white-noise chain law at its edges (a chain-law audit: at default settings it matched
simulation of the same chain within the CIs and converged at first order in h, as documented; these
are the defects it found, each pinned by a test that failed before the fix).

1. A huge ``width`` raised a raw ``OverflowError`` while the refusal's hint was computed.
2. ``nodes_per_sd`` 69-299 passed the check and could never fit, refused as "the law is too wide".
3. A too-large ``width`` was refused as "the law is too wide", not by name.
4. ``MIN_WIDTH``'s claim (tails beyond 15 widths change D by < 1e-5) held at h' = 0.1 only.
5. M0 was silently wrong at tiny tau_L' (a factor 460 at 1e-30): the solve's round-off.
"""
import math
import re
import warnings

import pytest

import dryfric_jax as dj
from dryfric_jax import chain_law, theory
from dryfric_jax.chain_law import white_chain_law
from dryfric_jax.params import Params


def test_a_grid_too_large_for_any_h_is_refused_naming_width_and_nodes_per_sd():
    """width = 1e300 (an OverflowError before) and 1e6 (blamed on the law) are refused by name."""
    p = Params.from_nondim(1e-6)
    for width in (1e300, 1e6):
        with pytest.raises(ValueError, match=re.escape(f"at width = {width:g} and nodes_per_sd = 8: lower them")):
            white_chain_law(p, 0.1 * p.tau0, width=width)
    with pytest.raises(ValueError, match="the law is too wide$"):  # the defaults: the law itself
        white_chain_law(Params.from_nondim(1e-6, math.inf, 0.99), 0.1 * Params.from_nondim(1e-6).tau0)


def test_nodes_per_sd_stops_where_a_grid_can_still_fit():
    """68 nodes per sd fit at the narrowest grid (15 widths, the largest admissible h); 69 are refused
    by the check, naming the bound (before, up to 299 passed it and failed later as "the law is too wide")."""
    p = Params.from_nondim(1e-6)
    assert chain_law.MAX_NODES_PER_SD == 68
    law = white_chain_law(p, 0.1 * p.tau0, nodes_per_sd=68, width=15.0)
    assert law.n_nodes <= chain_law.MAX_NODES and law.D > 0
    with pytest.raises(ValueError, match=r"^nodes_per_sd must be an integer in \[4, 68\]"):
        white_chain_law(p, 0.1 * p.tau0, nodes_per_sd=69, width=15.0)


def test_the_narrowest_width_costs_about_the_default_grids_error():
    """MIN_WIDTH's comment: 15 widths against 45 change D by up to ~1.5e-4 at gamma_bar' = 0.5, h' = 0.03
    (the audit's worst), and by more than the 1e-5 once claimed; 4 nodes per sd for speed."""
    p = Params.from_nondim(1e-6, math.inf, 0.5)
    h = 0.03 * p.tau0
    d15, d45 = (white_chain_law(p, h, nodes_per_sd=4, width=w).D for w in (15.0, 45.0))
    assert 1e-5 < abs(d15 / d45 - 1) <= 2e-4


def test_a_chain_law_m0_lost_to_round_off_is_warned_about():
    r"""gamma_bar' = 0.5, h = 0.01 tau_L: at tau_L' = 1e-20 (E[V] 5e-11 sds from 0) M0 is 0.7% off the
    continuum's and at 1e-30 a factor 460, against < 1e-4 at 1e-10 (the step bias is ~1e-8 there);
    the first two warn, naming M0, the last does not.  D stays within 1e-3 of the continuum's."""
    for tl, warned in ((1e-10, False), (1e-20, True), (1e-30, True)):
        p = Params.from_nondim(1e-9 * tl, tau_L=tl, gamma_bar=0.5)
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            law = white_chain_law(p, 0.01 * tl * p.tau0)
        got = [str(w.message) for w in rec if "M0 is unreliable" in str(w.message)]
        assert bool(got) == warned, (tl, got)
        assert all(issubclass(w.category, dj.DryfricWarning) for w in rec if "M0" in str(w.message))
        assert abs(law.D / theory.exact_D(p) - 1) < 1e-3
        if not warned:
            assert abs(law.M0 / theory.exact_M0(p) - 1) < 1e-4
