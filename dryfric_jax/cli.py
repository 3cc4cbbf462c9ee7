"""Command line: ``dryfric estimate | bruteforce | theory | duration | combine | sweep | figures | bench``.

Exit codes: 0 success; 2 a user mistake (one line on stderr naming the parameter and its valid
range, no traceback, nothing simulated); 3 a result was printed (and written to ``--out``) but
excursions hit the work bound, so it is biased (``--allow-truncated`` accepts it: exit 0);
1 no result possible (fewer than 2 complete excursions within the work bounds or ``--max-time``);
130 Ctrl-C (what the completed rounds reached is printed; nothing if fewer than 2 excursions closed);
143 SIGTERM (``kill``, a batch scheduler's time limit), taken as a Ctrl-C: the same is printed and kept;
141 stdout's reader closed the pipe before the output was written (``dryfric estimate | true``), quietly, as SIGPIPE
would; 1 when stdout cannot be written (a full disk); ``--out`` and the files of ``sweep`` and ``figures`` are written
first, so both keep them.
``sweep`` runs every point it can: 1 if a point ended without a result (or, with ``--durations``, without its
count's mean), else 3 if a point's
excursions were truncated (``--allow-truncated``), else 0; its refused and failed points are
recorded in the results file with their reasons.  ``duration``: 3 when lanes hit ``--max-steps`` (the mean
printed is biased low), 1 when fewer than 2 long excursions were counted within it or ``--max-time`` (as
``estimate``; its :class:`~dryfric_jax.NoCountError` in Python: it was 2, a user mistake's, after simulating).
"""
from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import sys
import threading
import time
import warnings

from . import compile_cache, interrupts
from .api import MAX_FIGURE_SEED
from .bench import MAX_REPEAT
from .durations import MAX_COUNT_LANES, NoCountError
from .durations import MAX_STEPS as DUR_MAX_STEPS
from .estimators import MAX_PATHS, MIN_PATHS, MIN_RELIABLE_PATHS
from .outfiles import _text_lines, check_writable, check_writable_dir, dumps, loads, locked, read_records, write_atomic
from .params import FIG3, Params
from .plan import MAX_BLOCK, MAX_LANES, MAX_STEPS
from .xla_flags import use_all_cpu_cores


class _StoreOnce(argparse._StoreAction):
    """The action of every option that takes a value: given at most once (with argparse's own,
    ``--tau 1 ... --tau 2`` silently ran at the last one)."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault("_options_given", set())
        if self.dest in given:
            raise argparse.ArgumentError(self, f"{option_string} must be given once (it was given again: {values!r})")
        given.add(self.dest)
        setattr(namespace, self.dest, values)


class _Parser(argparse.ArgumentParser):
    """Options are spelled out in full: argparse's abbreviations took ``--gamma 5`` as ``--gamma-bar 5``
    (the bias, where Gamma, ``--Gamma``, was meant) and ran it without a word."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        self.register("action", None, _StoreOnce)  # the default action ("store") of this parser's options

    def error(self, message):  # one line, exit 2 (argparse prints the usage block otherwise)
        if message.startswith("argument ") and ": --" in message:
            message = message.split(": ", 1)[1]  # our converters already name the option
        if message.startswith("unrecognized arguments: "):
            message += _spelling_hint(self, message.split(": ", 1)[1].split())
        raise _UserError(message)


def _spelling_hint(parser: argparse.ArgumentParser, words: list[str]) -> str:
    """For the unknown options among ``words`` (``--gamma``, ``--n-exc``, ``--tau-l``), the options
    they abbreviate or differ from only in case, of every subcommand: "" if none."""
    known = {o for a in _all_actions(parser) for o in a.option_strings if o.startswith("--")}
    said = []
    for w in words:
        name = w.split("=", 1)[0]
        if not name.startswith("--") or name in known:
            continue
        like = sorted(o for o in known if o.lower().startswith(name.lower()))
        if like:
            said.append(f"{name}: did you mean {' or '.join(like)}?")
    return (" (" + "; ".join(said) + "; options are case-sensitive and spelled out in full)") if said else ""


def _all_actions(parser: argparse.ArgumentParser):
    """The parser's actions and those of its subcommands."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return [*parser._actions, *(a for sub in subs for sp in sub.choices.values() for a in sp._actions)]


class _UserError(Exception):
    pass


def _in_float64(name, s, v):
    """``v = float(s)``, refused where the text is a number float64 cannot hold: "1e400" read as inf
    and "1e-400" as 0 (the range checks then said "got inf", "got 0.0", and --tau-L 1e999 ran
    silently as tau_L = inf)."""
    if "_" in s:  # Python reads "5_0" as 50: a typo for 5.0 or 5,0 would run silently
        raise argparse.ArgumentTypeError(f"--{name} must be a number (got {s!r}: '_' is not taken as a digit "
                                         "separator)")
    mantissa = s.strip().lower().split("e")[0]
    if (math.isinf(v) and "inf" not in mantissa) or (v == 0 and any(c in mantissa for c in "123456789")):
        raise argparse.ArgumentTypeError(f"--{name} must be a number within float64's range, 1e-308 to 1e308 in "
                                         f"magnitude (got {s!r})")
    return v


def _number(name):
    def conv(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"--{name} must be a number (got {s!r})") from None
        return _in_float64(name, s, v)
    conv.__name__ = name
    return conv


def _tau_L(s):
    if s.strip().lower() in ("inf", "infinity", "+inf"):
        return math.inf
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--tau-L must be a number > 0 or 'inf' (got {s!r})") from None
    return _in_float64("tau-L", s, v)


def _list_of(conv, name):
    def parse(s):
        items = [x.strip() for x in s.split(",")]
        if not all(items):  # "1,,2" or "1,": a value left out by mistake, not silently dropped
            raise argparse.ArgumentTypeError(f"--{name} must be a comma-separated list of values, none empty "
                                             f"(got {s!r})")
        return [conv(x) for x in items]
    return parse


class _Once(argparse.Action):
    """An option given at most once: a repeated sweep axis (--Gamma 1 --Gamma 2) would silently keep
    only the last list."""

    def __call__(self, parser, namespace, values, option_string=None):
        if getattr(namespace, self.dest) is not None:
            raise argparse.ArgumentError(self, f"{option_string} must be given once, as one comma-separated list")
        setattr(namespace, self.dest, values)


#: a value that starts with '-' but is a number or a list of numbers ("-1e-3", "-inf", "-0.5,0.5"), or
#: "-nan" (refused by the option's own check, which names its range, not as a missing value)
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


def _join_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``--gamma-bar -1e-3`` as ``--gamma-bar=-1e-3``: argparse takes only plain negative decimals
    ("-0.5") for an option's value, and "-1e-3", "-inf", "-nan" or "-0.5,0.5" for an unknown option."""
    takes_value = {opt for a in _all_actions(parser) if a.nargs != 0 for opt in a.option_strings}
    out, i = [], 0
    while i < len(argv):
        if argv[i] in takes_value and i + 1 < len(argv) and _NEGATIVE_VALUE.match(argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def _int_at_least(name, lo, hi=None, hi_text=None):
    rng = f">= {lo}" if hi is None else f"in [{lo}, {hi_text or hi}]"

    def conv(s):
        try:
            v = int(s)
        except ValueError:
            v = None
        # int("5_0") is 50: a typo would run silently
        if v is None or "_" in s or v < lo or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"--{name} must be an integer {rng} (got {s!r})")
        return v
    return conv


