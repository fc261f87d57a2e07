"""Faults of issue 11 at the io level: every one a regression test.

Outputs (:class:`hexcal.io.OutputSet`): clashes with inputs or each other, special files,
modes, symbolic and hard links, read-only files and folders, all-or-nothing commits under a
full disk, KeyboardInterrupt and signals, standard output that cannot encode or write.
Inputs: FIFOs and devices, CSV fields over the csv module's limit, comments after the header,
double byte order marks, row limits, YAML alias bombs and deep nesting, mixed key types,
implausible geometries, tables that hexcal could not read back. After every failure: one
line, nothing left behind, no input changed.
"""

from __future__ import annotations

import errno
import io
import os
import signal
import stat
import threading
import time
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_array_equal

import hexcal.io.outputs as outputs_module
import hexcal.io.table_reading as table_reading_module
from hexcal.core.presets import preset
from hexcal.errors import HexcalError, InputError, InputWarning
from hexcal.io import (
    DEFAULT_MAX_ROWS,
    OutputError,
    OutputSet,
    iter_legs,
    iter_poses,
    iter_tables,
    load_geometry,
    read_legs,
    read_matrix,
    read_measurements,
    read_poses,
    read_table,
    save_geometry,
    write_json,
    write_legs,
    write_poses,
    write_table,
    write_table_blocks,
)

POSES = "x,y,z,a,b,c"
ROW = "1,2,800,0.1,0.2,0.3"


def one_line(exc_info) -> str:
    message = str(exc_info.value)
    assert "\n" not in message and message, message
    assert ".tmp" not in message, "temporary names never reach the user"
    return message


def snapshot(folder: Path) -> dict[str, tuple[bytes | str, int]]:
    """Every entry of ``folder``: content (or link target) and mode."""
    out = {}
    for path in sorted(folder.iterdir()):
        st = path.lstat()
        if stat.S_ISLNK(st.st_mode):
            out[path.name] = (os.readlink(path), st.st_mode)
        elif stat.S_ISREG(st.st_mode):
            out[path.name] = (path.read_bytes(), st.st_mode)
        else:
            out[path.name] = (b"", st.st_mode)
    return out


@contextmanager
def no_hang(seconds: int = 5):
    """Fail instead of hanging (a FIFO opened for reading blocks forever)."""

    def alarm(signum, frame):
        raise AssertionError("blocked")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture
def files(tmp_path):
    """An input table, an existing output with mode 640, and the folder."""
    data = tmp_path / "measured.csv"
    data.write_text(f"id,{POSES}\np1,{ROW}\n", encoding="utf-8")
    old = tmp_path / "old.csv"
    old.write_text("old\n", encoding="utf-8")
    old.chmod(0o640)
    return tmp_path, data, old


# -- outputs: clashes, refused up front -------------------------------------------------


@pytest.mark.parametrize("how", ["same", "relative", "symlink", "hardlink", "dotdot"])
def test_an_output_naming_an_input_is_refused_before_any_work(files, how, monkeypatch):
    folder, data, _ = files
    name = {
        "same": data,
        "relative": Path("measured.csv"),
        "symlink": folder / "link.csv",
        "hardlink": folder / "hard.csv",
        "dotdot": folder / "sub" / ".." / "measured.csv",
    }[how]
    monkeypatch.chdir(folder)
    (folder / "sub").mkdir()
    if how == "symlink":
        (folder / "link.csv").symlink_to(data)
    if how == "hardlink":
        os.link(data, folder / "hard.csv")
    before = snapshot(folder)
    with pytest.raises(OutputError) as info:
        OutputSet([name], inputs=[data]).check()
    assert "also an input" in one_line(info)
    assert str(name) in str(info.value)
    assert snapshot(folder) == before


def test_two_outputs_on_one_file_are_refused(files):
    folder, _, _ = files
    (folder / "alias.yaml").symlink_to(folder / "r.yaml")
    for names in ([folder / "r.yaml", folder / "r.yaml"], [folder / "r.yaml", folder / "alias.yaml"]):
        with pytest.raises(OutputError) as info:
            OutputSet(names).check()
        assert "two outputs name the same file" in one_line(info)
    assert not (folder / "r.yaml").exists()


