"""The headline figures on the README and the benchmarks' page are the results' own:
``benchmarks/figures.py`` makes the table from ``benchmarks/results/*.json``."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import figures


@pytest.mark.parametrize("page", figures.PAGES, ids=lambda p: p.name)
def test_the_table_on_each_page_is_made_from_the_results(page: Path) -> None:
    text = page.read_text()
    block = text.split(figures.START)[1].split(figures.END)[0]
    assert block.strip() == figures.table().strip(), (
        f"{page}: the figures differ from benchmarks/results (python -m benchmarks.figures --write)"
    )


def test_a_page_without_its_markers_is_named() -> None:
    with pytest.raises(ValueError, match=r"page\.md: needs one"):
        figures.replaced("no markers here", "| a |\n", "page.md")
    text = f"a\n{figures.START}\nold\n{figures.END}\nb\n"
    assert (
        figures.replaced(text, "| new |\n", "p")
        == f"a\n{figures.START}\n| new |\n{figures.END}\nb\n"
    )