_seed = _int_at_least("seed", 0, MAX_FIGURE_SEED, "2^62 - 2^20")


def _count_option(name):
    """An excursion count: in [2, 2^62], the engine's counters are int64."""
    return _int_at_least(name, 2, 2**62, "2^62")


def _model_options() -> argparse.ArgumentParser:
    m = _Parser(add_help=False)
    g = m.add_argument_group("model (defaults: the paper's Fig. 3 point, SI units)")
    g.add_argument("--Gamma", type=_number("Gamma"), help=f"noise strength, m^2 s^-3 ({FIG3['Gamma']})")
    g.add_argument("--Delta", type=_number("Delta"), help=f"dry friction, m s^-2 ({FIG3['Delta']})")
    g.add_argument("--tau", type=_number("tau"), help=f"noise correlation time, s ({FIG3['tau']})")
    g.add_argument("--tau-L", type=_tau_L, help=f"viscous time, s, a number or 'inf' ({FIG3['tau_L']})")
    g.add_argument("--gamma-bar", type=_number("gamma-bar"), help=f"bias force, m s^-2 ({FIG3['gamma_bar']})")
    g.add_argument("--nondim", action="store_true",
                   help="read --tau, --tau-L, --gamma-bar in tau0, u0 units; Gamma and Delta then "
                        "default to 1 and the others to the Fig. 3 point's nondimensional values")
    g.add_argument("--json", action="store_true", help="print one JSON object")
    return m


