"""The oldest JAX, jaxlib and equinox the package accepts (dryfric_jax.requirements): the floors in
pyproject.toml and in the import check are the same, a too-old install is named with the command
that upgrades it (ImportError from Python, one line and exit 2 from the dryfric command), and the
installed versions pass."""
import subprocess
import sys
from pathlib import Path

import pytest

from dryfric_jax import requirements as rq

ROOT = Path(__file__).resolve().parents[1]


def test_the_floors_in_pyproject_are_the_ones_checked_at_import():
    floors = rq.pyproject_floors((ROOT / "pyproject.toml").read_text())
    for name, v in rq.MINIMUM.items():
        assert floors[name] == v, (name, floors.get(name), v)
    # every dependency has a floor (check_min_versions.sh installs exactly these)
    assert set(floors) == {"jax", "jaxlib", "numpy", "equinox", "matplotlib", "scipy"}, floors


def test_pyproject_floors_reads_the_dependencies_list_only():
    text = """[project]
dependencies = [
    "jax>=0.6.2",
    "numpy>=1.26",  # a comment
    "typing-extensions>=4.0",
    "nofloor",
    "capped<3",
    "scipy>=1.12,<2",  # jax's own floor: 'quoted>=9' in a comment is not read
    "matplotlib <4, >= 3.7",
    'equinox>=0.12.2',
    "rich[jupyter] >=13.1; python_version >= '3.9'",
    "tqdm~=4.6",
]
[project.optional-dependencies]
dev = ["pytest>=7"]
"""
    assert rq.pyproject_floors(text) == {"jax": "0.6.2", "numpy": "1.26", "typing-extensions": "4.0", "scipy": "1.12",
                                         "matplotlib": "3.7", "equinox": "0.12.2", "rich": "13.1"}
    with pytest.raises(ValueError, match="dependencies"):
        rq.pyproject_floors("[project]\nname = 'x'\n")


@pytest.mark.parametrize("version, expected", [
    ("0.6.2", (0, 6, 2)), ("0.10.2", (0, 10, 2)), ("0.10.2rc1", (0, 10, 2)), ("0.6.1.dev20250601", (0, 6, 1)),
    ("1!2.0", (2, 0)), ("v1.2", (1, 2)), ("0.12.2.post1", (0, 12, 2)), ("unknown", ()),
])
def test_release_numbers(version, expected):
    assert rq.release(version) == expected


def test_numbers_compare_as_numbers_not_text():
    # "0.10" < "0.6" as text; 0.10 is the newer release
    assert rq.too_old({"jax": "0.10.0", "jaxlib": "0.10.0", "equinox": "0.13.8"}) == []
    assert rq.too_old({"jax": "0.6", "jaxlib": "0.6.2", "equinox": "0.12.2"}) == ["jax 0.6"]


@pytest.mark.parametrize("installed, old", [
    ({"jax": "0.6.2", "jaxlib": "0.6.2", "equinox": "0.12.2"}, []),  # the floors themselves
    ({"jax": "0.6.1", "jaxlib": "0.6.1", "equinox": "0.13.8"}, ["jax 0.6.1", "jaxlib 0.6.1"]),
    ({"jax": "0.10.2", "jaxlib": "0.10.2", "equinox": "0.12.1"}, ["equinox 0.12.1"]),
    ({"jax": "0.5.3", "jaxlib": None, "equinox": None}, ["jax 0.5.3"]),  # missing metadata: not checked
])
def test_what_is_too_old(installed, old):
    assert rq.too_old(installed) == old
    msg = rq.requirement_error(installed)
    if not old:
        assert msg is None
        rq.check_requirements(installed)
        return
    with pytest.raises(ImportError) as e:
        rq.check_requirements(installed)
    assert str(e.value) == msg
    for item in old:  # names what is installed, the floors, and the command
        assert item in msg
    assert "jax >= 0.6.2" in msg and "equinox >= 0.12.2" in msg
    assert "pip install -U 'jax>=0.6.2' 'jaxlib>=0.6.2' 'equinox>=0.12.2'" in msg


