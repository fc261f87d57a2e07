"""The fast path of table blocks (hexcal.io.table_fast, issue 20 item 4): the same numbers,
ids, errors and warnings as the careful path, whatever a block holds.

The careful path is the reference: every file here is also read with the fast path switched
off (``block_numbers`` replaced by one that declines), and both must agree exactly.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hexcal.errors import InputError
from hexcal.io import iter_legs, iter_poses, read_legs, read_poses, table_fast, tables, write_poses
from hexcal.io.table_fast import block_numbers

HEADER = "id,x,y,z,a,b,c\n"
ROW = "{},1.5,-2,700.25,0.1,-0.05,1e-3\n"


def _careful(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tables, "block_numbers", lambda *args: None)


def _both(monkeypatch: pytest.MonkeyPatch, read, path: Path):  # type: ignore[no-untyped-def]
    """What ``read(path)`` gives (or the error line it raises) by the fast and the careful path."""
    results = []
    for careful in (False, True):
        with monkeypatch.context() as patch:
            if careful:
                _careful(patch)
            try:
                results.append(read(path))
            except InputError as exc:
                results.append(f"InputError: {exc}")
    return results


def _same(a, b) -> None:  # type: ignore[no-untyped-def]
    if isinstance(a, str) or isinstance(b, str):
        assert a == b
        return
    poses_a, ids_a = a
    poses_b, ids_b = b
    assert ids_a == ids_b
    np.testing.assert_array_equal(poses_a, poses_b)


@pytest.mark.parametrize(
    "cell, error",
    [
        (" ", "line 3, column 'y': not a number: ''"),  # np.fromstring reads a blank field as -1
        ("", "line 3, column 'y': not a number: ''"),
        ("0x10", "line 3, column 'y': not a number: '0x10'"),
        ("1_0", "line 3, column 'y': not a number: '1_0'"),
        ("1 2", "line 3, column 'y': not a number: '1 2'"),
        ("nan", "line 3, column 'y': nan is not a finite number"),
        ("1e999", "line 3, column 'y': 1e999 is not a finite number"),
        ("-1", None),  # a real -1 is read (by the careful path: -1 is what fromstring gives a blank)
        (" -1 ", None),
        ("+.5e1", None),
    ],
)
def test_a_cell_the_fast_path_may_not_judge_reads_as_the_careful_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, cell: str, error: str | None
) -> None:
    path = tmp_path / "p.csv"
    path.write_text(HEADER + ROW.format("p1") + f"p2,0,{cell},700,0,0,0\n" + ROW.format("p3"))
    fast, careful = _both(monkeypatch, lambda p: read_poses(p, "XYZ"), path)
    _same(fast, careful)
    if error is None:
        assert fast[0][1, 1] == float(cell)
    else:
        assert fast == f"InputError: {path}: {error}"


@pytest.mark.parametrize(
    "ids, error",
    [
        (["a", "b", "c"], None),
        (["-1", "2", "3"], None),  # a number may start with a formula mark
        ([" a", "b ", "c d"], None),  # blanks around an id are stripped, inside kept
        (["a", "b", "a"], "line 4, column 'id': id 'a' repeats line 2"),
        (["a", "", "c"], "line 3, column 'id': empty id"),
        (["a", "#b", "c"], "line 3, column 'id': id '#b' starts with '#'"),
        (["a", "=b", "c"], "line 3, column 'id': id '=b' starts with '='"),
        (["a", "b\x01", "c"], "line 3, column 'id': id 'b\\x01' holds a control"),
    ],
)
@pytest.mark.parametrize("where", ["first", "middle", "last"])
def test_ids_anywhere_in_the_row_read_and_refused_as_the_careful_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ids: list[str], error: str | None, where: str
) -> None:
    columns = {"first": ["id", "x", "y", "z", "a", "b", "c"], "middle": ["x", "y", "z", "id", "a", "b", "c"],
               "last": ["x", "y", "z", "a", "b", "c", "id"]}[where]  # fmt: skip
    lines = [",".join(columns)]
    for k, name in enumerate(ids):
        cells = {"id": name, "x": str(k), "y": "2.5", "z": "700", "a": "0.1", "b": "-0.2", "c": "0"}
        lines.append(",".join(cells[c] for c in columns))
    path = tmp_path / "p.csv"
    path.write_text("\n".join(lines) + "\n")
    for read in (lambda p: read_poses(p, "XYZ"), lambda p: next(iter_poses(p, "XYZ"))):
        fast, careful = _both(monkeypatch, read, path)
        _same(fast, careful)
        if where == "first" and "#b" in ids:  # a line that starts with '#' is a comment
            assert fast[1] == ("a", "c")
        elif error is None:
            assert fast[1] == tuple(i.strip() for i in ids)
            np.testing.assert_array_equal(fast[0][:, 0], np.arange(len(ids)))
        else:
            assert fast.startswith(f"InputError: {path}: {error}")


def test_a_leg_file_reads_only_the_columns_used(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """fk reads ``dl1..dl6`` when both groups are given; the lengths are not read, as with
    ``np.loadtxt``'s ``usecols`` (a text there is not refused), and the readings are exact."""
    path = tmp_path / "legs.csv"
    rows = [f"r{k},{','.join(['x'] * 6)},{','.join(str(k + j / 8) for j in range(6))}" for k in range(5)]
    path.write_text("id,l1,l2,l3,l4,l5,l6,dl1,dl2,dl3,dl4,dl5,dl6\n" + "\n".join(rows) + "\n")

    def read(p: Path):  # type: ignore[no-untyped-def]
        legs = read_legs(p)
        return legs.readings, legs.ids

    fast, careful = _both(monkeypatch, read, path)
    _same(fast, careful)
    np.testing.assert_array_equal(fast[0], [[k + j / 8 for j in range(6)] for k in range(5)])
    blocks = list(iter_legs(path, block_rows=2))
    assert [b.ids for b in blocks] == [("r0", "r1"), ("r2", "r3"), ("r4",)]


