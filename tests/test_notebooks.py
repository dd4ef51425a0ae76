"""Every notebook runs top to bottom (issue 5) and is committed with its outputs (issue 12);
the EMPS one reads the data through the normal loader."""

import json
import re
from pathlib import Path

import pytest

import hammerstein_ctrl as hc

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


#: Notebooks that read the benchmark records (the EMPS, and the public benchmarks beside it).
NEEDS_EMPS = {"03_emps_reproduction.ipynb", "05_pid_tuning.ipynb", "06_block_structures.ipynb",
              "07_trust.ipynb", "09_lure_emps.ipynb", "10_public_benchmarks.ipynb"}


def test_all_notebooks_are_present():
    assert [p.name for p in NOTEBOOKS] == [
        "01_quickstart.ipynb", "02_trs_reproduction.ipynb", "03_emps_reproduction.ipynb",
        "04_numerical_example.ipynb", "05_pid_tuning.ipynb", "06_block_structures.ipynb", "07_trust.ipynb",
        "08_mimo.ipynb", "09_lure_emps.ipynb", "10_public_benchmarks.ipynb",
    ]


#: Upper bound on the committed notebooks' total size (outputs included).
MAX_TOTAL_BYTES = 3_200_000


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_committed_notebook_carries_its_outputs(path):
    """Committed with outputs (``make notebooks``), so a code host shows the figures; each shown once."""
    nbformat = pytest.importorskip("nbformat")
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert [c.execution_count for c in code] == list(range(1, len(code) + 1)), \
        f"{path.name} was not executed top to bottom in one run: `make notebooks`"
    outputs = [o for c in code for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    assert not [o for o in outputs if "application/vnd.jupyter.widget-view+json" in o.get("data", {})]
    images = [sum("image/png" in o.get("data", {}) for o in c.outputs) for c in code]
    assert sum(images) >= 1, f"{path.name} has no figures saved"
    assert max(images) == 1, f"{path.name}: a cell shows a figure twice"


def test_committed_notebooks_stay_small():
    assert sum(p.stat().st_size for p in NOTEBOOKS) < MAX_TOTAL_BYTES


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


def test_quickstart_notebook_shows_the_lm_message_the_code_gives(trs_case):
    """Notebook 01's committed LM output shows the message the code no longer gives.

    The cell ``lm = hc.identify(data, structure, method="lm", ..., maxfev=2000)`` is committed with
    "[FAILED: evaluation budget of 2000 exhausted before convergence [evaluation budget of 2000
    exhausted]]" (the old _assess problem plus the old optimiser message); the same call now says
    "[FAILED: evaluation budget of 2000 exhausted before convergence]".
    """
    nb = json.loads((ROOT / "notebooks" / "01_quickstart.ipynb").read_text())
    cell = next(c for c in nb["cells"]
                if c["cell_type"] == "code" and "".join(c["source"]).startswith("lm = hc.identify("))
    shown = "".join(next(o for o in cell["outputs"] if "data" in o)["data"]["text/plain"]).splitlines()[0]
    lm = hc.identify(trs_case.data, trs_case.structure, method="lm", x0=[-2.0, 0.0, 5.0, -5.0, 0.0], maxfev=2000)
    tail = re.compile(r" s (\[.*\])$")
    assert tail.search(shown).group(1) == tail.search(lm.summary().splitlines()[0]).group(1)
