"""docs/formats.md: every example file on the page is read by hexcal's own readers.

Each fenced YAML, CSV or text block of the page follows a marker ``<!-- check: KIND
[name=NAME] [setup=NAME] [rows=N] -->`` that says which reader must accept it; a block
without one fails here, so that no example escapes the check. The sections that hexcal's
docstrings cite (``docs/formats.md "Setup file"``) exist on the page.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import hexcal
from hexcal.io import read_matrix

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "formats.md"
MARKER = re.compile(r"^<!-- check: (.+?) -->$")
FENCE = re.compile(r"^```(\w*)$")


def _blocks() -> list[tuple[str, dict[str, str], str, int]]:
    """``(kind, options, text, line)`` of every fenced block (kind ``""`` when unmarked)."""
    lines = PAGE.read_text(encoding="utf-8").splitlines()
    out, marker, k = [], None, 0
    while k < len(lines):
        line = lines[k]
        if m := MARKER.match(line):
            marker = m.group(1).split()
        elif m := FENCE.match(line):
            end = lines.index("```", k + 1)
            kind, *options = marker or [""]
            opts = dict(o.split("=", 1) for o in options)
            out.append(
                (kind if m.group(1) != "sh" else "sh", opts, "\n".join(lines[k + 1 : end]) + "\n", k + 1)
            )
            marker, k = None, end
        elif line.strip():
            marker = None  # a marker belongs to the block right under it
        k += 1
    return out


BLOCKS = _blocks()


def _of(kind: str) -> list[tuple[dict[str, str], str, int]]:
    return [(opts, text, line) for k, opts, text, line in BLOCKS if k == kind]


def _write(tmp_path: Path, text: str, name: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_every_example_is_marked_for_a_reader() -> None:
    assert len(BLOCKS) >= 14  # the files; the page's one command is a template (~~~ fence)
    unmarked = [line for kind, _, _, line in BLOCKS if kind == ""]
    assert not unmarked, f"docs/formats.md: blocks at lines {unmarked} have no check marker"
    known = {"geometry", "geometry-fragment", "setup", "measurements", "poses", "legs", "targets", "tool",
             "covariance", "sh"}  # fmt: skip
    assert {kind for kind, *_ in BLOCKS} <= known


def test_the_sections_hexcal_cites_exist() -> None:
    headings = {m.group(1) for m in re.finditer(r"^#+ (.+)$", PAGE.read_text(encoding="utf-8"), re.M)}
    cited = set()
    for path in [*(ROOT / "src").rglob("*.py"), *(ROOT / "tests").rglob("*.py")]:
        text = path.read_text(encoding="utf-8")
        cited |= set(re.findall(r'docs/formats\.md,? "([^"]+)"', " ".join(text.split())))
    assert {"Setup file", "Geometry file", "Tables"} <= cited
    assert cited <= headings, sorted(cited - headings)


def test_no_docstring_cites_the_development_contract() -> None:
    """hexcal stands alone: its docstrings and comments cite docs/formats.md."""
    contract = "FORMATS" + ".md"
    files = [*(ROOT / "src").rglob("*.py"), *(ROOT / "tests").rglob("*.py")]
    citing = [str(p.relative_to(ROOT)) for p in files if contract in p.read_text(encoding="utf-8")]
    assert not citing


def test_the_leg_file_example_is_the_home_pose(tmp_path) -> None:
    [(_, text, _)] = _of("legs")
    legs = hexcal.read_legs(_write(tmp_path, text, "legs.csv"))
    nominal = hexcal.preset("paper-hmt")
    np.testing.assert_allclose(
        legs.lengths[0], hexcal.inverse_kinematics(nominal, nominal.home_pose), atol=1e-4
    )
    np.testing.assert_allclose(legs.readings[0], legs.lengths[0] - nominal.initial_leg_lengths, atol=1e-4)


def test_the_geometry_example_is_the_preset_as_hexcal_writes_it(tmp_path) -> None:
    [(_, text, _)] = _of("geometry")
    geometry = hexcal.load_geometry(_write(tmp_path, text, "g.yaml"))
    assert geometry.to_dict() == hexcal.preset("paper-hmt").to_dict()
    hexcal.save_geometry(geometry, tmp_path / "again.yaml")
    assert (tmp_path / "again.yaml").read_text(encoding="utf-8") == text


@pytest.mark.parametrize("block", _of("geometry-fragment"), ids=lambda b: f"line{b[2]}")
def test_geometry_fragments_load_into_the_example(tmp_path, block) -> None:
    [(_, base, _)] = _of("geometry")
    geometry = hexcal.load_geometry(_write(tmp_path, base + block[1], "g.yaml"))
    kind = re.search(r"kind: (\S+)", block[1])
    assert geometry.leg_model.name == (kind.group(1) if kind else "linear")


@pytest.mark.parametrize("block", _of("setup"), ids=lambda b: f"line{b[2]}")
def test_setup_examples_load(tmp_path, block) -> None:
    setup = hexcal.load_setup(_write(tmp_path, block[1], "setup.yaml"))
    assert setup.kind in ("targets", "tool")
    assert setup.auto == ("instrument_frame: auto" in block[1])


def _setup(tmp_path: Path, name: str) -> hexcal.Setup:
    [text] = [t for opts, t, _ in _of("setup") if opts.get("name") == name]
    return hexcal.load_setup(_write(tmp_path, text, f"{name}.yaml"))


READERS = {
    "measurements": lambda path, opts, tmp: hexcal.read_measurements(path, "XYZ"),
    "poses": lambda path, opts, tmp: hexcal.read_poses(path, "XYZ"),
    "legs": lambda path, opts, tmp: hexcal.read_legs(path),
    "targets": lambda path, opts, tmp: hexcal.read_target_measurements(path, _setup(tmp, opts["setup"])),
    "tool": lambda path, opts, tmp: hexcal.read_session(path, _setup(tmp, opts["setup"]), "XYZ"),
}
TABLES = [(kind, *b) for kind in READERS for b in _of(kind)]


@pytest.mark.parametrize("kind, opts, text, line", TABLES, ids=[f"{t[0]}-line{t[3]}" for t in TABLES])
def test_table_examples_are_read(tmp_path, kind, opts, text, line) -> None:
    data = READERS[kind](_write(tmp_path, text, "table.csv"), opts, tmp_path)
    rows = len(data[1]) if isinstance(data, tuple) else len(data.ids) if hasattr(data, "ids") else len(data)
    assert rows == int(opts["rows"])


def test_the_export_and_the_plain_file_say_the_same(tmp_path) -> None:
    """The semicolon, decimal-comma export with a unit row holds the plain example's numbers."""
    export, plain = [hexcal.read_measurements(_write(tmp_path, t, f"m{k}.csv"), "XYZ")
                     for k, (_, t, _) in enumerate(_of("measurements")[:2])]  # fmt: skip
    np.testing.assert_array_equal(export.readings, plain.readings)
    np.testing.assert_allclose(export.poses, plain.poses, rtol=0, atol=1e-12)


def test_the_tool_example_follows_the_transform_convention(tmp_path) -> None:
    """What the page says a probe reads at the home pose is what hexcal predicts there."""
    setup = _setup(tmp_path, "probe")
    nominal = hexcal.preset("paper-hmt")
    quiet = hexcal.NoiseModel(0.0, 0.0, 0.0)
    session = hexcal.simulate_session(
        nominal, nominal, hexcal.instrument_for(setup), nominal.home_pose[None], quiet, 0
    )
    [(_, text, _)] = _of("tool")
    read = hexcal.read_session(_write(tmp_path, text, "tool.csv"), setup, "XYZ")
    np.testing.assert_allclose(read.data.poses, session.data.poses, atol=1e-9)
    np.testing.assert_allclose(read.data.readings, session.data.readings, atol=1e-4)  # 4 decimals on the page


def test_the_covariance_example_is_read(tmp_path) -> None:
    [(_, text, _)] = _of("covariance")
    matrix = read_matrix(_write(tmp_path, text, "cov.txt"), (6, 6))
    np.testing.assert_array_equal(np.diag(matrix), [1e-4] * 3 + [1e-8] * 3)