def _params(a) -> Params:
    pick = lambda given, default: default if given is None else given
    if a.nondim:
        fig = Params(**FIG3).nondim()
        return Params.from_nondim(pick(a.tau, fig.tau), pick(a.tau_L, fig.tau_L), pick(a.gamma_bar, fig.gamma_bar),
                                  Gamma=pick(a.Gamma, 1.0), Delta=pick(a.Delta, 1.0))
    return Params(Gamma=pick(a.Gamma, FIG3["Gamma"]), Delta=pick(a.Delta, FIG3["Delta"]), tau=pick(a.tau, FIG3["tau"]),
                  tau_L=pick(a.tau_L, FIG3["tau_L"]), gamma_bar=pick(a.gamma_bar, FIG3["gamma_bar"]))


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="dryfric", description="Dry friction under colored noise: diffusivity D and mobility M0.",
                epilog="Compiled code is kept between commands in ~/.cache/dryfric_jax/xla (or $XDG_CACHE_HOME/dryfric_jax/xla); "
                       "DRYFRIC_CACHE_DIR=DIR moves it, DRYFRIC_CACHE_DIR=off turns it off.")
    from ._version import __version__

    p.add_argument("--version", action="version", version=f"dryfric_jax {__version__}",
                   help="print the package version and exit")
    sub = p.add_subparsers(dest="cmd", required=True, parser_class=_Parser)
    model = _model_options()
    sim = _Parser(add_help=False)
    sim.add_argument("--method", default="di",
                     help="di (differential inclusion, OU noise; the default), pdmp (exact jump-noise PDMP) or "
                          "auto (the cheaper by the cost model; estimate and sweep only, bruteforce refuses it)")
    sim.add_argument("--h", type=_number("h"), default=None, help="DI step, s (default 0.01*min(tau0, tau_L))")
    sim.add_argument("--delta", type=_number("delta"), default=None,
                     help="PDMP noise grid step, s^-1/2 (default: delta' = delta sqrt(Gamma)/Delta = 0.05, "
                          "and delta sqrt(tau) <= 1/16 for slow noise)")
    sim.add_argument("--seed", type=_seed, default=0, help="random seed, an integer in [0, 2^62 - 2^20] (default 0); "
                                                          "the same seed and settings give the same numbers")
    sim.add_argument("--dtype", default="float64", help="float64 (the default) or float32 (the DI and the PDMP "
                                                        "fall back to float64 where float32 is not safe, README)")
    sim.add_argument("--max-work", type=_number("max-work"), default=None,
                     help="cap on lane-steps (DI) or events (PDMP) of the run; a run predicted to need more is "
                          "refused before it starts (default 1e11)")
    sim.add_argument("--out", default=None, help="also write the JSON result to this file (atomically)")

    e = sub.add_parser("estimate", parents=[model, sim], help="long-excursion estimate of D and M0")
    e.add_argument("--n-excursions", type=_count_option("n-excursions"), default=20_000,
                   help="at least this many excursions (default 20000; the first round when --rtol is given)")
    e.add_argument("--rtol", type=_number("rtol"), default=None,
                   help="run rounds until the 95%% CI half-width of D is <= RTOL*|D|")
    e.add_argument("--max-time", type=_number("max-time"), default=None,
                   help="stop after this many seconds (the excursions in flight are then finished, for at most as "
                        "long again; any still running are counted as truncated: exit 3); checked between the "
                        "engine's calls of 2^26-2^27 lane-steps (a few seconds on 2 CPU cores at Fig. 3's point, "
                        "longer where a step costs more), so it may be passed by up to one call")
    e.add_argument("--lanes", type=_int_at_least("lanes", 1, MAX_LANES, "2^22"), default=None,
                   help="engine lanes (default: a power of two near N/32, 512-4096 on a CPU (fewer when N < 512), "
                        "up to 2^18 on a GPU; 'dryfric bench --lanes ...' measures layouts); the law does not change, "
                        "the random streams do")
    e.add_argument("--block", type=_int_at_least("block", 1, MAX_BLOCK), default=None,
                   help="engine block size K, steps per loop iteration (default 128; 256 for the DI on a GPU)")
    e.add_argument("--max-steps", type=_int_at_least("max-steps", 1, MAX_STEPS, "2^62"), default=None,
                   help="work bound per excursion, steps (events); longer excursions are truncated and reported "
                        "(default: 1e4 of the excursion's time scales, README 'Validity ranges')")
    e.add_argument("--allow-truncated", action="store_true",
                   help="exit 0 even when excursions hit the work bound (the result is biased low; exit 3 otherwise)")
    b = sub.add_parser("bruteforce", parents=[model, sim], help="fixed-horizon (brute force) D^t")
    b.add_argument("--t", type=_number("t"), required=True,
                   help="horizon, s; D_t is biased low by O(1/t) (white noise, tau_L = inf, gamma_bar = 0: "
                        "D (1 - 5.4 tau0/t)), warned about below 100 correlation times "
                        "max(min(tau0/(1 - |gamma_bar'|)^2, tau_L), tau)")
    b.add_argument("--n-paths", type=_int_at_least("n-paths", MIN_PATHS, MAX_PATHS, "2^26"), required=True,
                   help=f"independent paths (>= {MIN_PATHS}; the CI under-covers below {MIN_RELIABLE_PATHS})")
    b.add_argument("--burn-in", type=_number("burn-in"), default=0.0,
                   help="uncounted warm-up, s (20 tau0 removes about half of the horizon bias, the start's)")
    b.add_argument("--max-events", type=_int_at_least("max-events", 1, 2**62, "2^62"), default=None,
                   help="PDMP only: events per path before t (default 10x the expected count + 1000); a path "
                        "that reaches it fails the run, which says so")
    th = sub.add_parser("theory", parents=[model], help="exact white-noise (tau -> 0) D and M0; --tau is not used",
                        description="Exact white-noise (tau -> 0) D and M0 of the model (MODEL_NOTES section 2): "
                                    "--tau is not used ('dryfric estimate' gives the colored-noise values).")
    th.add_argument("--h", type=_number("h"), default=None,
                    help="also the exact white-noise D, M0 and E[V^2] of the DI chain at this step, s (its "
                         "step bias; seconds for small h)")
    du = sub.add_parser("duration", parents=[model],
                        help="the paper's mean long-excursion duration of the DI (Fig. 3's right panel), by counting "
                             "releases", description="The DI's mean long-excursion duration in the paper's sense "
                        "(threshold to threshold; dryfric_jax/durations.py): lanes of the DI chain count the changes "
                        "of direction of their releases, and stop starting new excursions once they have counted "
                        "--n-excursions in all (those in flight are finished, so the long ones are not left out: a "
                        "ratio consistent in N, its bias O(1/N)); the 95% CI is Student's t "
                        "over the excursions.  Crossings of the thresholds by X between two steps are counted too (a "
                        "Brownian-bridge correction), so the bias falls like h, not sqrt(h).  "
                        "'dryfric estimate' prints the mean duration of its regeneration cycles, each one or more of "
                        "these.  On a terminal a status line shows the excursions counted so far, their mean and the "
                        "time left (never under --json).")
    du.add_argument("--h", type=_number("h"), default=None,
                    help="DI step, s (default min(0.01*min(tau0, tau_L), tau/700, the step that moves X by 0.125 "
                         "of the stuck band's half-width, i.e. q = 0.0155): the count's bias falls like h, ~30q%%)")
    du.add_argument("--seed", type=_seed, default=0, help="random seed, an integer in [0, 2^62 - 2^20] (default 0)")
    du.add_argument("--dtype", default="float64",
                    help="float64 (the default) or float32 (float64 where float32 is not safe)")
    du.add_argument("--no-bridge", action="store_true",
                    help="count only the releases the chain makes, without the bridge correction (its bias then falls "
                         "only like sqrt(h))")
    du.add_argument("--n-excursions", type=_int_at_least("n-excursions", 2, 2**40, "2^40"), default=2048,
                    help="long excursions to count (default 2048); those in flight when the lanes' total reaches it "
                         "are finished, so a few more are counted")
    du.add_argument("--max-time", type=_number("max-time"), default=None,
                    help="time limit, s: past it no excursion starts and those in flight finish (the mean stays "
                         "consistent, over fewer); at twice it those still in flight are left out (exit 3); it acts "
                         "between the count's pieces, the least one block of 128 steps of every lane (at 2^21 lanes "
                         "~7 s on 2 CPU cores)")
    du.add_argument("--n-lanes", type=_int_at_least("n-lanes", 1, MAX_COUNT_LANES, "2^21"), default=None,
                    help="lanes (default: the power of 2 nearest n-excursions/3, in [32, 256]); they change the "
                         "random numbers, not the law")
    du.add_argument("--max-steps", type=_int_at_least("max-steps", 1, DUR_MAX_STEPS, "(2^31 - 2) x 128"),
                    default=None,
                    help="bound on the loop's steps (default: planned from the predicted excursion, at least 1e8); "
                         "an excursion in flight there is left out and counted (the mean is then biased low: exit 3)")
    du.add_argument("--max-work", type=_number("max-work"), default=None,
                    help="bound on the lane-steps (default 1e11): a run predicted to need more is refused before it "
                         "starts, and once the lanes have computed it no excursion starts (those in flight finish, "
                         "which can take the run several times past it: a note says so)")
    du.add_argument("--out", default=None, help="also write the JSON result to this file (atomically)")
    du.add_argument("--allow-truncated", action="store_true",
                    help="exit 0 even when lanes hit --max-steps (the mean is biased low; exit 3 otherwise)")
    fg = sub.add_parser("figures", help="reproduce the paper's figures and tables (PNG, PDF, JSON)")
    fg.add_argument("--fig", default="all", help="all, 1 (Figs. 1-2), 3, 4, 5, 6, 7, 8, 9 or table1")
    fg.add_argument("--quick", action="store_true", help="small settings: all figures in minutes on a CPU")
    fg.add_argument("--out", required=True, help="output directory (created if its parent exists); Figs. 3, 8 "
                    "and 9 keep each finished run there (fig3.points.jsonl, ...), so rerunning an interrupted "
                    "command resumes; a figure already written there by this version with the same --seed and "
                    "--quick is not made again")
    fg.add_argument("--allow-truncated", action="store_true",
                    help="exit 0 even if runs of Figs. 3, 8 or 9 had truncated excursions (default: exit 3)")
    fg.add_argument("--redo", action="store_true", help="make every figure again even if it is already in --out "
                    "(the kept runs of Figs. 3, 8 and 9 are still reused)")
    fg.add_argument("--seed", type=_seed, default=0, help="the figures' seed (each run's is derived from it; "
                                                          "default 0): the same seed gives the same numbers")
    sw = sub.add_parser("sweep", help="D and M0 with CIs over a grid of parameters, resumable (JSON Lines file)")
    g = sw.add_argument_group("axes: comma-separated lists (SI units); omitted ones stay at the Fig. 3 point")
    for name, conv in (("Gamma", _number("Gamma")), ("Delta", _number("Delta")), ("tau", _number("tau")),
                       ("tau-L", _tau_L), ("gamma-bar", _number("gamma-bar"))):
        g.add_argument(f"--{name}", type=_list_of(conv, name), default=None, action=_Once,
                       help=f"values of {name}, e.g. 1,2.5,5" + (" (or inf)" if name == "tau-L" else ""))
    sw.add_argument("--out", required=True, help="results file (JSON Lines); an existing one is resumed")
    sw.add_argument("--method", default="di", help="di (the default), pdmp or auto (as for 'estimate')")
    sw.add_argument("--h", type=_number("h"), default=None, help="DI step, s, at every point (default: each point's "
                                                                 "0.01*min(tau0, tau_L))")
    sw.add_argument("--delta", type=_number("delta"), default=None,
                    help="PDMP noise grid step, s^-1/2, at every point (default: each point's, as for 'estimate')")
    sw.add_argument("--dtype", default="float64", help="float64 (the default) or float32 (as for 'estimate')")
    sw.add_argument("--seed", type=_seed, default=0,
                    help="the sweep's seed (default 0); each point's seed is derived from it and the point's "
                         "parameters and settings (recorded; stable when the grid is edited)")
    sw.add_argument("--n-excursions", type=_count_option("n-excursions"), default=20_000,
                    help="excursions per point (default 20000; the first round when --rtol is given)")
    sw.add_argument("--rtol", type=_number("rtol"), default=None,
                    help="run each point until the 95%% CI half-width of D is <= RTOL*|D|")
    sw.add_argument("--max-work", type=_number("max-work"), default=None,
                    help="cap on lane-steps (events) per point; a point predicted to need more is refused before "
                         "any point runs (see --skip-refused; default 1e11)")
    sw.add_argument("--max-time", type=_number("max-time"), default=None,
                    help="time limit of each point, s (as for 'estimate'); a point it stopped is rerun by the same "
                         "command with a larger --max-time (or none), and its record kept until then")
    sw.add_argument("--skip-refused", action="store_true",
                    help="record the points the planner refuses (predicted work over --max-work, no stationary "
                         "state, ...) as 'refused' and run the others; without it such a grid is refused "
                         "(exit 2) and the message counts the refused points and names the first six")
    sw.add_argument("--durations", type=_int_at_least("durations", 2, 2**40, "2^40"), default=None, metavar="N",
                    help="also the paper's mean long-excursion duration (threshold to threshold, Fig. 3's right "
                         "panel) at each point, counted over N long excursions of the DI as 'duration' does, e.g. "
                         "2048; the D stays the one without it, and adding it to a finished sweep runs only the "
                         "counts")
    sw.add_argument("--allow-truncated", action="store_true",
                    help="exit 0 even when points have truncated excursions (their results are biased low; "
                         "exit 3 otherwise)")
    sw.add_argument("--json", action="store_true", help="print a JSON summary")
    cb = sub.add_parser("combine", help="pool the excursions of independent estimate runs (JSON files of "
                                        "'estimate --out' or '--json', different seeds, same model)")
    cb.add_argument("files", nargs="+", help="result files (one JSON object each, or JSON Lines: sweep records)")
    cb.add_argument("--out", default=None, help="also write the pooled JSON result to this file (atomically; it "
                    "replaces only an earlier pooled result)")
    cb.add_argument("--json", action="store_true", help="print the pooled result as one JSON object")
    cb.add_argument("--allow-truncated", action="store_true",
                    help="exit 0 even when runs had excursions that hit the work bound (the pooled result is biased "
                         "low; exit 3 otherwise, as for 'estimate')")
    cb.add_argument("--allow-mixed-versions", action="store_true",
                    help="pool runs of different dryfric_jax versions as the same model (refused otherwise, exit 2: "
                         "a version may change a seed's numbers or fix a result)")
    bn = sub.add_parser("bench", help="throughput: DI engine vs RNG bound vs compiled baseline")
    bn.add_argument("--json", action="store_true", help="print one JSON object")
    bn.add_argument("--n-excursions", type=_count_option("n-excursions"), default=10_000,
                    help="excursions per DI/PDMP run (default 10000); a smaller N also shortens the RNG, chain-floor "
                         "and numba timings")
    bn.add_argument("--repeat", type=_int_at_least("repeat", 1, MAX_REPEAT), default=1,
                    help="rounds, each measuring every number (or timing every layout) once; prints the "
                         "medians of the rounds and their ranges, each ratio taken within its round (default 1, at "
                         f"most {MAX_REPEAT})")
    bn.add_argument("--lanes", type=_list_of(_int_at_least("lanes", 1, MAX_LANES, "2^22"), "lanes"), default=None,
                    help="layout sweep instead of the side-by-side bench: DI lane-steps/s for these lane "
                         "counts (comma-separated; default: the run's own) ...")
    bn.add_argument("--block", type=_list_of(_int_at_least("block", 1, MAX_BLOCK), "block"), default=None,
                    help="... and these block sizes K (default: the run's own, 128 on a CPU); each layout runs "
                         "max(N, 8 lanes) excursions at the Fig. 3 point")
    bn.add_argument("--dtype", choices=("float32", "float64"), default="float32",
                    help="simulation dtype of the layout sweep (default float32)")
    return p


