"""Every notebook runs top to bottom (issue 5); the EMPS one reads the data through the normal loader."""

from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))


#: Notebooks that read the EMPS benchmark record.
NEEDS_EMPS = {"03_emps_reproduction.ipynb", "05_pid_tuning.ipynb", "06_block_structures.ipynb"}


def test_all_notebooks_are_present():
    assert [p.name for p in NOTEBOOKS] == [
        "01_quickstart.ipynb", "02_trs_reproduction.ipynb", "03_emps_reproduction.ipynb",
        "04_numerical_example.ipynb", "05_pid_tuning.ipynb", "06_block_structures.ipynb",
    ]


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes(path, request, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    if path.name in NEEDS_EMPS:
        emps_dir = request.getfixturevalue("emps_dir")  # skips (or fails in CI) without the data
        monkeypatch.setenv("HAMMERSTEIN_CTRL_DATA", str(emps_dir.parent))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(nb, timeout=240, kernel_name="python3",
                                     resources={"metadata": {"path": str(path.parent)}})
    client.execute()  # raises CellExecutionError on the first failing cell
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.get("output_type") == "error"]
    assert not errors
