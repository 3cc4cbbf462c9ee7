"""The oldest JAX, jaxlib and equinox the package runs on, checked when it is imported.

``pyproject.toml`` states the same floors (a test keeps the two equal).  They were found by
installing older releases on Python 3.11 and running the package (2026-11-28):

* jax/jaxlib 0.6.0 and older have no ``jax.shard_map`` (the lanes' multi-device round,
  :mod:`dryfric_jax.excursions`): ``dryfric estimate`` stopped with an AttributeError traceback
  on 0.4.38, 0.5.3 and 0.6.0.
* jax 0.6.1 runs the DI and the PDMP, but its Pallas (the ``"fused"`` layout, the DI's default on
  an NVIDIA GPU, :mod:`dryfric_jax.fused`) imports ``absl``, which it does not install: 3 tests
  failed with ModuleNotFoundError.
* On jax/jaxlib 0.6.2 with equinox 0.12.2, numpy 1.26.0, scipy 1.12.0 and matplotlib 3.7.0 (each
  package's floor) the whole test suite passes.
* equinox 0.12.1 and older do not import under jax 0.6.1 (``jaxlib.xla_extension`` and
  ``jax.core.Primitive`` are gone); 0.12.2 does.

The check reads the installed versions from the packages' metadata, without importing them (an
equinox too old for the installed JAX fails inside its own import, with a traceback that does not
say what to upgrade).  A package whose metadata is missing is not checked.
"""
from __future__ import annotations

import re
from importlib import metadata

#: the oldest release of each package the package runs on (module docstring)
MINIMUM = {"jax": "0.6.2", "jaxlib": "0.6.2", "equinox": "0.12.2"}


def pyproject_floors(text: str) -> dict:
    """Every ``name>=version`` floor of the ``dependencies = [...]`` list of a ``pyproject.toml``'s
    ``text``, as name -> version (the test that pyproject agrees with :data:`MINIMUM`, and
    ``scripts/check_min_versions.sh``, which loads this file before the package is installed).

    A requirement is a quoted PEP 508 string: its floor is the ``>=`` among its specifiers, also
    beside others (``"numpy>=1.26,<3"``), with spaces, extras or a marker (``"a[x] >= 2; ..."``).
    One without a floor is not listed; a comment is not read (``# jax's own floor``)."""
    deps = re.search(r"^dependencies = \[(.*?)^\]", text, re.S | re.M)
    if deps is None:
        raise ValueError("no 'dependencies = [...]' list in the pyproject text")
    floors = {}
    body = re.sub(r"#[^\n]*", "", deps.group(1))  # comments (no requirement with a floor holds a '#')
    for req in re.findall(r"\"([^\"]*)\"|'([^']*)'", body):
        m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*(?:\[[^\]]*\])?([^;]*)", req[0] or req[1])
        floor = re.search(r">=\s*([0-9][0-9.]*)", m.group(2)) if m else None
        if floor:
            floors[m.group(1)] = floor.group(1).rstrip(".")
    return floors


def release(version: str) -> tuple[int, ...]:
    """The release numbers at the start of a version string: ``"0.6.1"`` -> (0, 6, 1),
    ``"0.10.2rc1"`` and ``"0.6.1.dev20250601"`` -> (0, 10, 2) and (0, 6, 1) (a pre-release or
    nightly counts as its release), ``"1!2.0"`` -> (2, 0); () if there is none."""
    m = re.match(r"\s*v?(?:\d+!)?(\d+(?:\.\d+)*)", version)
    return tuple(int(x) for x in m.group(1).split(".")) if m else ()


def too_old(installed: dict) -> list[str]:
    """``"name version"`` for each package of ``installed`` (name -> version string or None: not
    installed, or no metadata) older than :data:`MINIMUM`."""
    old = []
    for name, floor in MINIMUM.items():
        v = installed.get(name)
        if v is not None and release(v) < release(floor):
            old.append(f"{name} {v}")
    return old


def installed_versions() -> dict:
    """The installed version of each package of :data:`MINIMUM` (None where metadata is missing)."""
    out = {}
    for name in MINIMUM:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def requirement_error(installed: dict | None = None) -> str | None:
    """What is too old, and the command that upgrades it; None if nothing is."""
    old = too_old(installed_versions() if installed is None else installed)
    if not old:
        return None
    need = " ".join(f"'{n}>={v}'" for n, v in MINIMUM.items())
    return (f"dryfric_jax needs jax >= {MINIMUM['jax']}, jaxlib >= {MINIMUM['jaxlib']} and equinox >= "
            f"{MINIMUM['equinox']}; installed: {', '.join(old)}.  Upgrade with: pip install -U {need}")


def check_requirements(installed: dict | None = None) -> None:
    """Raise ``ImportError`` (:func:`requirement_error`) if an installed package is too old."""
    msg = requirement_error(installed)
    if msg is not None:
        raise ImportError(msg)
