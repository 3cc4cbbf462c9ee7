"""The compiled code the `dryfric` command keeps between runs (dryfric_jax.compile_cache): where it
lives, when it is off, and that a run on loaded code gives the freshly compiled run's numbers."""
import json
import os
import pathlib
import platform
import subprocess
import sys

import jax
import jaxlib
import pytest

from dryfric_jax import compile_cache
from dryfric_jax.compile_cache import cache_root, enable, host_tag

ROOT = pathlib.Path(__file__).parent.parent
# the commands below start with no JAX cache directory of the developer's (which would win over ours)
ENV = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}


def test_cache_root_follows_the_environment():
    home = os.path.expanduser("~")
    assert cache_root({}) == os.path.join(home, ".cache", "dryfric_jax", "xla")
    assert cache_root({"XDG_CACHE_HOME": "/x/cache"}) == "/x/cache/dryfric_jax/xla"
    # an empty or relative XDG_CACHE_HOME counts as unset, as the XDG spec says
    assert cache_root({"XDG_CACHE_HOME": ""}) == os.path.join(home, ".cache", "dryfric_jax", "xla")
    assert cache_root({"XDG_CACHE_HOME": "rel/cache"}) == os.path.join(home, ".cache", "dryfric_jax", "xla")
    # DRYFRIC_CACHE_DIR wins over XDG_CACHE_HOME, as given (~ expanded), and turns the cache off
    assert cache_root({"DRYFRIC_CACHE_DIR": "/y/c", "XDG_CACHE_HOME": "/x"}) == "/y/c"
    assert cache_root({"DRYFRIC_CACHE_DIR": "~/c"}) == os.path.join(home, "c")
    for off in ("off", "OFF", "0", "no", "false", "none", "", "  "):
        assert cache_root({"DRYFRIC_CACHE_DIR": off, "XDG_CACHE_HOME": "/x"}) is None, off


def test_no_home_directory_means_no_cache(monkeypatch):
    monkeypatch.setattr(os.path, "expanduser", lambda p: p)  # what it does when it finds no home
    assert cache_root({}) is None
    assert cache_root({"XDG_CACHE_HOME": "/x"}) == "/x/dryfric_jax/xla"
    assert cache_root({"DRYFRIC_CACHE_DIR": "c"}) == "c"  # a relative directory the user asked for is theirs


def test_host_tag_is_one_per_jaxlib_machine_and_cpu(monkeypatch):
    tag = host_tag()
    assert tag.startswith(f"jaxlib-{jaxlib.__version__}-{platform.machine()}-")
    assert host_tag() == tag  # the same host, the same directory
    monkeypatch.setattr(compile_cache, "_cpu_features", lambda: "model name : A\nflags : fpu sse2 avx2")
    a = host_tag()
    monkeypatch.setattr(compile_cache, "_cpu_features", lambda: "model name : A\nflags : fpu sse2 avx2 avx512f")
    b = host_tag()
    assert a != b and a.rsplit("-", 1)[0] == b.rsplit("-", 1)[0]  # only the CPU part differs


@pytest.mark.skipif(not os.path.exists("/proc/cpuinfo"), reason="Linux's /proc/cpuinfo")
def test_cpu_features_are_the_first_processors_model_and_flags():
    first = open("/proc/cpuinfo", encoding="utf-8", errors="replace").read().split("\n\n")[0].splitlines()
    feats = compile_cache._cpu_features().splitlines()
    assert feats and set(feats) <= set(first)
    names = {ln.split(":")[0].strip().lower() for ln in feats}
    assert names & {"flags", "features", "isa"}  # the instruction set is in it (x86 flags, Arm features)
    assert "processor" not in names and "cpu mhz" not in names  # nothing that changes between cores or runs


@pytest.fixture
def no_jax_cache():
    """This process with no JAX cache directory (a developer's JAX_COMPILATION_CACHE_DIR set aside)."""
    before = jax.config.jax_compilation_cache_dir
    jax.config.update("jax_compilation_cache_dir", None)
    yield
    jax.config.update("jax_compilation_cache_dir", before)


