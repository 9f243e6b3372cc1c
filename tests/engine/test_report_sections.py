"""Generated sections of docs/RESULTS.md: replaced in place, added before an anchor, one blank line after."""

from __future__ import annotations

from pathlib import Path

from bench._report import replace_section

DOC = "# Results\n\nintro\n\n## A\n\nold a\n\n## B\n\nb text\n"


def test_a_section_is_replaced_in_place_and_keeps_a_blank_line_before_the_next(tmp_path: Path) -> None:
    path = tmp_path / "RESULTS.md"
    path.write_text(DOC)
    replace_section(path, "## A", "## A\n\nnew a\n", before="## B")
    assert path.read_text() == "# Results\n\nintro\n\n## A\n\nnew a\n\n## B\n\nb text\n"
    replace_section(path, "## A", "## A\n\nnewer a", before="## B")  # no trailing newline given
    replace_section(path, "## A", "## A\n\nnewer a\n\n\n", before="## B")  # or too many
    assert path.read_text() == "# Results\n\nintro\n\n## A\n\nnewer a\n\n## B\n\nb text\n"


def test_a_missing_section_goes_in_front_of_the_first_anchor_present(tmp_path: Path) -> None:
    path = tmp_path / "RESULTS.md"
    path.write_text(DOC)
    replace_section(path, "## C", "## C\n\nc text\n", before=("## Z", "## B"))
    assert path.read_text() == "# Results\n\nintro\n\n## A\n\nold a\n\n## C\n\nc text\n\n## B\n\nb text\n"
