r"""Model parameters, reference units and the nondimensional system (paper section 2).

The model (MODEL_NOTES section 1) is

.. math::
    \dot V + \partial\varphi(V) \ni b(V) + \sqrt{\Gamma} X, \qquad
    \varphi(v) = \Delta |v|, \qquad b(v) = -v/\tau_L + \bar\gamma, \qquad
    \tau\, dX = -X\,dt + \sqrt{2}\, dW .

Reference units: :math:`\tau_0 = \Gamma/\Delta^2` (s) and :math:`u_0 = \Gamma^2/\Delta^3` (m).
In these units :math:`\Gamma = \Delta = 1` and the model keeps three numbers,
:math:`\tau' = \tau/\tau_0`, :math:`\tau_L' = \tau_L/\tau_0`, :math:`\bar\gamma' = \bar\gamma/\Delta`.
"""
from __future__ import annotations

import decimal
import math
import sys

import equinox as eqx
import jax
import numpy as np


def shown(x, width: int = 60, head: int = 24) -> str:
    """``repr(x)`` in one readable line: up to ``width`` characters as it is, longer (an int of 400
    digits, a long path) as its first ``head`` characters and its length."""
    text = repr(x)
    return text if len(text) <= width else f"{text[:head]}... ({len(text)} characters)"


def brief(x: float, digits: int = 4) -> str:
    """``x`` to ``digits`` significant digits, or to the fewest more (at most 12) where that rounding would show a
    whole number that ``x`` is not: 0.999999 is not shown as 1, which near the runaway bias is another case (a
    hard-cases audit: a refusal said gamma_bar' = 1 and a sweep labelled 0.999999 and 1.000001 both gamma_bar=1);
    1170.2857 is shown as 1170.3, not to 12 digits."""
    text = f"{x:.{digits}g}"
    while math.isfinite(x) and not float(x).is_integer() and float(text).is_integer() and digits < 12:
        digits += 1
        text = f"{x:.{digits}g}"
    return text


def rounded_bound(x: float, *, lower: bool, digits: int = 4) -> str:
    """A refusal's bound ``x`` to ``digits`` significant digits, rounded *into* the admissible
    range: up for a lower bound, down for an upper one, so that a value a user copies from the
    message, or any value inside the printed range, is accepted (``f"{x:.4g}"`` rounded
    h_max = 0.0123456 up to 0.01235, which the message called admissible and the check refused).
    Non-finite or zero ``x`` is shown as ``.{digits}g`` shows it."""
    x = float(x)
    s = f"{x:.{digits}g}"
    if not math.isfinite(x) or x == 0.0 or (float(s) >= x if lower else float(s) <= x):
        return s
    # one unit of the last digit inward (compared as the floats a user's text becomes)
    d = decimal.Decimal(s)
    step = decimal.Decimal(1).scaleb(decimal.Decimal(x).adjusted() - digits + 1)  # x's last digit, not s's
    return f"{float(d + step if lower else d - step):.{digits}g}"


def _concrete(name: str, x):
    """``x`` as a Python float; None for a tracer (under jit/vmap: validated on the concrete call).
    ``ValueError`` naming ``name`` for anything but a real scalar (a string, None, a bool, a
    complex number, an array with more than one element: loop over a grid instead)."""
    if isinstance(x, jax.core.Tracer):
        return None
    a = None if isinstance(x, (bool, np.bool_, str, bytes)) else np.asarray(x)
    if a is None or a.shape != () or a.dtype.kind not in "iuf":
        if a is not None and a.shape != ():
            fix = ("make one Params per grid point (or run 'dryfric sweep')" if name in _FIELDS
                   else "call once per value")  # t of first_moment: not a Params field
            raise ValueError(f"{name} must be a real number (got an array of shape {a.shape}): {fix}")
        raise ValueError(f"{name} must be a real number (got {shown(x)})")
    return float(a)


#: the model parameters (an array of one of them is a grid: one Params per point)
_FIELDS = ("Gamma", "Delta", "tau", "tau_L", "gamma_bar")


