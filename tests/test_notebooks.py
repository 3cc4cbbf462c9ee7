"""The notebooks run end to end (small N: ``DRYFRIC_QUICK=1``), their code cells executed in order in
one namespace, without a Jupyter kernel (no extra dependency)."""
import json
import pathlib

import matplotlib
import pytest

matplotlib.use("Agg")

NOTEBOOKS = sorted((pathlib.Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs(path, monkeypatch, tmp_path):
    monkeypatch.setenv("DRYFRIC_QUICK", "1")
    monkeypatch.chdir(tmp_path)  # the sweep notebook writes its results file to the working directory
    nb = json.loads(path.read_text())
    # the sweep notebook twice in the same directory: its text says a rerun resumes (its quick asserts then see
    # each point once; a rerun had listed every point twice, its D record and its count's record)
    for _ in range(2 if path.name == "sweep.ipynb" else 1):
        ns = {"__name__": "__main__"}
        for i, cell in enumerate(nb["cells"]):
            if cell["cell_type"] == "code":
                exec(compile("".join(cell["source"]), f"{path.name}[cell {i}]", "exec"), ns)  # noqa: S102


def test_there_are_notebooks():
    assert {"quickstart.ipynb", "sweep.ipynb", "figures.ipynb"} <= {p.name for p in NOTEBOOKS}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_cells_have_the_ids_their_format_requires(path):
    """Format 4.5 requires a unique id per cell (nbformat warned, and Jupyter rewrote the files with
    random ids on every save)."""
    nb = json.loads(path.read_text())
    ids = [c.get("id") for c in nb["cells"]]
    assert (nb["nbformat"], nb["nbformat_minor"]) >= (4, 5)
    assert all(isinstance(i, str) and 1 <= len(i) <= 64 for i in ids) and len(set(ids)) == len(ids), ids
