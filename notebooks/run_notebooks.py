"""Execute the notebooks in place and keep their outputs, so a code host shows the figures.

Used by ``make notebooks``; ``python notebooks/run_notebooks.py [NOTEBOOK ...]`` runs
the given notebooks (default: all of them).  Progress bars are turned off
(``HAMMERSTEIN_CTRL_PROGRESS=0``) so no widget output is stored, figures are
rendered at :data:`FIGURE_DPI` (a ``matplotlibrc`` given to the kernel through
``$MATPLOTLIBRC``) to keep the files small, and the per-cell execution
timestamps are dropped to keep diffs quiet.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import nbclient
import nbformat

HERE = Path(__file__).resolve().parent
#: Seconds a single cell may take (the 25-trial studies run several minutes on 2 cores).
CELL_TIMEOUT = 1800
#: Resolution of the stored PNG figures (dots per inch).
FIGURE_DPI = 72


def run(path: Path) -> None:
    nb = nbformat.read(path, as_version=4)
    started = time.perf_counter()
    nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT, kernel_name="python3",
                            resources={"metadata": {"path": str(HERE)}}).execute()
    for cell in nb.cells:
        cell.metadata.pop("execution", None)
    nbformat.write(nb, path)
    print(f"{path.name}: {time.perf_counter() - started:.0f} s, {path.stat().st_size / 1e3:.0f} kB", flush=True)


def main(argv: list[str]) -> int:
    os.environ["HAMMERSTEIN_CTRL_PROGRESS"] = "0"
    os.environ.setdefault("HAMMERSTEIN_CTRL_DATA", str(HERE.parents[1] / "shared" / "data"))
    paths = [Path(a).resolve() for a in argv] or sorted(HERE.glob("*.ipynb"))
    with tempfile.TemporaryDirectory() as rc_dir:
        Path(rc_dir, "matplotlibrc").write_text(f"figure.dpi: {FIGURE_DPI}\n")
        os.environ["MATPLOTLIBRC"] = rc_dir
        for path in paths:
            run(path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