def real_or_none(x) -> float | None:
    """``x`` as a Python float if it is a concrete real scalar (an int, a float, a numpy scalar, a
    0-d array, not a bool), else None: for the settings (h, rtol, max_time, ...), which take numpy
    values as readily as Python ones."""
    if isinstance(x, (bool, np.bool_, str, bytes, jax.core.Tracer)) or x is None:
        return None
    try:
        a = np.asarray(x)
    except Exception:  # noqa: BLE001
        return None
    return float(a) if a.shape == () and a.dtype.kind in "iuf" else None


def plain_number(x):
    """A real scalar (a numpy float32 or float16, an int, a 0-d array) as a Python float; anything
    else unchanged, for a check to refuse by name (a tracer under jit is left alone).  Params
    stores its fields so (a float32 Delta = 1e-10 made D0 = inf), and sweep records their points
    and settings so (JSON)."""
    f = real_or_none(x)
    return x if f is None else f


def _field_number(x):
    """:func:`plain_number` for a Params field, which also takes the texts ``"inf"`` and ``"-inf"``: the results'
    strict JSON (:func:`~dryfric_jax.outfiles.dumps`) writes an infinite tau_L so, and a result's params read
    with ``json.loads`` were refused (an audit)."""
    return float(x) if isinstance(x, str) and x in ("inf", "-inf") else plain_number(x)


def refuse_traced(name: str, value, what: str) -> None:
    """``ValueError`` naming ``name`` if ``value`` is a JAX tracer (under ``jax.jit``, ``vmap`` or ``grad``):
    ``what`` computes on the host, from numbers; a tracer failed deep inside with JAX's ConcretizationTypeError,
    or was refused as out of a range it may lie in (an audit)."""
    if isinstance(value, jax.core.Tracer):
        raise ValueError(f"{name} is a JAX tracer (under jax.jit, vmap or grad): {what} computes on the host from "
                         "numbers and cannot be traced; call it with numbers (in a Python loop over them)")


def check_params(params) -> None:
    """``ValueError`` unless ``params`` is a valid :class:`Params` with concrete values (a dict, say,
    failed later with an AttributeError).

    A Params may hold tracers (its properties work under jit), but the estimators, the planner and the
    exact laws run on the host: under ``jax.jit``/``vmap``/``grad`` they failed deep inside with JAX's
    ConcretizationTypeError.  And ``eqx.tree_at`` or ``tree_map`` build a Params without its checks:
    Gamma = -1 got through and was refused later as "tau_L must be >= 1e-60 tau0 = -6.78e-62 s" (both from a
    user audit), so the values are checked again here, by name."""
    if not isinstance(params, Params):
        raise ValueError(f"params must be a dryfric_jax.Params (got {type(params).__name__}): e.g. "
                         "Params(Gamma=5.0, Delta=3.84, tau=0.5, tau_L=0.067, gamma_bar=0.342), or Params(**d) "
                         "for a dict d")
    traced = [k for k in _FIELDS if isinstance(getattr(params, k), jax.core.Tracer)]
    if traced:
        raise ValueError(f"params.{traced[0]} is a JAX tracer (under jax.jit, vmap or grad): the estimators run on "
                         "the host, round after round, and cannot be traced; call them in a Python loop over the "
                         "parameters (a new Gamma, Delta, tau, tau_L or gamma_bar reuses the compiled code)")
    Params(*(getattr(params, k) for k in _FIELDS))  # __check_init__ again: ValueError naming the field


def check_positive(name: str, value, *, allow_inf: bool = False) -> None:
    """Raise ``ValueError`` naming ``name`` unless ``value`` is a number > 0 (finite unless allowed)."""
    v = _concrete(name, value)
    if v is None:
        return
    ok = v > 0 and (math.isfinite(v) or (allow_inf and v == math.inf))
    if not ok:
        rng = "> 0 or inf" if allow_inf else "finite and > 0"
        raise ValueError(f"{name} must be {rng} (got {value!r})")


