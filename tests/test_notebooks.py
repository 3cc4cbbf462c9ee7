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
    ns = {"__name__": "__main__"}
    for i, cell in enumerate(nb["cells"]):
        if cell["cell_type"] == "code":
            exec(compile("".join(cell["source"]), f"{path.name}[cell {i}]", "exec"), ns)  # noqa: S102


def test_there_are_notebooks():
    assert {"quickstart.ipynb", "sweep.ipynb", "figures.ipynb"} <= {p.name for p in NOTEBOOKS}
