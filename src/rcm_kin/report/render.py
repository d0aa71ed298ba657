"""The report's HTML: section data objects rendered by the jinja2 templates in ``templates/``.

Every section is a frozen dataclass naming its template (``template``, a class variable); the
template sees it as ``s``. Tables arrive formatted (:class:`Table`, strings), numbers for
prose arrive as numbers and are formatted in the template. Links are paths relative to the
report folder (:func:`relative`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import jinja2
from markupsafe import Markup


@dataclass(frozen=True)
class Table:
    """A table to show: column headings and rows of formatted cells."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]

    @classmethod
    def of(cls, rows, header) -> Table:
        return cls(tuple(header), tuple(tuple(str(c) for c in r) for r in rows))


def relative(path: str | Path, out: str | Path) -> str:
    """``path`` relative to the report folder ``out``, with forward slashes (a link in index.html)."""
    return Path(path).resolve().relative_to(Path(out).resolve()).as_posix()


@functools.cache
def environment() -> jinja2.Environment:
    """The templates shipped in ``rcm_kin/report/templates``, HTML-escaped, strict about names."""
    return jinja2.Environment(loader=jinja2.PackageLoader("rcm_kin.report", "templates"),
                              autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
                              lstrip_blocks=True, keep_trailing_newline=True)


def render_section(section) -> Markup:
    """One section's HTML."""
    return Markup(environment().get_template(section.template).render(s=section))


def render_index(sections, title: str = "rcm-kin report") -> str:
    """The whole page: the sections in order."""
    return environment().get_template("index.html.j2").render(
        title=title, sections=[render_section(s) for s in sections])