def check_flag(name: str, value) -> bool:
    """``value`` as a bool, or ``ValueError`` naming ``name`` unless it is True or False (a numpy bool too): a
    string such as ``'no'`` is truthy and was taken for True (an audit)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False (got {shown(value)})")
    return bool(value)


def check_finite(name: str, value) -> None:
    v = _concrete(name, value)
    if v is not None and not math.isfinite(v):
        raise ValueError(f"{name} must be a finite number (got {value!r})")


#: the reference units and the nondimensional numbers must lie in this range (_check_scales)
SCALE_RANGE = (1e-300, 1e300)


def _tau0(Gamma, Delta):
    r""":math:`\tau_0 = \Gamma/\Delta^2`; as :math:`(\Gamma/\Delta)/\Delta` where :math:`\Delta^2` itself leaves
    float64's normal range although :math:`\tau_0` need not (:math:`\Gamma = 10^{300}, \Delta = 10^{155}`:
    :math:`\tau_0 = 10^{-10}`, was computed as 0 and those parameters refused as "tau0 ... got 0").
    ``Delta * Delta``, not ``Delta**2``: a float's ** raises on overflow.  A tracer (under jit) as is."""
    d2 = Delta * Delta
    if isinstance(d2, float) and not sys.float_info.min <= d2 <= sys.float_info.max:
        return Gamma / Delta / Delta
    return Gamma / d2


def _beyond(x: float, lo: float, hi: float) -> str:
    """``x`` (outside [lo, hi]) to 3 digits, or in full where 3 digits would show it on a bound
    (1.0000000000000002e300 is not "1e+300")."""
    s = f"{x:.3g}"
    return repr(x) if float(s) in (lo, hi) else s


def _check_scales(p: "Params") -> None:
    r"""``ValueError`` unless the reference units :math:`\tau_0, u_0, v_0, D_0` and the numbers
    :math:`\tau', \tau_L'` (unless infinite) lie in :data:`SCALE_RANGE` and
    :math:`|\bar\gamma'|` below its top: D and M0 are reported as D' D0 and M0' v0, so a unit
    that overflows (or underflows to 0) would turn a finite estimate into inf (or 0).  Only for
    concrete values."""
    v = {k: _concrete(k, getattr(p, k)) for k in ("Gamma", "Delta", "tau", "tau_L", "gamma_bar")}
    if None in v.values():
        return
    lo, hi = SCALE_RANGE
    div = lambda a, b: a / b if b != 0.0 else math.inf
    tau0, v0 = _tau0(v["Gamma"], v["Delta"]), v["Gamma"] / v["Delta"]  # as the properties do
    checks = [("Gamma and Delta", "tau0 = Gamma/Delta^2", tau0), ("Gamma and Delta", "v0 = Gamma/Delta", v0),
              ("Gamma and Delta", "u0 = Gamma^2/Delta^3", tau0 * v0),
              ("Gamma and Delta", "D0 = Gamma^3/Delta^4", tau0 * v0 * v0),
              ("tau", "tau' = tau/tau0", div(v["tau"], tau0))]
    if math.isfinite(v["tau_L"]):
        checks.append(("tau_L", "tau_L' = tau_L/tau0", div(v["tau_L"], tau0)))
    for names, what, x in checks:
        if not lo <= x <= hi:
            raise ValueError(
                f"{names} must keep {what} in [{lo:g}, {hi:g}] (got {_beyond(x, lo, hi)} from Gamma = {v['Gamma']!r}, "
                f"Delta = {v['Delta']!r}, tau = {v['tau']!r}, tau_L = {v['tau_L']!r}): out of floating-point "
                "range, express the parameters in other units")
    if not abs(v["gamma_bar"] / v["Delta"]) <= hi:
        raise ValueError(f"gamma_bar must keep |gamma_bar/Delta| <= {hi:g} (got gamma_bar = {v['gamma_bar']!r}, "
                         f"Delta = {v['Delta']!r})")