def _progress_line(d):
    """One self-overwriting status line on stderr (terminal only, never under --json): N, D so
    far, the goal, the time so far and the projected time left (``api.time_left``), naming
    ``--max-work`` or ``--max-time`` when that limit is projected to end the run first."""
    from .api import duration_text, left_text, status_line

    D, ci = d["D"], d["D_ci"]
    # before 2 excursions have closed there is no D yet: a dash, not "nan ± nan%" (nor the 0 a run may report
    # then); after, a D of exactly 0 has no relative CI, so its CI is shown as it is (it was shown as the dash)
    if D == 0 and ci == ci and d["n_excursions"] >= 2:
        shown = f"0 ± {ci:.3g}"
    elif D == D and D and ci == ci:
        shown = f"{D:.5g} ± {100 * ci / abs(D):.2f}%"
    else:
        shown = "–"
    goal = f"target {100 * d['rtol']:.2g}%" if d["rtol"] else f"target N = {d['target']}"
    left = left_text(d, options=True)
    print(status_line(f"  N = {d['n_excursions']:>9d}   D = {shown}   ({goal})",
                      f"   {duration_text(d.get('elapsed_s', 0.0))}{left}"), end="", file=sys.stderr, flush=True)


def _duration_line(d):
    """``dryfric duration``'s self-overwriting status line on stderr (terminal only, never under --json): the long
    excursions counted so far of those asked, the mean of those counted so far (a dash before the first), the time
    so far and the projected time left, naming --max-time when it is projected to end the count first; once no
    excursion starts any more, how many are still in flight.  Cleared when the count ends (its summary follows)."""
    from .api import duration_text, in_flight_text, left_text, status_line

    mean = f"{d['mean_s']:.4g} s" if d["mean_s"] == d["mean_s"] else "–"
    tail = in_flight_text(d) if d["stopping"] else left_text(d, options=True)
    # those in flight when the rule stopped the starts finish and count: past the target it says "(N asked)", not
    # "265 of 200"
    k, n = d["n_excursions"], d["target"]
    of = f"of {n}" if k <= n else f"({n} asked)"
    print(status_line(f"  long excursions = {k:>7d} {of}   mean so far = {mean}",
                      f"   {duration_text(d['elapsed_s'])}{tail}"), end="", file=sys.stderr, flush=True)


def _figures_line(d):
    """``dryfric figures``' progress on stderr (``run_figures``' ``progress``): a line per scene once it is written,
    with its time, or found already made; on a terminal also one self-overwriting status line while a scene
    computes, naming the run it is at (Figs. 3, 8, 9: the runs so far, the kind and Gamma, tau) with the run's own
    progress (``api.progress_text``), or the stage it is at (the other scenes), and the scene's time so far."""
    from .api import duration_text, progress_text, status_line

    tty = sys.stderr.isatty()
    tag = f"  {d['scene']} ({d['index']} of {d['total']})"
    if d["stage"] == "done":
        what = ("already made by this version with this --seed and --quick: not made again" if d["kept"]
                else f"written in {duration_text(d['wall_s'])}")
        print(("\r\x1b[K" if tty else "") + f"{tag}: {what}", file=sys.stderr, flush=True)
    elif tty:
        now = "computing"
        if d["stage"] == "run":
            p = d["params"]
            what = d["kind"] + (f" ({d['method']})" if d.get("method") else "")
            now = f"run {d['runs'] + 1}, {what} at Gamma={p['Gamma']:.4g} tau={p['tau']:.4g}"
            now += "" if d["run"] is None else ": " + progress_text(d["run"])
        elif d["stage"] == "step":
            now = d["step"]
        el = f" [{duration_text(d['elapsed_s'])}]" if "elapsed_s" in d else ""  # not at "start" until _Ticking's
        print(status_line(f"{tag}: {now}", el), end="", file=sys.stderr, flush=True)