def test_a_written_file_reads_back_exactly_by_the_fast_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Values of every magnitude the writer uses (15 significant digits, scientific below 1e-4)
    read back as ``float(format(v, '.15g'))``; several blocks and chunks, the first after the header."""
    rng = np.random.default_rng(7)
    n = 50_000
    poses = rng.uniform(-1, 1, (n, 6)) * 10.0 ** rng.integers(-9, [6, 6, 6, 1, 1, 1], (n, 6))  # angles < 1
    path = tmp_path / "p.csv"
    write_poses(path, poses, ids=[f"p{k}" for k in range(n)], comment="made by the test")
    expected = np.array([[float(format(v, ".15g")) for v in row] for row in poses])
    called = []
    original = table_fast.block_numbers

    def counted(*args):  # type: ignore[no-untyped-def]
        got = original(*args)
        called.append(got is not None)
        return got

    monkeypatch.setattr(tables, "block_numbers", counted)
    got, ids = read_poses(path, "XYZ")
    np.testing.assert_array_equal(got, expected)
    assert ids == tuple(f"p{k}" for k in range(n))
    assert called and all(called)  # every block by the fast path, the first one too
    blocks = list(iter_poses(path, "XYZ", block_rows=4096))
    np.testing.assert_array_equal(np.concatenate([b[0] for b in blocks]), expected)


def test_block_numbers_declines_what_it_cannot_judge() -> None:
    ends = lambda text: np.flatnonzero(np.frombuffer(text, np.uint8) == 10)  # noqa: E731
    good = b"a,1,2\nb,3,4\n"
    values, ids, plain = block_numbers(good, ends(good), ",", 3, 0, [1, 2])
    np.testing.assert_array_equal(values, [[1, 2], [3, 4]])
    assert ids == ["a", "b"] and plain
    assert (
        block_numbers(b"a,1\nb,3,4,5\n", ends(b"a,1\nb,3,4,5\n"), ",", 3, 0, [1, 2]) is None
    )  # field counts
    assert block_numbers(b"a\t1\t2\n", ends(b"a\t1\t2\n"), "\t", 3, 0, [1, 2]) is None  # tabs: loadtxt
    values, _, _ = block_numbers(b"a,1,-1\n", ends(b"a,1,-1\n"), ",", 3, 0, [1, 2])
    assert values.tolist() == [[1.0, -1.0]]  # a -1 is read (np.fromstring gave it to blanks)
    for blank in (b"a,1,\n", b"a,1, \n", b"a,1,nan\n", b"a,1,1_0\n"):  # the careful path names them
        assert block_numbers(blank, ends(blank), ",", 3, 0, [1, 2]) is None
    assert block_numbers(b"a,1,2\n", ends(b"a,1,2\n"), ",", 3, 0, [0, 1]) is None  # the id as a number
    values, ids, plain = block_numbers(b" a,1,2\n", ends(b" a,1,2\n"), ",", 3, 0, [2])
    assert ids == [" a"] and not plain and values.tolist() == [[2.0]]


@pytest.mark.parametrize(
    "ids, expected",
    [
        ([f"p{k}" for k in range(1200)], True),  # p9 < p10: shorter first
        ([str(k) for k in range(1, 200)], True),  # the default row numbers
        ([f"{k:06d}" for k in range(50)], True),
        (["a" * 20 + "b", "a" * 20 + "c"], True),  # decided in the third 8-byte word
        (["a", "b", "b"], False),  # a repeat
        (["a" * 20, "a" * 20], False),
        (["b", "a"], False),
        (["10", "9"], False),
        (["a", "ab", "ac", "b"], False),  # shorter after longer
        (["é", "f"], False),  # not ASCII: left to the set
        (["x" * 65, "x" * 64 + "y"], False),  # over ORDER_CHARS: left to the set
    ],
)
def test_strictly_increasing_ids_are_shown_distinct_without_a_set(ids: list[str], expected: bool) -> None:
    assert table_fast.strictly_increasing(ids) is expected
    if expected:  # what it promises
        assert len(set(ids)) == len(ids)


@pytest.mark.parametrize(
    "ids, error",
    [
        (["a", "b", "c", "d", "e"], None),
        (["a", "b", "b", "c", "d"], "line 4, column 'id': id 'b' repeats line 3"),  # in one block
        (["a", "b", "c", "c", "d"], "line 5, column 'id': id 'c' repeats line 4"),  # across two
        (["a", "b", "d", "e", "b"], "line 6, column 'id': id 'b' repeats line 3"),  # after order ends
        (["b", "a", "c", "d", "a"], "line 6, column 'id': id 'a' repeats line 3"),  # never in order
    ],
)
def test_repeats_are_found_whether_or_not_the_blocks_are_in_order(
    tmp_path: Path, ids: list[str], error: str | None
) -> None:
    path = tmp_path / "p.csv"
    path.write_text(HEADER + "".join(ROW.format(i) for i in ids))
    for read in (lambda: list(iter_poses(path, "XYZ", block_rows=2)), lambda: [read_poses(path, "XYZ")]):
        if error is None:
            assert sum((b[1] for b in read()), ()) == tuple(ids)
        else:
            with pytest.raises(InputError) as info:
                read()
            assert str(info.value) == f"{path}: {error}"