def test_this_install_is_recent_enough():
    installed = rq.installed_versions()
    assert installed["jax"] is not None and installed["equinox"] is not None
    assert rq.requirement_error() is None, installed


# a child that reports an old jax in its metadata, then imports the package as the given program
_CHILD = """
import sys
from importlib import metadata
real = metadata.version
metadata.version = lambda name: "0.5.3" if name in ("jax", "jaxlib") else real(name)
sys.argv = [sys.argv[1]]
{body}
"""


def _child(argv0, body):
    return subprocess.run([sys.executable, "-c", _CHILD.format(body=body), argv0], capture_output=True,
                          text=True, timeout=120)


def test_the_dryfric_command_names_an_old_jax_in_one_line_and_exits_2():
    r = _child("/usr/bin/dryfric", "from dryfric_jax.cli import main\nsys.exit(main())")
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dryfric: error: dryfric_jax needs jax >= 0.6.2"), r.stderr
    assert "installed: jax 0.5.3, jaxlib 0.5.3" in lines[0]


def test_python_m_dryfric_jax_is_the_command_too():
    """``python -m dryfric_jax`` (its __main__) runs the command: it got Python's ImportError traceback and exit 1 for
    an old JAX where ``dryfric`` says one line and exits 2 (a README audit, stop 91)."""
    r = _child("-m", "sys.orig_argv = [sys.executable, '-m', 'dryfric_jax', 'estimate']\nimport runpy\n"
                     "runpy.run_module('dryfric_jax', run_name='__main__', alter_sys=True)")
    assert r.returncode == 2 and "Traceback" not in r.stderr, (r.returncode, r.stderr)
    assert r.stderr.startswith("dryfric: error: dryfric_jax needs jax >= 0.6.2"), r.stderr


def test_python_gets_an_import_error_naming_the_old_jax():
    r = _child("script.py", "try:\n    import dryfric_jax\nexcept ImportError as e:\n    print(e)\n"
                            "    print('jax' in sys.modules)")
    assert r.returncode == 0, r.stderr
    msg, imported = r.stdout.strip().splitlines()
    assert msg.startswith("dryfric_jax needs jax >= 0.6.2") and "jax 0.5.3" in msg
    assert imported == "False"  # checked before JAX is imported


def test_the_source_distribution_carries_what_its_tests_use(tmp_path):
    """setuptools alone put tests/test_*.py in the sdist but not conftest.py (x64, the cache off, one device per
    core), the notebooks test_notebooks.py runs, nor the scripts test_cli.py runs: an unpacked sdist failed its own
    tests (a packaging audit).  MANIFEST.in grafts them.  Built here offline (setuptools' own backend, no
    isolation) from a copy of the tracked files (a checkout's egg-info/SOURCES.txt adds the files of earlier
    builds), then every tracked file is looked for in it."""
    import shutil
    import tarfile
    tracked = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True).stdout.split()
    if not tracked:
        pytest.skip("not a git checkout")
    src = tmp_path / "src"
    for f in tracked:
        if (ROOT / f).is_file():  # a tracked file deleted in the working tree is not shipped
            (src / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / f, src / f)
    code = "import sys, setuptools.build_meta as b; print(b.build_sdist(sys.argv[1]))"
    name = subprocess.run([sys.executable, "-c", code, str(tmp_path)], cwd=src, capture_output=True, text=True,
                          timeout=120, check=True).stdout.strip().splitlines()[-1]
    with tarfile.open(tmp_path / name) as tar:
        have = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    want = {f for f in tracked if f.split("/")[0] in ("tests", "notebooks", "scripts", "dryfric_jax")
            or f.endswith(".md") or f in ("MANIFEST.in", "pyproject.toml")}
    assert "tests/conftest.py" in want and want - have == set()