def test_enable_runs_without_a_cache_it_cannot_make(tmp_path, no_jax_cache, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    assert enable(str(blocker / "cache")) is None  # a file in the way: no cache, no error
    assert jax.config.jax_compilation_cache_dir is None
    # a directory that exists but takes no file (a read-only mount, a full quota: os.access says yes there)
    from dryfric_jax import outfiles
    monkeypatch.setattr(outfiles, "_can_create_in", lambda d: False)
    assert enable(str(tmp_path / "ro")) is None
    assert jax.config.jax_compilation_cache_dir is None


def test_enable_is_off_when_told(monkeypatch, no_jax_cache):
    monkeypatch.setenv("DRYFRIC_CACHE_DIR", "off")
    assert enable() is None
    assert jax.config.jax_compilation_cache_dir is None


def _python(code, env):
    p = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return p.stdout.strip()


def test_enable_removes_the_entries_a_full_disk_left_empty(tmp_path):
    """JAX never rewrites an entry that exists: one a full disk left empty made every later run compile anew,
    silently (an audit).  enable() removes the empty ones and keeps the others."""
    env = {**ENV, "DRYFRIC_CACHE_DIR": str(tmp_path / "c")}
    d = tmp_path / "c" / _python("import dryfric_jax.compile_cache as c; print(c.host_tag())", env)
    d.mkdir(parents=True)
    (d / "jit__round_impl-0a1b-cache").write_bytes(b"")
    (d / "jit__lane_start-2c3d-cache").write_bytes(b"compiled")
    (d / "notes").write_bytes(b"")  # not an entry
    assert _python("import dryfric_jax.compile_cache as c; print(c.enable())", env) == str(d)
    assert sorted(os.listdir(d)) == ["jit__lane_start-2c3d-cache", "notes"]


def test_enable_leaves_the_users_own_jax_cache_alone(tmp_path):
    # JAX reads JAX_COMPILATION_CACHE_DIR when it starts: a new process
    env = {**ENV, "JAX_COMPILATION_CACHE_DIR": str(tmp_path / "theirs"), "DRYFRIC_CACHE_DIR": str(tmp_path / "ours")}
    out = _python("import jax, dryfric_jax.compile_cache as c; print(c.enable(), jax.config.jax_compilation_cache_dir)",
                  env)
    assert out == f"{tmp_path / 'theirs'} {tmp_path / 'theirs'}"
    assert not (tmp_path / "ours").exists()


def test_enable_sets_jax_cache_in_the_hosts_directory(tmp_path):
    env = {**ENV, "DRYFRIC_CACHE_DIR": str(tmp_path / "c")}
    out = _python("import jax, dryfric_jax.compile_cache as c; p = c.enable(); print(p, c.host_tag(), "
                  "jax.config.jax_compilation_cache_dir == p, jax.config.jax_persistent_cache_min_compile_time_secs, "
                  "c.enable(str(p) + '-elsewhere') == p)", env).split()
    assert out[0] == str(tmp_path / "c" / out[1]) and os.path.isdir(out[0])
    assert out[2] == "True" and float(out[3]) == compile_cache.MIN_COMPILE_TIME_S
    assert out[4] == "True" and not os.path.exists(out[0] + "-elsewhere")  # a second call keeps the first's


# the command, run as `dryfric` runs it, counting the compilations that JAX's cache served (its own events)
_COUNTED = """
import sys, jax
from dryfric_jax import cli
hits = []
jax.monitoring.register_event_listener(lambda e, **kw: hits.append(e) if e.endswith("/cache_hits") else None)
rc = cli.main(sys.argv[1:])
print("HITS", len(hits), file=sys.stderr)
sys.exit(rc)
"""


def _estimate(env):
    """``dryfric estimate --json`` (the fields a compilation may change dropped) and the cache's hits."""
    argv = [sys.executable, "-c", _COUNTED, "estimate", "--json", "--n-excursions", "300", "--seed", "5"]
    p = subprocess.run(argv, env=env, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    r = json.loads(p.stdout)
    for timing in ("wall_s", "lane_steps_per_s"):
        r.pop(timing)
    return r, int(p.stderr.split("HITS")[-1])


def test_a_run_on_cached_code_gives_the_fresh_runs_numbers(tmp_path):
    """The command writes its compiled code on the first run and loads every entry on the second, and
    the result is the same to the last bit.  (The second run may add entries: a program that compiled
    in under MIN_COMPILE_TIME_S the first time can take longer on a loaded machine.)"""
    env = {**ENV, "DRYFRIC_CACHE_DIR": str(tmp_path)}
    fresh, _ = _estimate(env)
    entries = sorted(p.name for p in tmp_path.rglob("*") if p.is_file())
    assert entries and all(e.endswith("-cache") for e in entries)
    assert {p.name for p in tmp_path.iterdir()} == {host_tag()}
    loaded, hits = _estimate(env)
    assert hits >= len(entries)  # each entry loaded (an entry may serve several calls' compilations)
    assert set(entries) <= {p.name for p in tmp_path.rglob("*") if p.is_file()}  # still there
    assert loaded == fresh