#: taken by whatever writes a line on stderr while ``dryfric figures``' status line is redrawn from another thread
#: (``_Ticking``), so that a redraw never lands inside a warning's line
_LINE_LOCK = threading.RLock()


class _Ticking:
    """``dryfric figures``' progress callback with the status line kept ticking: ``tick`` redraws the last line with
    the scene's time advanced by the time since it came, so that a long stage (Fig. 4's paths, ~1.5 min each at
    full settings) or a run with no progress of its own (brute force) shows time passing rather than a time frozen
    at its start.  Nothing is redrawn after a scene's "done" line.  ``draw`` (``_figures_line``) and ``tick`` run
    under ``_LINE_LOCK``."""

    def __init__(self, draw, clock=time.monotonic):
        self.draw, self.clock, self.last = draw, clock, None

    def __call__(self, d: dict):
        with _LINE_LOCK:
            self.last = None if d["stage"] == "done" else (d, self.clock())
            self.draw(d)

    def tick(self):
        with _LINE_LOCK:
            if self.last is not None:
                d, t = self.last
                self.draw({**d, "elapsed_s": d.get("elapsed_s", 0.0) + self.clock() - t})


@contextlib.contextmanager
def _ticking(draw, show: bool, period: float = 1.0):
    """``draw`` as a progress callback; where ``show`` (a terminal), wrapped in :class:`_Ticking` with a daemon
    thread calling its ``tick`` every ``period`` seconds until the block ends, however it ends."""
    if not show:
        yield draw
        return
    ticking, stop = _Ticking(draw), threading.Event()

    def loop():
        while not stop.wait(period):
            try:
                ticking.tick()
            except OSError:  # stderr gone or not writable now: the redraws stop, the run goes on
                return

    thread = threading.Thread(target=loop, name="dryfric-status-line", daemon=True)
    thread.start()
    try:
        yield ticking
    finally:
        stop.set()
        thread.join()


#: the keys that mark a file as one result of estimate or combine (D_ci), bruteforce (D_t_ci) or duration
#: (n_requested): the only files besides empty ones that --out replaces
_RESULT_MARKS = ("D_ci", "D_t_ci", "n_requested")
#: a file larger than this is no single result (one is a few kB)
_RESULT_MAX_BYTES = 1 << 24


def _check_out(path, inputs=(), pooled_only=False):
    """Refuse, before anything is simulated, an output path that cannot be written, one of ``inputs`` (combine's
    files: the pooled result replaced a run's sums), or an existing file that holds anything but one earlier result
    of estimate, combine, bruteforce or duration (a sweep's records, a figure's numbers, any other file: an audit
    found them replaced without a word).  With ``pooled_only`` (combine) an earlier result is replaced only if it
    was pooled too: a run's result not among the inputs (a typo, another host's run left out) holds the only copy
    of its excursion sums."""
    if path is None:
        return
    try:
        check_writable(path)
    except ValueError as e:
        raise _UserError("--" + str(e)) from None
    if not os.path.isfile(path):
        return
    for f in inputs:
        try:
            same = os.path.samefile(path, f)
        except OSError:
            same = False
        if same:
            raise _UserError(f"--out must not be one of the files combined (got {path!r}): the pooled result would "
                             "replace that run's excursion sums; give another path")
    size = os.path.getsize(path)
    if size == 0:
        return
    if size <= _RESULT_MAX_BYTES:
        try:
            with open(path, encoding="utf-8-sig") as fh:
                obj = loads(fh.read())
            if isinstance(obj, dict) and any(k in obj for k in _RESULT_MARKS):
                if not pooled_only or obj.get("stopped_by") == "combined":
                    return
                seed = obj.get("seed")
                run = "a run's result" + (f" (seed {seed})" if type(seed) is int else "")
                raise _UserError(f"--out must be a new file, an empty one or one that holds an earlier pooled "
                                 f"result, which it replaces (got {path!r}, which holds {run} not among the files "
                                 "combined, and would be lost); give another path (to pool that run too, list its "
                                 "file among those combined and write the pool elsewhere)")
        except (OSError, ValueError, RecursionError):  # UnicodeDecodeError is a ValueError
            pass
    kinds = "pooled result" if pooled_only else "result of estimate, combine, bruteforce or duration"
    raise _UserError(f"--out must be a new file, an empty one or one that holds an earlier {kinds}, which it "
                     f"replaces (got {path!r}, which holds something else: a sweep's records, a figure's numbers, "
                     "another file); give another path or remove it")


def _write_out(path, obj):
    """Write the result's JSON to ``--out``; a failure (the disk filled up during the run, ...) is
    an error once the result has been printed (:func:`_report`), so nothing computed is lost."""
    if path is not None:
        try:
            write_atomic(path, dumps(obj, indent=1))
        except OSError as e:
            raise RuntimeError(f"could not write --out {path!r} ({e}); the result is printed above") from None


def _read_results(paths):
    """The results in ``paths`` with their labels: a file holds one JSON object (``estimate --out``)
    or one per line (a sweep's records, labelled ``path:line``; they failed with 'Extra data')."""
    out, labels = [], []
    for path in paths:
        try:
            # under the file's lock: a record being appended is not seen half written, and the lines numbered
            # below are those read_records parses (two reads apart, an append between them shifted the labels)
            with locked(path):
                with open(path, encoding="utf-8-sig") as f:  # -sig: a file saved with a byte-order mark
                    text = f.read()
                try:
                    found = [(path, loads(text))]
                except ValueError:  # JSON Lines?
                    numbers = [i for i, x in _text_lines(text.encode() + b"\n", 1, "", path) if x.strip()]
                    if len(numbers) < 2:
                        raise
                    # as a sweep reads its file: a last line a kill cut short is skipped, with a warning (it was
                    # refused, so a file another host was writing could not be combined: an audit); it is the last
                    # line, so the records are the first lines'
                    try:
                        recs = read_records(path, (), "files: cannot read an estimate result from {path!r} line "
                                            "{line} (not a JSON object)")
                    except ValueError as e:
                        raise _UserError(str(e)) from None
                    found = [(f"{path}:{i}", rec) for i, rec in zip(numbers, recs)]
        except (OSError, ValueError) as e:  # ValueError: not JSON, or not UTF-8
            raise _UserError(f"files: cannot read an estimate result from {path!r} ({e})") from None
        for label, r in found:
            if not isinstance(r, dict):
                raise _UserError(f"files: {label!r} holds no estimate result (a JSON object)")
            out.append(r)
            labels.append(label)
    return out, labels