def require_x64() -> None:
    """``RuntimeError`` unless JAX's 64-bit mode is on.  Importing dryfric_jax turns it on (the sums are
    float64 whatever the simulation dtype); a notebook that turned it off afterwards got five "float64
    truncated to float32" warnings and an OverflowError from inside JAX (a user audit).  Every runner calls it
    (:func:`~dryfric_jax.api._key`, the model builders, :func:`~dryfric_jax.combine_estimates`): the long-excursion
    count, a model and a pool ran silently in float32 (the count with int32 counters) and said float64 (a later
    audit)."""
    if not jax.config.jax_enable_x64:
        raise RuntimeError("dryfric_jax needs JAX's 64-bit mode (its sums are float64 in every dtype; importing it "
                           "turned the mode on and something turned it off): jax.config.update('jax_enable_x64', "
                           "True) restores it, and dtype='float32' still simulates in float32")


class Params(eqx.Module):
    r"""Physical parameters of the dry-friction model, SI units.

    Args:
        Gamma: noise strength :math:`\Gamma` (m^2 s^-3), finite and > 0.
        Delta: dry-friction level :math:`\Delta` (m s^-2), finite and > 0.
        tau: noise correlation time :math:`\tau` (s), finite and > 0.
        tau_L: viscous relaxation time :math:`\tau_L` (s), > 0 or ``inf`` (no viscous term; also the text
            ``"inf"``, as a result's JSON holds it).
        gamma_bar: constant bias force :math:`\bar\gamma` (m s^-2), finite.

    The drift is :math:`b(v) = -v/\tau_L + \bar\gamma`; ``tau_L = inf`` is a proper case.
    """

    Gamma: float = eqx.field(converter=_field_number)
    Delta: float = eqx.field(converter=_field_number)
    tau: float = eqx.field(converter=_field_number)
    tau_L: float = eqx.field(default=math.inf, converter=_field_number)
    gamma_bar: float = eqx.field(default=0.0, converter=_field_number)

    def __check_init__(self):
        check_positive("Gamma", self.Gamma)
        check_positive("Delta", self.Delta)
        check_positive("tau", self.tau)
        check_positive("tau_L", self.tau_L, allow_inf=True)
        check_finite("gamma_bar", self.gamma_bar)
        _check_scales(self)

    # ---- reference units (section 2) ------------------------------------------------------
    @property
    def tau0(self):
        r"""Reference time :math:`\tau_0 = \Gamma/\Delta^2` (s)."""
        return _tau0(self.Gamma, self.Delta)

    @property
    def u0(self):
        r"""Reference length :math:`u_0 = \Gamma^2/\Delta^3` (m)."""
        return self.tau0 * self.v0

    @property
    def v0(self):
        r"""Reference velocity :math:`u_0/\tau_0 = \Gamma/\Delta` (m/s); also the unit of M0."""
        return self.Gamma / self.Delta

    @property
    def D0(self):
        r"""Reference diffusivity :math:`u_0^2/\tau_0 = \Gamma^3/\Delta^4` (m^2/s)."""
        return self.u0 * self.v0

    # ---- nondimensional numbers -----------------------------------------------------------
    @property
    def tau_nd(self):
        r""":math:`\tau' = \tau/\tau_0`."""
        return self.tau / self.tau0

    @property
    def tau_L_nd(self):
        r""":math:`\tau_L' = \tau_L/\tau_0` (``inf`` stays ``inf``)."""
        return self.tau_L / self.tau0

    @property
    def gamma_bar_nd(self):
        r""":math:`\bar\gamma' = \bar\gamma/\Delta`."""
        return self.gamma_bar / self.Delta

    @property
    def inv_tau_L(self):
        r""":math:`1/\tau_L`, exactly 0 for ``tau_L = inf``."""
        return 1.0 / self.tau_L

    def nondim(self) -> "Params":
        """The same model in (tau0, u0) units: a ``Params`` with Gamma = Delta = 1."""
        return Params(Gamma=1.0, Delta=1.0, tau=self.tau_nd, tau_L=self.tau_L_nd,
                      gamma_bar=self.gamma_bar_nd)

    @classmethod
    def from_nondim(cls, tau, tau_L=math.inf, gamma_bar=0.0, *, Gamma=1.0, Delta=1.0) -> "Params":
        r"""Build physical parameters from :math:`(\tau', \tau_L', \bar\gamma')` and a choice of
        :math:`\Gamma, \Delta` (default 1, i.e. the nondimensional model itself)."""
        check_positive("Gamma", Gamma)
        check_positive("Delta", Delta)
        # the numbers as given are checked by their own names (tau' = -1 was refused as "tau ... (got -0.222)", a
        # value the user never gave)
        check_positive("tau'", tau)
        check_positive("tau_L'", tau_L, allow_inf=True)
        check_finite("gamma_bar'", gamma_bar)
        Gamma, Delta = float(Gamma), float(Delta)
        tau0 = _tau0(Gamma, Delta)
        lo, hi = SCALE_RANGE
        if not lo <= tau0 <= hi:  # tau = tau' tau0 would be 0 (or inf), and refused as if the user gave it
            raise ValueError(f"Gamma and Delta must keep tau0 = Gamma/Delta^2 in [{lo:g}, {hi:g}] (got "
                             f"{_beyond(tau0, lo, hi)} from Gamma = {Gamma!r}, Delta = {Delta!r}): out of "
                             "floating-point range, express the parameters in other units")
        nd = []
        for name, v, unit in (("tau", tau, tau0), ("tau_L", tau_L, tau0), ("gamma_bar", gamma_bar, Delta)):
            c = _concrete(name, v)  # a Python float; None for a tracer, kept (Params checks it on the concrete call)
            if c is not None and math.isfinite(c):  # inf (tau_L) and NaN are Params' to refuse
                time = name != "gamma_bar"  # a time (unit tau0), checked as given: tau' = 1e-300 with tau0 = 1e-10
                # was refused as "tau' ... got 9.99e-301 ... tau = 1e-310", tau_L' = 1e-320 as "tau_L must be > 0
                # (got 0.0)": values never given
                if time and not lo <= c <= hi:
                    raise ValueError(f"{name}' must lie in [{lo:g}, {hi:g}] (got {_beyond(c, lo, hi)}): out of "
                                     "floating-point range, express the parameters in other units")
                if not math.isfinite(c * unit):  # 1e300 tau0: tau_L = inf
                    raise ValueError(f"{name} must keep {name}' x its unit finite (got {name}' = {c!r} with unit "
                                     f"{unit:.3g}): choose a "
                                     + ("smaller Gamma or a larger Delta" if time else "smaller Delta"))
                if time and c * unit < sys.float_info.min:  # subnormal or 0
                    raise ValueError(f"{name} must keep {name}' x its unit above {sys.float_info.min:.3g} (got "
                                     f"{name}' = {c!r} with unit {unit:.3g}): choose a larger Gamma or a smaller "
                                     "Delta")
            nd.append(v if c is None else c)
        tau, tau_L, gamma_bar = nd
        try:
            return cls(Gamma=Gamma, Delta=Delta, tau=tau * tau0, tau_L=tau_L * tau0, gamma_bar=gamma_bar * Delta)
        except ValueError as e:  # the physical values are ours, not the user's: say what they came from
            raise ValueError(f"{e} (from_nondim's tau' = {tau!r}, tau_L' = {tau_L!r}, gamma_bar' = {gamma_bar!r} "
                             f"in units tau0 = {tau0!r} s, Delta = {Delta!r})") from None

    def as_dict(self) -> dict:
        return {k: float(getattr(self, k)) for k in ("Gamma", "Delta", "tau", "tau_L", "gamma_bar")}

    # ---- thresholds (section 6.1) ---------------------------------------------------------
    @property
    def x_thresholds(self):
        r"""Noise thresholds :math:`x_{\pm\Delta} = (-b(0) \pm \Delta)/\sqrt{\Gamma}`.

        A stuck particle (V = 0) starts to move up when :math:`X` rises above :math:`x_{\Delta}`
        and down when it falls below :math:`x_{-\Delta}`.
        """
        s = math.sqrt(self.Gamma)
        return (-self.gamma_bar + self.Delta) / s, (-self.gamma_bar - self.Delta) / s


#: The paper's Fig. 3 point (SI units): also the CLI defaults.
FIG3 = dict(Gamma=5.0, Delta=3.84, tau=0.5, tau_L=0.067, gamma_bar=0.342)
