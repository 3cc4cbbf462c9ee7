#!/usr/bin/env bash
# The test suite on the oldest releases pyproject.toml allows: every ">=" floor of the package's
# dependencies installed exactly (a pip constraint), in a fresh virtual environment, then the
# README's test command (extra pytest arguments pass through, e.g. -k requirements).  Not part of
# CI (it would double its time); run it when a floor changes (dryfric_jax/requirements.py).
# PYTHON=python3.10 picks the interpreter (3.10, the oldest Python pyproject allows).
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${TMPDIR:-/tmp}/dryfric-min-venv"
rm -rf "$venv"
"${PYTHON:-python3}" -m venv "$venv"
. "$venv/bin/activate"
python -m pip install -q --upgrade pip
python - > "$venv/floors.txt" <<'PY'
import importlib.util
import pathlib

# the package is not installed yet: load its requirements module (no imports beyond the stdlib) by path
spec = importlib.util.spec_from_file_location("requirements", "dryfric_jax/requirements.py")
rq = importlib.util.module_from_spec(spec)
spec.loader.exec_module(rq)
for name, version in rq.pyproject_floors(pathlib.Path("pyproject.toml").read_text()).items():
    print(f"{name}=={version}")
PY
python -m pip install -q -c "$venv/floors.txt" -e ".[dev]"
echo "installed (floors: $(tr '\n' ' ' < "$venv/floors.txt"))"
python -m pip list 2>/dev/null | grep -i -E "^(jax|jaxlib|equinox|numpy|scipy|matplotlib) "
python -m pytest -n 2 --dist loadfile -ra "$@"