@contextlib.contextmanager
def _warnings_kept_in_result():
    """Silence the library's DryfricWarnings: each is also in ``result.warnings``, which
    :func:`_report` prints as one line.  A ProjectionWarning, said while the run goes on and
    not kept in the result, goes to stderr at once (on its own line under a progress line), and so does a
    FileWarning (a results file's line cut short, skipped: a review found combine dropping one without a word)."""
    from .api import DryfricWarning, FileWarning, ProjectionWarning

    def show(message, category, *args, **kw):
        if issubclass(category, (ProjectionWarning, FileWarning)):
            clear = "\r\x1b[K" if sys.stderr.isatty() else ""  # the progress line's
            print(f"{clear}dryfric: warning: {message}", file=sys.stderr, flush=True)

    with warnings.catch_warnings():
        warnings.simplefilter("always", DryfricWarning)
        warnings.showwarning = show
        yield


@contextlib.contextmanager
def _cleared_after(show: bool):
    """Clear the status line on stderr (where ``show``) when the block ends, however it ends."""
    try:
        yield
    finally:
        if show:
            print("\r\x1b[K", end="", file=sys.stderr, flush=True)


@contextlib.contextmanager
def _warnings_as_lines(progress_line: bool = False):
    """The library's DryfricWarnings as one ``dryfric: warning:`` line each on stderr (``dryfric
    figures``: its scenes keep their runs' notes in their records; what is left is said to the user),
    each on a cleared line where ``progress_line`` (``dryfric duration``'s status line) may be shown."""
    from .api import DryfricWarning

    clear = "\r\x1b[K" if progress_line else ""

    with warnings.catch_warnings():
        warnings.simplefilter("always", DryfricWarning)  # said each time, also on a second call in one process
        shown = warnings.showwarning

        def show(message, category, *args, **kw):
            with _LINE_LOCK:  # not inside a status line redrawn by _Ticking's thread
                if issubclass(category, DryfricWarning):
                    print(f"{clear}dryfric: warning: {message}", file=sys.stderr, flush=True)
                else:
                    shown(message, category, *args, **kw)

        warnings.showwarning = show
        yield


def _report(a, r, text=lambda r: r.summary(), warn: bool = True):
    """A result to ``--out`` (atomically), then its warnings on stderr (``warn``) and its JSON by ``--json`` to stdout
    (otherwise ``text(r)``): each survives the other's failure.  A failed write is an error after the result
    has been printed; a stdout or stderr that cannot be written (its reader gone, ``| true``, or a full disk) leaves
    the file written (it was printed first, and a pipe closed by the reader lost the file: an audit).  stdout gets
    one write, also unbuffered (``PYTHONUNBUFFERED``): ``print`` wrote the text and its newline apart, and ``| head
    -1``, leaving between them, made the second fail (exit 141 in 1-3 of 6 runs: a docs audit).  A first Ctrl-C or
    SIGTERM acts after the result is written and printed (a second at once): one in the write lost the finished
    run, exit 143 with nothing written or printed (an interrupt audit)."""
    with interrupts.held_interrupts(second_acts=True):
        try:
            _write_out(a.out, r.to_dict())
            failed = None
        except RuntimeError as e:
            failed = e
        for w in r.warnings if warn else ():
            print(f"dryfric: warning: {w}", file=sys.stderr)
        sys.stdout.write((dumps(r.to_dict()) if a.json else text(r)) + "\n")
        sys.stdout.flush()
    if failed is not None:
        raise failed


def _work_options(a):
    kw = {}
    if a.max_work is not None:
        kw["max_work"] = a.max_work
    return kw


#: the commands whose completed work a SIGTERM keeps (printed and written, as a Ctrl-C does)
KEEPS_RESULTS = ("estimate", "sweep", "figures", "duration")


def _run(a) -> int:
    from . import api

    if a.cmd == "bench":
        from .bench import format_table, run_bench

        if a.lanes or a.block:
            from .bench import format_layouts, tune_layout
            from .plan import plan_estimate

            plan = plan_estimate(Params(**FIG3), n_excursions=a.n_excursions)
            b = tune_layout(a.lanes or [plan.lanes], a.block or [plan.block], a.dtype, n_excursions=a.n_excursions,
                            repeat=a.repeat)
            print(dumps(b) if a.json else format_layouts(b))
            return 0
        b = run_bench(n_excursions=a.n_excursions, repeat=a.repeat)
        print(dumps(b) if a.json else format_table(b))
        return 0
    if a.cmd == "sweep":
        return _sweep(a)
    if a.cmd == "figures":
        from .figures import SCENES, run_figures

        if a.fig != "all" and a.fig not in SCENES:
            raise _UserError(f"--fig must be one of {['all', *SCENES]} (got {a.fig!r})")
        try:
            check_writable_dir(a.out)
        except ValueError as e:
            raise _UserError("--" + str(e)) from None
        tty = sys.stderr.isatty()
        try:
            # a status line left by a scene that stopped: cleared before the message that follows
            with _cleared_after(tty), _ticking(_figures_line, tty) as said, _warnings_as_lines(progress_line=tty):
                nums = run_figures(a.fig, a.out, quick=a.quick, seed=a.seed, redo=a.redo, progress=said)
        except KeyboardInterrupt:
            print(f"dryfric: interrupted; the figures already written and the finished runs of Figs. 3, 8 and 9 "
                  f"({a.out}/*.points.jsonl) are kept: the same command resumes from them", file=sys.stderr)
            return 130
        except ValueError as e:  # a points file that is not one: the option's name, as for --out's other errors
            if str(e).startswith("out must"):
                raise _UserError("--" + str(e)) from None
            raise
        except OSError as e:  # the directory was checked writable; a file may still fail (a full disk)
            raise RuntimeError(f"could not write a figure into --out {a.out!r} ({e}); the finished runs of Figs. 3, "
                               "8 and 9 are kept in *.points.jsonl there: the same command resumes") from None
        print(f"figures written to {a.out}")
        if "table1" in nums:
            from .figures.touchette import table1_text

            print(table1_text(nums["table1"]))
        # truncated excursions of the scenes' runs, Fig. 3's DI duration lanes stopped by their bound and its missing
        # DI duration points
        what = (("n_truncated", "truncated excursions"),
                ("le_dur_truncated", "DI duration lanes stopped by their bound"),
                ("le_dur_missing", "DI duration points missing"))
        cut = {n: ", ".join(f"{k} {text}" for key, text in what
                            if (k := (v.get("runs", {}) if key == "n_truncated" else v).get(key, 0)))
               for n, v in nums.items()}
        cut = {n: t for n, t in cut.items() if t}
        if cut and not a.allow_truncated:
            print("dryfric: warning: " + "; ".join(f"{n}: {t}" for n, t in cut.items())
                  + ": those points are biased low or missing (see the scene's JSON and *.points.jsonl); exit 3 "
                  "(--allow-truncated accepts them)", file=sys.stderr)
            return 3
        return 0
    if a.cmd == "combine":
        from .combine import combine_estimates

        _check_out(a.out, a.files, pooled_only=True)
        with _warnings_kept_in_result():
            results, labels = _read_results(a.files)
            r = combine_estimates(results, labels=labels, allow_mixed_versions=a.allow_mixed_versions)
        _report(a, r)
        # which runs hold them (an audit: the pool's count alone did not say which file to rerun)
        cut = [lab for res, lab in zip(results, labels)
               if isinstance(res, dict) and ((res.get("result") if isinstance(res.get("result"), dict) else res)
                                             .get("n_truncated") or 0)]
        return _truncation_exit(a, r, f"; they come from {', '.join(cut[:3])}" + (" ..." if len(cut) > 3 else "")
                                if cut else "")
    params = _params(a)
    if a.cmd == "theory":
        return _theory(a, params)
    _check_out(getattr(a, "out", None))
    if a.cmd == "estimate":
        show = not a.json and sys.stderr.isatty()
        # the status line cleared when the run ends, however it ends: the result (its final N and D, which the
        # last line drawn, after an earlier round, did not show), an error or an interrupt's message on a clean line
        with _cleared_after(show), _warnings_kept_in_result():
            r = api.estimate_diffusivity(params, a.seed, method=a.method, h=a.h, delta=a.delta,
                                         n_excursions=a.n_excursions, max_steps=a.max_steps,
                                         dtype=a.dtype, rtol=a.rtol, max_time=a.max_time, lanes=a.lanes,
                                         progress=_progress_line if show else None, **_work_options(a),
                                         **({} if a.block is None else dict(block=a.block)))

        _report(a, r, lambda r: r.summary() + (f"\n{r.method_reason}" if a.method == "auto" else ""))
        if r.stopped_by == "interrupted":
            return 130
        return _truncation_exit(a, r, _truncation_remedy(r))
    if a.cmd == "duration":
        from .durations import di_long_excursion_duration

        show = not a.json and sys.stderr.isatty()
        # said as they come: a run that then fails (max_steps too small) says why; the summary or the error follows
        # on a clean line
        with _cleared_after(show), _warnings_as_lines(show):
            r = di_long_excursion_duration(params, a.seed, h=a.h, n_excursions=a.n_excursions,
                                           n_lanes=a.n_lanes, max_steps=a.max_steps, dtype=a.dtype,
                                           bridge=not a.no_bridge, max_time=a.max_time,
                                           progress=_duration_line if show else None, **_work_options(a))
        _report(a, r, warn=False)  # its warnings were said as they came
        if r.stopped_by == "interrupted":  # a Ctrl-C (SIGTERM): what was counted is above, and in --out
            return 130
        if r.n_truncated and not a.allow_truncated:
            # (stopped by the work bound, those in flight are cut only at twice --max-time)
            spare = "--max-time" if r.stopped_by in ("max_time", "work_bound") else "--max-steps"
            print(f"dryfric: warning: {r.n_truncated} long excursions truncated: the mean above is biased low; exit 3 "
                  f"(--allow-truncated accepts it, a larger {spare} spares it)", file=sys.stderr)
            return 3
        return 0
    if a.cmd == "bruteforce":
        with _warnings_kept_in_result():
            r = api.bruteforce_diffusivity(params, a.seed, t=a.t, n_paths=a.n_paths, method=a.method, h=a.h,
                                           delta=a.delta, burn_in=a.burn_in, dtype=a.dtype, max_events=a.max_events,
                                           **_work_options(a))
        _report(a, r)
        return 0
    raise _UserError(f"unknown command {a.cmd!r}")


