"""The documentation site's page lists (docs/_ext/hexcal_docs.py), without building it.

The build itself (``make docs``: every page, the API reference, the executed tutorials, with
warnings as errors) runs in CI after the tests; these checks say that a page added to docs/
joins the start page by itself, and that the start page keeps the markers that list them.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _load_ext(name: str):
    """A module of docs/_ext, loaded from its file (docs/_ext is not a package)."""
    spec = importlib.util.spec_from_file_location(name, DOCS / "_ext" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_extension():
    return _load_ext("hexcal_docs")


def test_every_page_of_docs_is_in_a_list_of_the_start_page():
    ext = load_extension()
    index = (DOCS / "index.md").read_text(encoding="utf-8")
    assert ext.MARKER in index and ext.TUTORIAL_MARKER in index
    listed = set(ext.guide_pages(DOCS)) | set(ext.tutorial_pages(DOCS))
    for other in ext.ELSEWHERE - {"index"}:  # the pages the start page names itself
        assert f"\n{other}\n" in index, other
        listed.add(other)
    pages = {p.stem for p in DOCS.glob("*.md")} - {"index"}
    pages |= {
        p.relative_to(DOCS).with_suffix("").as_posix()
        for p in DOCS.glob("*/**/*.md")
        if p.relative_to(DOCS).parts[0] not in ext.OWN_FOLDERS
    }
    pages |= {f"tutorials/{p.stem}" for p in (DOCS / "tutorials").glob("*.md")}
    assert pages <= listed, pages - listed


def test_a_new_page_joins_the_user_guide_after_the_known_ones(tmp_path):
    ext = load_extension()
    for name in ("formats", "commands", "ballbar", "iso-tests", "index", "changelog"):
        (tmp_path / f"{name}.md").write_text(f"# {name}\n", encoding="utf-8")
    (tmp_path / "tutorials").mkdir()
    for name in ("zeta", "paper"):
        (tmp_path / "tutorials" / f"{name}.md").write_text("# t\n", encoding="utf-8")
    (tmp_path / "guide").mkdir()
    (tmp_path / "guide" / "deep.md").write_text("# deep\n", encoding="utf-8")
    assert ext.guide_pages(tmp_path) == ["commands", "formats", "ballbar", "iso-tests", "guide/deep"]
    assert ext.tutorial_pages(tmp_path) == ["tutorials/paper", "tutorials/zeta"]


def test_the_tutorials_are_notebooks_the_build_executes():
    for page in [DOCS / "getting-started.md", *sorted((DOCS / "tutorials").glob("*.md"))]:
        text = page.read_text(encoding="utf-8")
        assert text.startswith("---\njupytext:") and "kernelspec:" in text, page.name
        assert "```{code-cell} ipython3" in text, page.name


def load_runner():
    """The examples check (plain text: it needs none of the docs dependencies)."""
    return _load_ext("hexcal_examples")


def test_every_shell_or_python_example_runs_or_is_a_template():
    run = load_runner()
    pages = [p for p in DOCS.rglob("*.md") if "_build" not in p.parts]
    unrun = {p.relative_to(DOCS).as_posix(): run.unrun_examples(p.read_text(encoding="utf-8")) for p in pages}
    assert not {page: lines for page, lines in unrun.items() if lines}
    # the guide pages' command examples do run (the build runs {hexcal-run} blocks)
    for name in ("commands", "ballbar", "instruments", "sessions", "observability", "planning"):
        kinds = dict(run.classify((DOCS / f"{name}.md").read_text(encoding="utf-8"))).values()
        assert "run" in kinds, name


def test_the_check_finds_an_example_that_neither_runs_nor_is_marked():
    run = load_runner()
    page = "\n".join(
        [
            "```sh",
            "hexcal paper",
            "```",  # 1: unmarked
            "```{code-block} bash",
            ":caption: x",
            "hexcal fk",
            "```",  # 4: unmarked
            "```{code-block} sh",
            ":class: template",
            "hexcal fk",
            "```",  # 8: template
            "```{hexcal-run}",
            ":hide:",
            "hexcal --version",
            "```",  # 12: runs
            "```",
            "hexcal ik --geometry g.yaml",
            "```",  # 16: bare command
            "```python",
            "import hexcal",
            "```",  # 19: unmarked
            "```yaml",
            "units: mm",
            "```",  # data
            "```",
            "id,x,y",
            "```",  # data / output
            "````{code-cell} ipython3",
            "1 + 1",
            "````",  # 28: runs
        ]
    )
    assert run.classify(page) == [
        (1, "unmarked"),
        (4, "unmarked"),
        (8, "template"),
        (12, "run"),
        (16, "unmarked"),
        (19, "unmarked"),
        (28, "run"),
    ]
    assert run.unrun_examples(page) == [1, 4, 16, 19]


def _build(tmp_path, page: str) -> tuple[int, str, str]:
    """Build one page with the runner (text builder, warnings as errors): exit, warnings, text."""
    pytest.importorskip("myst_parser")
    from sphinx.cmd.build import build_main

    src = tmp_path / "src"
    src.mkdir()
    (src / "conf.py").write_text(
        f"import sys\nsys.path.insert(0, {str(DOCS / '_ext')!r})\n"
        "extensions = ['myst_parser', 'hexcal_run']\n",
        encoding="utf-8",
    )
    (src / "index.md").write_text(page, encoding="utf-8")
    warnings = tmp_path / "warnings.txt"
    code = build_main(
        ["-q", "-E", "-W", "--keep-going", "-b", "text", "-w", str(warnings), str(src), str(tmp_path / "out")]
    )
    out = tmp_path / "out" / "index.txt"
    return code, warnings.read_text(encoding="utf-8"), out.read_text(encoding="utf-8") if out.exists() else ""


def test_a_run_block_shows_its_output_and_later_blocks_see_its_files(tmp_path):
    page = "\n".join(
        [
            "# t",
            "",
            "```{hexcal-run}",
            ":hide:",
            "echo 41 > n.txt",
            "```",
            "",
            "```{hexcal-run}",
            "---",
            "expect: |",
            "  it is 42",
            "---",
            'echo "it is $(( $(cat n.txt) + 1 ))"',
            "hexcal --version",
            "```",
            "",
        ]
    )
    code, warnings, text = _build(tmp_path, page)
    assert code == 0, warnings
    assert "it is 42" in text and "hexcal " in text and "41 > n.txt" not in text


@pytest.mark.parametrize(
    "script, message",
    [
        ("hexcal fk --geometry nowhere.yaml --legs none.csv --out x.csv", "the example failed (exit 1)"),
        ("echo 0.061 mm", "does not contain '0.063 mm'"),
    ],
)
def test_a_failing_block_or_a_figure_the_output_lacks_fails_the_build(tmp_path, script, message):
    page = "\n".join(
        [
            "# t",
            "",
            "```{hexcal-run}",
            "---",
            "expect: 0.063 mm",
            "---",
            script,
            "```",
            "",
            "```sh",
            "hexcal paper",
            "```",
            "",
        ]
    )
    code, warnings, _ = _build(tmp_path, page)
    assert code != 0
    assert message in warnings
    assert "index.md:10: WARNING: a shell or Python example that does not run" in warnings
