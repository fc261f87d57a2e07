"""Issue 22, files that other programs read: HTML reports and CSV tables with hostile ids and
names. The pages of ``identify --html`` and ``validate --html`` must show them as text (escaped),
never as markup: one script (hexcal's own table sorter), no event handler, no element that the
input brought. CSV outputs must read back to the same ids.
"""

from __future__ import annotations

import csv
import html.parser
from pathlib import Path

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.io import read_poses, save_geometry

#: Pose ids that are markup if a page inserts them unescaped (also inside SVG comments).
HOSTILE_IDS = [
    "<script>alert(1)</script>",
    '"><img src=x onerror=alert(2)>',
    "p--><script>alert(3)</script><!--",  # not '-' first: refused, a spreadsheet's formula
    "<svg onload=alert(4)>",
    "]]><script>alert(5)</script>",
    "</title><iframe src=javascript:alert(6)>",
]
HOSTILE_NAME = "</title><script>alert('name')</script><b onmouseover=alert(7)>"


class _Markup(html.parser.HTMLParser):
    """Every element, attribute and script of a page."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[str] = []
        self.attributes: list[str] = []
        self.scripts: list[str] = []
        self._in_script = False
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        self.attributes += [name for name, _ in attrs]
        self._in_script = tag == "script"
        if tag == "script":
            self.scripts.append("")

    def handle_endtag(self, tag):
        if tag == "script":
            self._in_script = False

    def handle_data(self, data):
        if self._in_script:
            self.scripts[-1] += data
        else:
            self.text.append(data)


def _check_page(path: Path, shown: list[str]) -> None:
    page = path.read_text(encoding="utf-8")
    markup = _Markup()
    markup.feed(page)
    assert len(markup.scripts) == 1 and "alert" not in markup.scripts[0]  # hexcal's own sorter
    assert not [a for a in markup.attributes if a.lower().startswith("on")]
    assert not {"img", "iframe", "b"} & set(markup.tags)
    for value in [*HOSTILE_IDS, HOSTILE_NAME]:  # never in the page as it was given
        assert value not in page, value
    text = "".join(markup.text)
    for value in shown:  # the hostile text is there, as text
        assert value in text, value


def _write_poses(path: Path, ids: list[str]) -> None:
    corners = workspace_corners(preset("paper-hmt"))
    poses = corners[np.random.default_rng(5).choice(len(corners), len(ids), replace=False)]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(["id", "x", "y", "z", "a", "b", "c"])
        for pid, pose in zip(ids, poses, strict=True):
            writer.writerow([pid, *(repr(float(v)) for v in pose)])


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    """Measurements whose pose ids are hostile, of a nominal geometry with a hostile name."""
    d = tmp_path_factory.mktemp("hostile")
    save_geometry(preset("paper-hmt").replace(name=HOSTILE_NAME), d / "nominal.yaml")
    ids = [*HOSTILE_IDS, *(f"p{k}" for k in range(16 - len(HOSTILE_IDS)))]
    _write_poses(d / "poses.csv", ids)
    argv = ["synthesize", "--nominal", d / "nominal.yaml", "--true", "paper-hmt-true", "--poses"]
    assert main([str(a) for a in [*argv, d / "poses.csv", "--out", d / "measured.csv", "--seed", "1"]]) == 0
    # one gross error (5 mm in x) at a hostile id: identify names it as an outlier, as text
    lines = (d / "measured.csv").read_text(encoding="utf-8").splitlines(keepends=True)
    rows = list(csv.reader([line for line in lines if not line.startswith("#")]))
    x = rows[0].index("x")
    rows[1][x] = repr(float(rows[1][x]) + 5.0)
    with open(d / "measured.csv", "w", newline="", encoding="utf-8") as fh:
        fh.writelines(line for line in lines if line.startswith("#"))
        csv.writer(fh, lineterminator="\n").writerows(rows)
    return d


def test_identify_html_shows_hostile_ids_and_names_as_text(campaign, capsys):
    d = campaign
    argv = ["identify", "--geometry", d / "nominal.yaml", "--data", d / "measured.csv", "--method", "length"]
    status = main([str(a) for a in [*argv, "--out", d / "cal.yaml", "--html", d / "id.html", "--force"]])
    capsys.readouterr()
    assert status == 0
    _check_page(d / "id.html", [HOSTILE_NAME, HOSTILE_IDS[0]])


def test_validate_html_shows_hostile_ids_and_names_as_text(campaign, capsys):
    d = campaign
    argv = ["validate", "--geometry", d / "nominal.yaml", "--data", d / "measured.csv"]
    status = main([str(a) for a in [*argv, "--html", d / "val.html", "--out", d / "val.csv"]])
    capsys.readouterr()
    assert status == 0
    _check_page(d / "val.html", HOSTILE_IDS)
    # the per-pose table keeps the ids as they were, quoted where CSV needs it
    with open(d / "val.csv", newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(line for line in fh if not line.startswith("#"))]
    assert [r[0] for r in rows[1 : 1 + len(HOSTILE_IDS)]] == HOSTILE_IDS


def test_candidates_with_hostile_ids_read_back_the_same(campaign, tmp_path, capsys):
    argv = ["candidates", "--geometry", "paper-hmt", "--candidates", campaign / "poses.csv"]
    assert main([str(a) for a in [*argv, "--out", tmp_path / "c.csv"]]) == 0
    capsys.readouterr()
    _, ids = read_poses(tmp_path / "c.csv", "XYZ")
    assert list(ids[: len(HOSTILE_IDS)]) == HOSTILE_IDS