def _truncation_remedy(r) -> str:
    """The options that would have spared an estimate its truncated excursions, by the causes its
    notes give: the work bound (``--max-steps``) or the final round's deadline (``--max-time``)."""
    from .api import BOUND_NOTE, CUT_NOTE

    fixes = [fix for note, fix in ((BOUND_NOTE, "--max-steps raises the bound"),
                                   (CUT_NOTE, "a larger --max-time lets the final round finish"))
             if any(note in w for w in r.warnings)]
    return "".join(f", {f}" for f in fixes)


def _truncation_exit(a, r, remedy: str) -> int:
    """3 when excursions hit the work bound (the result printed is biased low) unless
    ``--allow-truncated``; else 0."""
    if r.n_truncated and not a.allow_truncated:
        print(f"dryfric: warning: {r.n_truncated} truncated excursions: the result above is biased low; exit 3 "
              f"(--allow-truncated accepts it{remedy})", file=sys.stderr)
        return 3
    return 0


def _theory(a, params) -> int:
    """``dryfric theory``: the exact white-noise D and M0 (and the DI chain's at ``--h``).  A value
    beyond float64 (D ~ 2 tau_L^2 Gamma underflows at tau_L = 1e-300 s) is refused by name, exit 2,
    but the other is still printed: the whole output was refused for D alone."""
    from . import theory
    from .api import DryfricWarning

    # the command says "white-noise", and its help that --tau is not used: theory's warning about tau is not said
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DryfricWarning)
        out, refused = {}, {}
        for name, f in (("D", theory.exact_D), ("M0", theory.exact_M0)):
            try:
                out[name] = f(params)
            except ValueError as e:
                out[name], refused[name] = None, str(e)
        out.update(params=params.as_dict(), convention="model (Gamma_w = 2 Gamma)")
        if refused:  # print the one that is not (nothing when both are: a runaway bias, a user's mistake)
            kept = [k for k in ("D", "M0") if k not in refused]
            if kept and a.json:
                print(dumps({**out, "refused": refused}))
            elif kept:
                print(f"white-noise {kept[0]:<2} = {out[kept[0]]:.6g} {'m^2/s' if kept[0] == 'D' else 'm/s'}")
            why = "; ".join(dict.fromkeys(refused.values()))  # D and M0 refused for one reason: said once
            skipped = "; the DI chain at --h is not computed" if a.h is not None else ""
            raise _UserError(why + (f" ({kept[0]} printed above{skipped})" if kept else ""))
        if a.h is not None:
            out["mean_v2"] = theory.exact_mean_square_velocity(params)
    continuum = f"white-noise D  = {out['D']:.6g} m^2/s\nwhite-noise M0 = {out['M0']:.6g} m/s"
    if a.h is not None:  # the chain law's own warnings said (an unreliable M0 was printed without a word: an audit)
        from .chain_law import white_chain_law

        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", DryfricWarning)
            try:
                law = white_chain_law(params, a.h)
            except ValueError as e:  # the continuum's D and M0 are still printed (it printed nothing: an audit)
                print(dumps({**out, "refused": {"h": str(e)}}) if a.json else continuum)
                raise _UserError(f"{e} (the white-noise D and M0 are printed above; the DI chain at --h is not "
                                 "computed)") from None
        notes = list(dict.fromkeys(str(w.message) for w in said if issubclass(w.category, DryfricWarning)))
        for w in said:
            if not issubclass(w.category, DryfricWarning):
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        for note in notes:
            print(f"dryfric: warning: {note}", file=sys.stderr)
        out.update(h=a.h, chain_D=law.D, chain_M0=law.M0, chain_mean_v2=law.mean_v2, chain_warnings=notes)
    if a.json:
        print(dumps(out))
    else:
        print(continuum)
        if a.h is not None:
            rel = lambda x, y: f"{100 * (x / y - 1):+.2f}%" if y else "white noise: 0"
            print(f"DI chain at h = {a.h:.4g} s (white noise, exact): D = {law.D:.6g} ({rel(law.D, out['D'])}), "
                  f"M0 = {law.M0:.6g} ({rel(law.M0, out['M0'])}), E[V^2] = {law.mean_v2:.6g} "
                  f"({rel(law.mean_v2, out['mean_v2'])})")
    return 0