@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "socket"])
def test_special_files_are_refused_as_outputs(tmp_path, kind):
    path = tmp_path / kind
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "socket":
        import socket

        sock = socket.socket(socket.AF_UNIX)
        try:
            sock.bind(str(path))
        except OSError:
            pytest.skip("no unix sockets here")
    else:
        path = Path("/dev/null")
    with no_hang(), pytest.raises(OutputError) as info:
        write_table(path, ["x"], np.zeros((1, 1)))
    assert "regular file" in one_line(info)
    if kind == "device":
        assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_read_only_file_is_refused_even_for_root(files):
    folder, _, old = files
    old.chmod(0o444)
    before = snapshot(folder)
    with pytest.raises(OutputError) as info:
        write_poses(old, np.zeros((1, 6)))
    assert "read-only" in one_line(info)
    assert snapshot(folder) == before


def test_hard_linked_file_is_refused_and_the_link_kept(files):
    folder, _, old = files
    os.link(old, folder / "other-name.csv")
    before = snapshot(folder)
    with pytest.raises(OutputError) as info:
        write_poses(old, np.zeros((1, 6)))
    assert "hard links" in one_line(info)
    assert snapshot(folder) == before
    assert old.stat().st_nlink == 2


def test_unwritable_folder_is_refused_by_check(tmp_path, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir()
    real = outputs_module.tempfile.mkstemp

    def refuse(*args, dir=None, **kwargs):
        if Path(dir) == locked:
            raise PermissionError(errno.EACCES, "Permission denied")
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(outputs_module.tempfile, "mkstemp", refuse)
    out = OutputSet([tmp_path / "a.csv", locked / "b.csv"])
    with pytest.raises(OutputError) as info:
        out.check()
    assert "cannot write in the folder" in one_line(info) and "Permission denied" in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["locked"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes in read-only folders")
def test_read_only_folder_really(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        with pytest.raises(OutputError):
            OutputSet([locked / "b.csv"]).check()
    finally:
        locked.chmod(0o755)


def test_missing_folder(tmp_path):
    with pytest.raises(OutputError) as info:
        OutputSet([tmp_path / "nowhere" / "x.csv"]).check()
    assert "does not exist" in one_line(info)


# -- outputs: what a commit keeps ---------------------------------------------------------


def test_a_replaced_file_keeps_its_mode(files):
    _, _, old = files
    write_poses(old, np.zeros((1, 6)))
    assert stat.S_IMODE(old.stat().st_mode) == 0o640
    assert old.read_text().startswith("x,y,z")


def test_new_files_get_the_umask_mode(tmp_path):
    mask = os.umask(0o027)
    try:
        write_poses(tmp_path / "new.csv", np.zeros((1, 6)))
    finally:
        os.umask(mask)
    assert stat.S_IMODE((tmp_path / "new.csv").stat().st_mode) == 0o640


def test_a_symbolic_link_is_written_through(files):
    folder, _, old = files
    link = folder / "link.csv"
    link.symlink_to("old.csv")
    write_poses(link, np.zeros((2, 6)))
    assert link.is_symlink() and os.readlink(link) == "old.csv"
    assert len(read_poses(old, "XYZ")[1]) == 2
    assert stat.S_IMODE(old.stat().st_mode) == 0o640


def test_outputs_are_committed_together_or_not_at_all(files):
    folder, data, old = files
    before = snapshot(folder)
    with pytest.raises(RuntimeError), OutputSet([old, folder / "b.json"], inputs=[data]) as out:
        out.check()
        write_poses(old, np.zeros((1, 6)))  # the active set stages it
        write_json(folder / "b.json", {"a": 1})
        assert snapshot(folder).keys() - before.keys(), "staged beside the targets"
        raise RuntimeError("a later step fails")
    assert snapshot(folder) == before


def test_commit_after_success(files):
    folder, data, old = files
    with OutputSet([old, folder / "b.json", "-"], inputs=[data], stdout=io.StringIO()) as out:
        out.check()
        write_poses(old, np.zeros((1, 6)))
        write_json(folder / "b.json", {"a": 1})
        out.print("done")
        assert old.read_text() == "old\n"
    assert old.read_text().startswith("x,y,z")
    assert (folder / "b.json").read_text() == '{\n  "a": 1\n}\n'
    assert sorted(p.name for p in folder.iterdir()) == ["b.json", "measured.csv", "old.csv"]


def test_a_declared_folder_is_removed_if_nothing_is_committed(tmp_path):
    with pytest.raises(KeyboardInterrupt), OutputSet() as out:
        results = out.folder(tmp_path / "results" / "paper")
        out.check()
        assert results.is_dir()
        out.write_text(results / "table1.json", "{}")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_figures_are_staged_with_their_suffix(tmp_path):
    with OutputSet([tmp_path / "fig.png"]) as out, out.staged(tmp_path / "fig.png") as name:
        assert name.endswith(".png") and Path(name).parent == tmp_path
        Path(name).write_bytes(b"\x89PNG")
    assert (tmp_path / "fig.png").read_bytes() == b"\x89PNG"
    assert [p.name for p in tmp_path.iterdir()] == ["fig.png"]


# -- outputs: standard output before the commit ------------------------------------------


class _Full(io.RawIOBase):
    def writable(self):
        return True

    def write(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")


@pytest.mark.parametrize("fault", ["ascii", "full"])
def test_standard_output_failure_leaves_no_output_file(files, fault):
    folder, _, old = files
    if fault == "ascii":
        stream = io.TextIOWrapper(io.BytesIO(), encoding="ascii")
    else:
        stream = io.TextIOWrapper(io.BufferedWriter(_Full()), encoding="utf-8")
    before = snapshot(folder)
    with pytest.raises(OutputError) as info, OutputSet([old], stdout=stream) as out:
        write_poses(old, np.zeros((1, 6)))
        out.print("residual 0.012 mm, σ = 0.01 mm")
    message = one_line(info)
    assert message.startswith("standard output")
    assert ("PYTHONIOENCODING" in message) if fault == "ascii" else ("No space left" in message)
    assert snapshot(folder) == before


def test_dash_is_standard_output(tmp_path):
    stream = io.TextIOWrapper(io.BytesIO(), encoding="utf-8")
    with OutputSet(["-"], stdout=stream) as out:
        write_poses("-", np.zeros((1, 6)), outputs=out)
    stream.flush()
    assert stream.buffer.getvalue().decode().startswith("x,y,z,a,b,c\n0,0,0")
    assert list(tmp_path.iterdir()) == []


# -- outputs: a full disk, KeyboardInterrupt and signals at random moments ----------------


class _FillingFile:
    """A file on a disk that runs out of space after ``budget["left"]`` characters in all."""

    def __init__(self, fh, budget):
        self._fh, self._budget = fh, budget

    def write(self, text):
        if len(text) > self._budget["left"]:
            raise OSError(errno.ENOSPC, "No space left on device")
        self._budget["left"] -= len(text)
        return self._fh.write(text)

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._fh.close()


def _three_outputs(folder, data, old):
    with OutputSet([old, folder / "g.yaml", folder / "r.json"], inputs=[data]) as out:
        out.check()
        write_poses(old, np.arange(600.0).reshape(100, 6))
        save_geometry(preset("paper-hmt"), folder / "g.yaml")
        write_json(folder / "r.json", {"rms": [0.1] * 50})


@pytest.mark.parametrize("room", [0, 10, 500, 2400, 2900, 3500])
def test_a_full_disk_at_any_point_leaves_nothing(files, monkeypatch, room):
    folder, data, old = files
    budget = {"left": room}
    real_open = open

    def filling_open(path, mode="r", *args, **kwargs):
        fh = real_open(path, mode, *args, **kwargs)
        if "w" not in mode:
            return fh
        return _FillingFile(fh, budget)

    monkeypatch.setattr(outputs_module, "open", filling_open, raising=False)
    before = snapshot(folder)
    with pytest.raises(OutputError) as info:
        _three_outputs(folder, data, old)
    message = one_line(info)
    assert "No space left on device" in message and str(folder) in message
    assert snapshot(folder) == before


@pytest.mark.parametrize("target", ["replace", "link", "chmod"])
@pytest.mark.parametrize("call", [1, 2, 3])
def test_keyboard_interrupt_during_the_commit_changes_nothing(files, monkeypatch, target, call):
    folder, data, old = files
    (folder / "g.yaml").write_text("previous: 1\n")
    (folder / "r.json").write_text("{}\n")
    real = getattr(os, target)
    count = {"n": 0}

    def interrupted(*args, **kwargs):
        count["n"] += 1
        if count["n"] == call:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    before = snapshot(folder)
    monkeypatch.setattr(outputs_module.os, target, interrupted)
    with pytest.raises(KeyboardInterrupt):
        _three_outputs(folder, data, old)
    monkeypatch.undo()
    assert snapshot(folder) == before  # rolled back; staged files and backups removed


def test_a_real_signal_during_the_renames_is_held_until_they_are_done(files, monkeypatch):
    folder, data, old = files
    real = os.replace
    sent = {"done": False}

    def replace_and_signal(*args, **kwargs):
        if not sent["done"]:
            sent["done"] = True
            # to this (the main) thread: a process-wide signal may land on another thread of the
            # test process (the browser tests' driver), which does not hold it
            signal.pthread_kill(threading.get_ident(), signal.SIGINT)  # held: after the last rename
        return real(*args, **kwargs)

    monkeypatch.setattr(outputs_module.os, "replace", replace_and_signal)
    # Python's own SIGINT handler, whatever an earlier test (a worker pool, a command's
    # handlers) left installed: the premise of the test is that SIGINT raises KeyboardInterrupt
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            _three_outputs(folder, data, old)
    finally:
        signal.signal(signal.SIGINT, previous)
    monkeypatch.undo()
    names = sorted(p.name for p in folder.iterdir())
    assert names == ["g.yaml", "measured.csv", "old.csv", "r.json"]  # all new, nothing left
    assert old.read_text().startswith("x,y,z")


# -- inputs: special files, limits ---------------------------------------------------------


@pytest.mark.parametrize(
    "reader",
    [
        read_table,
        lambda p: read_poses(p, "XYZ"),
        lambda p: read_measurements(p, "XYZ"),
        read_legs,
        load_geometry,
        lambda p: read_matrix(p, (6, 6)),
        lambda p: list(iter_tables(p)),
    ],
)
def test_a_fifo_or_device_is_refused_at_once(tmp_path, reader):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    for path, word in ((fifo, "FIFO"), (Path("/dev/zero"), "device")):
        start = time.monotonic()
        with no_hang(), pytest.raises(InputError) as info:
            reader(path)
        assert word in one_line(info) and str(path) in str(info.value)
        assert time.monotonic() - start < 1


def test_a_csv_field_over_the_csv_limit_is_one_line(tmp_path):
    path = tmp_path / "big.csv"
    path.write_text(f'id,{POSES}\n"{"x" * 200_000}",{ROW}\n', encoding="utf-8")
    with pytest.raises(InputError) as info:
        read_poses(path, "XYZ")
    assert "line 2" in one_line(info) and "field" in str(info.value)


def test_comment_lines_after_the_header_are_skipped(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text(f"id,{POSES}\np1,{ROW}\n#p2,{ROW}\n  # note\np3,{ROW}\n", encoding="utf-8")
    poses, ids = read_poses(path, "XYZ")
    assert ids == ("p1", "p3") and len(poses) == 2
    assert read_table(path).lines == (2, 5)


def test_an_id_starting_with_a_hash_is_refused(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text(f"{POSES},id\n{ROW},#2\n", encoding="utf-8")
    with pytest.raises(InputError) as info:
        read_poses(path, "XYZ")
    assert "line 2" in one_line(info) and "'#2'" in str(info.value)


def test_a_double_bom_keeps_the_id_column(tmp_path):
    path = tmp_path / "p.csv"
    path.write_bytes(("\ufeff\ufeff" + f"id,{POSES}\np1,{ROW}\n").encode("utf-8"))
    with pytest.warns(InputWarning, match="byte order mark"):
        _, ids = read_poses(path, "XYZ")
    assert ids == ("p1",)


def test_a_bom_inside_the_header_is_refused(tmp_path):
    path = tmp_path / "p.csv"
    path.write_bytes(f"x,\ufeffy,z,a,b,c\n{ROW}\n".encode())
    with pytest.raises(InputError) as info:
        read_poses(path, "XYZ")
    assert "U+FEFF" in one_line(info)


def test_the_row_limit_names_itself_and_the_option(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text(POSES + "\n" + f"{ROW}\n" * 11, encoding="utf-8")
    with pytest.raises(InputError) as info:
        read_poses(path, "XYZ", max_rows=10)
    assert "10 data rows" in one_line(info) and "--max-rows" in str(info.value)
    assert len(read_poses(path, "XYZ", max_rows=11)[1]) == 11
    assert DEFAULT_MAX_ROWS == 1_000_000


# -- inputs: reading in blocks ---------------------------------------------------------------


@pytest.mark.parametrize("ending", ["\n", "\r\n", "\r"])
def test_blocks_equal_the_whole_table_across_chunk_boundaries(tmp_path, monkeypatch, ending):
    monkeypatch.setattr(table_reading_module, "_CHUNK_BYTES", 7)  # cut lines, and \r\n, everywhere
    rng = np.random.default_rng(3)
    poses = rng.uniform(-1, 1, (23, 6))
    lines = ["# c", f"id,{POSES}"] + [
        f"q{k}," + ",".join(repr(float(v)) for v in p) for k, p in enumerate(poses)
    ]
    lines.insert(7, "")
    path = tmp_path / "p.csv"
    path.write_bytes(ending.join(lines).encode() + ending.encode())
    whole, ids = read_poses(path, "XYZ")
    assert_array_equal(whole, poses)
    blocks = list(iter_poses(path, "XYZ", block_rows=5))
    assert [len(b[1]) for b in blocks] == [5, 5, 5, 5, 3]
    assert_array_equal(np.concatenate([b[0] for b in blocks]), poses)
    assert sum((b[1] for b in blocks), ()) == ids


def test_blocks_find_repeated_ids_and_errors_by_physical_line(tmp_path):
    path = tmp_path / "l.csv"
    cols = ",".join(f"l{i}" for i in range(1, 7))
    rows = [f"r{k},800,800,800,800,800,800" for k in range(9)] + ["r2,800,800,800,800,800,800"]
    path.write_text(f"id,{cols}\n" + "\n".join(rows) + "\n", encoding="utf-8")
    with pytest.raises(InputError) as info:
        list(iter_legs(path, block_rows=4))
    assert "line 11" in one_line(info) and "repeats line 4" in str(info.value)
    path.write_text(f"{cols}\n" + "800,800,800,800,800,800\n" * 6 + "800,800,x,800,800,800\n")
    with pytest.raises(InputError) as info:
        list(iter_legs(path, block_rows=4))
    assert "line 8, column 'l3'" in one_line(info)
    path.write_text(f"{cols}\n" + "800,800,800,800,800,800\n" * 6)
    assert [b.ids for b in iter_legs(path, block_rows=4)] == [("1", "2", "3", "4"), ("5", "6")]


def test_write_table_blocks_streams_and_refuses_no_rows(tmp_path):
    def blocks():
        for k in range(3):
            yield np.full((2, 2), float(k)), [f"{k}a", f"{k}b"]

    assert write_table_blocks(tmp_path / "t.csv", ["u", "v"], blocks()) == 6
    table = read_table(tmp_path / "t.csv")
    assert table.ids() == ("0a", "0b", "1a", "1b", "2a", "2b")
    with pytest.raises(OutputError) as info:
        write_table_blocks(tmp_path / "e.csv", ["u"], iter([]))
    assert "no rows" in one_line(info)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]


# -- tables hexcal could not read back ----------------------------------------------------------


@pytest.mark.parametrize("value", [np.inf, -np.inf, np.nan])
def test_write_table_refuses_non_finite_numbers(tmp_path, value):
    data = np.ones((3, 2))
    data[1, 1] = value
    with pytest.raises(OutputError) as info:
        write_table(tmp_path / "t.csv", ["u", "v"], data, ids=["a", "b", "c"])
    assert "'b'" in one_line(info) and "column 'v'" in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_header_only_table_is_refused(tmp_path):
    with pytest.raises(OutputError):
        write_legs(tmp_path / "legs.csv", np.zeros((0, 6)), np.zeros((0, 6)), ids=[])
    assert list(tmp_path.iterdir()) == []


def test_write_json_refuses_nan_naming_the_key(tmp_path):
    with pytest.raises(OutputError) as info:
        write_json(tmp_path / "r.json", {"bound": {"mean": 0.1, "rms": float("nan")}})
    assert "bound.rms" in one_line(info)
    assert list(tmp_path.iterdir()) == []


# -- YAML and geometry values -------------------------------------------------------------------


def _geometry_dict() -> dict:
    return preset("paper-hmt").to_dict()


def _bomb(levels: int = 9) -> str:
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for k in range(1, levels):
        refs = ", ".join([f"*a{k - 1}"] * 9)
        lines.append(f"a{k}: &a{k} [{refs}]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("key", ["units", "name", "base_joints"])
def test_a_yaml_alias_bomb_fails_fast(tmp_path, key):
    text = yaml.safe_dump({k: v for k, v in _geometry_dict().items() if k != key}, sort_keys=False)
    path = tmp_path / "bomb.yaml"
    path.write_text(_bomb() + text + f"{key}: *a8\n", encoding="utf-8")
    start = time.monotonic()
    with pytest.raises(InputError) as info:
        load_geometry(path)
    assert time.monotonic() - start < 1
    assert "alias" in one_line(info) and str(path) in str(info.value)


def test_yaml_aliases_within_limits_still_load(tmp_path):
    data = _geometry_dict()
    text = yaml.safe_dump(data, sort_keys=False).replace("leg_gains:", "leg_gains: &gains")
    path = tmp_path / "g.yaml"
    path.write_text(text, encoding="utf-8")
    assert_array_equal(load_geometry(path).leg_gains, np.ones(6))


def test_deeply_nested_yaml_is_one_line(tmp_path):
    path = tmp_path / "deep.yaml"
    path.write_text("units: mm\nname: " + "[" * 500 + "]" * 500 + "\n", encoding="utf-8")
    with pytest.raises(InputError) as info:
        load_geometry(path)
    assert "nested" in one_line(info)


@pytest.mark.parametrize(
    "text", ["1: a\nunits: mm\n", "units: mm\nhome_pose: {x: 0, 1: 2}\n", "units: mm\n2: [1]\nb: 3\n"]
)
def test_integer_keys_beside_string_keys(tmp_path, text):
    path = tmp_path / "g.yaml"
    data = _geometry_dict()
    data.pop("home_pose") if "home_pose" in text else None
    path.write_text(yaml.safe_dump({k: v for k, v in data.items() if k != "units"}) + text, encoding="utf-8")
    with pytest.raises(InputError) as info:
        load_geometry(path)
    one_line(info)


def test_yaml_integer_over_python_digit_limit(tmp_path):
    path = tmp_path / "g.yaml"
    path.write_text("units: mm\nname: " + "9" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(InputError):
        load_geometry(path)


def _with(change) -> dict:
    data = _geometry_dict()
    change(data)
    return data


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (lambda d: d.__setitem__("leg_gains", [1, 1, 0, 1, 1, 1]), "g3 = 0"),
        (lambda d: d.__setitem__("leg_gains", [1, 1, 1, 1, 1, -1]), "g6 = -1"),
        (lambda d: d.__setitem__("initial_leg_lengths", [0] * 6), "l0_1 = 0"),
        (lambda d: d.__setitem__("initial_leg_lengths", [600, 600, -5, 600, 600, 600]), "l0_3 = -5"),
        (lambda d: d.__setitem__("leg_length_limits", [-10, 1100]), "0 < min < max"),
        (lambda d: d.__setitem__("leg_length_limits", [1100, 600]), "0 < min < max"),
        (lambda d: d["base_joints"].__setitem__(4, d["base_joints"][1]), "u2 and u5 coincide"),
        (lambda d: d["platform_joints"].__setitem__(0, d["platform_joints"][5]), "s1 and s6 coincide"),
        (lambda d: d["home_pose"].__setitem__("z", 1000), "outside the workspace"),
        (lambda d: d["home_pose"].__setitem__("z", 1e9) or d.pop("workspace"), "outside leg_length_limits"),
        (lambda d: d.__setitem__("leg_gains", [float("inf")] * 6), "NaN or inf"),
        (lambda d: d.__setitem__("euler", 5), "euler"),
        (lambda d: d.__setitem__("name", [1, 2]), "name must be text"),
        (lambda d: d["home_pose"].__setitem__("x", 10**400), "must be a number"),
    ],
)
def test_implausible_geometry_values_are_refused(tmp_path, change, expected):
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump(_with(change), sort_keys=False), encoding="utf-8")
    before = path.read_bytes()
    with pytest.raises(InputError) as info:
        load_geometry(path)
    assert expected in one_line(info) and str(path) in str(info.value)
    assert path.read_bytes() == before


def test_every_error_here_is_a_hexcal_error():
    assert issubclass(OutputError, HexcalError) and issubclass(OutputError, OSError)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert str(OutputError("x: y")) == "x: y"
