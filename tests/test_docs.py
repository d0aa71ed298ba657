"""The documentation covers the public API, without building it (CI builds the site with
``sphinx-build -W``): every name of ``rcm_kin.__all__`` has a docstring and is listed in the API
reference, every subpackage has its section there, and the README stays short and links pages
that exist."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

import rcm_kin

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
API = (DOCS / "api.md").read_text()
SUBPACKAGES = sorted(p.parent.name for p in (ROOT / "src" / "rcm_kin").glob("*/__init__.py"))


@pytest.mark.parametrize("name", rcm_kin.__all__)
def test_public_name_has_a_docstring(name):
    obj = getattr(rcm_kin, name)
    doc = (obj.__doc__ or "").strip()
    generated = dataclasses.is_dataclass(obj) and doc.startswith(f"{obj.__name__}(")  # dataclass's own
    assert doc and not generated, f"rcm_kin.{name} has no docstring"


@pytest.mark.parametrize("name", rcm_kin.__all__)
def test_public_name_is_in_the_api_reference(name):
    obj = getattr(rcm_kin, name)
    face = obj.__module__.split(".")[1]          # rcm_kin.<subpackage>.<module>
    assert f"rcm_kin.{face}.{name}" in API, f"docs/api.md does not list rcm_kin.{face}.{name}"


@pytest.mark.parametrize("package", SUBPACKAGES)
def test_every_subpackage_has_a_section_in_the_api_reference(package):
    assert re.search(rf"\.\. auto(module|function):: rcm_kin\.{package}\b", API), package


def test_every_page_is_in_the_table_of_contents():
    index = (DOCS / "index.md").read_text()
    pages = sorted(p.stem for p in DOCS.glob("*.md") if p.stem != "index")
    assert [p for p in pages if f"\n{p}\n" not in index] == []


def test_readme_is_short_and_links_pages_that_exist():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    links = re.findall(r"\]\(((?:docs/)?[\w./-]+\.(?:md|png))(?:#[\w-]+)?\)", readme)
    assert links and [link for link in links if not (ROOT / link).is_file()] == []


def test_readme_python_example_runs(capsys, tmp_path, monkeypatch):
    readme = (ROOT / "README.md").read_text()
    (block,) = re.findall(r"```python\n(.*?)```", readme, re.S)
    monkeypatch.chdir(tmp_path)                       # the example writes its files where it runs
    namespace = {}
    exec(compile(block, "README.md", "exec"), namespace)
    assert list(namespace["ik"].q) == pytest.approx([0.1, -0.2, 0.09])
    assert capsys.readouterr().out.strip()           # it printed its results (their wrapping follows numpy's options)
    assert (tmp_path / "torque_map.csv").stat().st_size > 0 and (tmp_path / "psm.html").stat().st_size > 0
    tmap = namespace["tmap"]
    assert tmap.sel(roll=10, pitch=-10, joint="pitch").pwm == tmap.effort.pwm[10, 30, 0, 1]