def _points(n: int) -> str:
    return f"{n} point" + ("" if n == 1 else "s")


def _sweep(a) -> int:
    from . import sweep

    axes = {k: getattr(a, k) for k in ("Gamma", "Delta", "tau", "tau_L", "gamma_bar") if getattr(a, k) is not None}
    kw = dict(seed=a.seed, method=a.method, h=a.h, delta=a.delta, dtype=a.dtype, n_excursions=a.n_excursions,
              rtol=a.rtol, max_time=a.max_time, skip_refused=a.skip_refused, durations=a.durations,
              **_work_options(a))
    try:
        # a point's ProjectionWarning on stderr at once; a bar left mid-line (a Ctrl-C, an error; within a point)
        # cleared, so the summary or the error is on a clean line
        with _cleared_after(sys.stderr.isatty()), _warnings_kept_in_result():
            points = sweep.grid(**axes)
            out = sweep.run_sweep(points, a.out, progress=sweep.progress_bar_for(points),
                                  point_progress=sweep.point_line_for(points), **kw)
    except ValueError as e:
        if str(e).startswith("out must"):
            raise _UserError("--" + str(e)) from None
        raise
    except OSError as e:  # the file was checked writable before; the disk may fill up later
        raise RuntimeError(f"could not write --out {a.out!r} ({e}); the points finished before are in it, and "
                           "the same command resumes") from None
    if a.json:
        print(dumps(out))
    else:
        extra = "".join(f", {out[k]} {k}" for k in ("refused", "failed", "truncated") if out[k]) + (
            f", {out['time_limited']} stopped by --max-time" if out["time_limited"] else "") + (
            f", {out['no_count']} without a duration count" if out["no_count"] else "")
        twice = f" (and {out['duplicates']} repeated, run once)" if out["duplicates"] else ""
        print(f"{_points(out['computed'])} computed, {out['skipped']} already in {a.out}, {out['total']} in the grid"
              + twice + extra)
    if out["interrupted"]:
        kept = (" and the finished D of the point in progress (not its duration count)" if out["kept_d"] else "")
        print(f"dryfric: interrupted: {_points(out['computed'])}{kept} newly written to {a.out}; run the same command "
              "again to resume", file=sys.stderr)
        return 130
    if out["time_limited"]:
        print(f"dryfric: note: --max-time stopped {_points(out['time_limited'])} (fewer excursions than asked, or "
              "none); the same command with a larger --max-time (or none) reruns them", file=sys.stderr)
    if out["refused"] or out["failed"]:
        print(f"dryfric: note: {_points(out['refused'])} refused and {_points(out['failed'])} failed: no result; "
              f"their reasons are in {a.out} (status, reason)", file=sys.stderr)
    if out["failed"]:
        print(f"dryfric: error: {_points(out['failed'])} ended without an estimate (fewer than 2 complete excursions "
              "within the work bounds); a rerun with the same settings skips them (they would fail again); run those "
              "points with a larger --max-work to retry them (or a larger --max-time, for those it stopped)",
              file=sys.stderr)
        return 1
    if out["no_count"]:
        print(f"dryfric: error: {_points(out['no_count'])} got D but no mean long-excursion duration (fewer than 2 "
              "long excursions ended within the count's loop bound or --max-work, or its planner refused the count); "
              f"their reasons are in {a.out} (durations, reason), and a rerun skips them: 'dryfric duration' at such "
              "a point counts them where the reason allows (a larger --max-steps or --max-work, fewer excursions)",
              file=sys.stderr)
        return 1
    if out["truncated"] and not a.allow_truncated:
        print(f"dryfric: warning: {_points(out['truncated'])} with truncated excursions: their results are biased "
              "low; exit 3 (--allow-truncated accepts them)", file=sys.stderr)
        return 3
    return 0


def main(argv=None) -> int:
    use_all_cpu_cores(vector_width=True)  # one device per core (also at import) and 512-bit vectors
    compile_cache.enable()  # before anything compiles: compiled code kept between commands (DRYFRIC_CACHE_DIR)
    with contextlib.suppress(AttributeError, ValueError):  # a path that is not UTF-8 ('d\xe9.jsonl') printed with
        # an escape: with a strict encoding it made a finished sweep's summary an error, exit 2 (an audit)
        sys.stdout.reconfigure(errors="backslashreplace")
    try:
        interrupts.started()  # from here a Ctrl-C is the KeyboardInterrupt below, not "while starting"
        parser = build_parser()
        a = parser.parse_args(_join_negative_values(parser, list(sys.argv[1:] if argv is None else argv)))
        # SIGTERM (kill, a scheduler's time limit) keeps results as Ctrl-C does, in the commands that have results to
        # keep; elsewhere it keeps its default action: 'timeout 60 dryfric bench' at 2^22 lanes ran on for 10 min,
        # its SIGTERM waiting for a long compiled call to return (an audit), with nothing to keep
        keeps = interrupts.sigterm_as_ctrl_c() if a.cmd in KEEPS_RESULTS else contextlib.nullcontext()
        with keeps:
            rc = _run(a)
        if rc == 130:  # a sweep or figures run stopped by Ctrl-C (its results kept): no timer holds the exit
            interrupts.cancel_timers()
        return interrupts.exit_status(rc)
    except NoCountError as exc:  # a count ran and found fewer than 2: no result possible, as for estimate
        print(f"dryfric: error: {exc}", file=sys.stderr)
        return 1
    except (_UserError, ValueError) as exc:
        print(f"dryfric: error: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:  # e.g. every excursion hit the work bound: no estimate to print
        print(f"dryfric: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:  # with its reason when the API gave one (before 2 excursions closed)
        print("dryfric: " + ("terminated (SIGTERM)" if interrupts.terminated() else "interrupted")
              + (f": {exc}" if str(exc) else ""), file=sys.stderr)
        interrupts.cancel_timers()  # one JAX left running would hold the exit for 60 s (interrupts.cancel_timers)
        return interrupts.exit_status(130)
    except BrokenPipeError:  # the reader of stdout left (`dryfric estimate | head -1`): stop as SIGPIPE would
        _drop_stdout()
        return EXIT_BROKEN_PIPE
    except OSError as exc:  # stdout or stderr not writable (a full disk: `> /dev/full`); files are written first
        _drop_stdout()
        with contextlib.suppress(OSError):
            print(f"dryfric: error: could not write the output ({exc})", file=sys.stderr)
        return 1


#: exit status when stdout's reader closed the pipe: 128 + SIGPIPE, what a shell reports for a program
#: that SIGPIPE ended (files a sweep or ``figures`` had written stay written)
EXIT_BROKEN_PIPE = 141


def _drop_stdout() -> None:
    """Point stdout at the null device, so that the interpreter's flush at exit does not raise the
    broken pipe again (Python's "Exception ignored ... BrokenPipeError" line)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # stdout replaced by an object without a descriptor
        pass


if __name__ == "__main__":
    sys.exit(main())
