"""The documentation's contracts: every public name documented with an example, the README short, and no page
pointing outside the repository.  ``make docs`` (run by CI) builds the site with warnings and broken references as
errors."""

import inspect
import re
from pathlib import Path

import pytest

import hammerstein_ctrl as hc

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]


@pytest.mark.parametrize("name", [n for n in hc.__all__ if n != "__version__"])
def test_every_public_name_has_a_runnable_example(name):
    doc = inspect.getdoc(getattr(hc, name)) or ""
    assert "Examples" in doc and ">>>" in doc, f"hammerstein_ctrl.{name} has no example in its docstring"


def test_the_readme_stays_short():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 150


@pytest.mark.parametrize("page", [p for p in PAGES if "_build" not in p.parts], ids=lambda p: p.name)
def test_no_page_points_outside_the_repository(page):
    text = page.read_text()
    assert "DESIGN.md" not in text and "../shared" not in text
    for target in re.findall(r"\]\(([^)#]+)\)", text):
        if "://" in target:
            continue
        assert (page.parent / target).resolve().is_relative_to(ROOT), f"{page.name} links to {target}"
        assert (page.parent / target).exists(), f"{page.name} links to {target}, which does not exist"


def test_the_user_guide_covers_every_topic():
    guide = ROOT / "docs" / "user_guide"
    topics = ("data", "structures", "identification", "selection", "mimo", "delay_records", "lure",
              "wiener_hammerstein", "pid", "cli", "speed")
    index = (guide / "index.md").read_text()
    for topic in topics:
        assert (guide / f"{topic}.md").is_file() and f"\n{topic}\n" in index


SUBPACKAGES = ("data", "optimize", "simulate", "blocks", "plotting", "assess", "fit", "design", "io", "cli")


@pytest.mark.parametrize("sub", SUBPACKAGES)
def test_every_subpackage_states_its_contract(sub):
    """``__all__``, every name of it documented, and a docstring whose table lists only names of ``__all__``."""
    import importlib

    module = importlib.import_module(f"hammerstein_ctrl.{sub}")
    doc = module.__doc__ or ""
    listed = re.findall(r"^   (\w+)$", doc.split(".. autosummary::", 1)[-1], flags=re.M) if "autosummary" in doc else []
    assert listed and set(listed) <= set(module.__all__), f"hammerstein_ctrl.{sub}'s docstring table: {listed}"
    undocumented = [n for n in module.__all__ if not n.isupper() and not inspect.getdoc(getattr(module, n))]
    assert not undocumented, f"hammerstein_ctrl.{sub}: {undocumented} have no docstring"
