"""Covariate columns (issue 30 item 1, issue 28's ``time``): read, checked, carried and written.

``time`` (s, increasing), ``temp1 ... temp6`` or ``temp`` (°C), ``payload_kg`` and
``payload_x, payload_y, payload_z`` (docs/formats.md "Covariates") are read from the data file
of every instrument and from pose and leg files, with their values and shapes; carried by the
data through subsets and copies; written back by every writer so that a file round-trips;
passed from a pose file through ``synthesize``, ``ik``, ``fk`` and ``compensate``; and every
value or set of columns the contract refuses is one line through the command line, with
nothing written.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

import hexcal
from hexcal.cli import main
from hexcal.errors import InputError, UsageError
from hexcal.instruments import COVARIATE_COLUMNS, Covariates, TargetModel
from hexcal.io import iter_legs, iter_poses, read_legs, read_session, write_legs, write_session_data

M = 12
#: The covariates of the test poses: a warm-up (leg 3 warmer), a payload, a clock (values with
#: few digits, so that files written with 15 significant digits give them back exactly).
TIME = np.arange(M) * 37.5 + 100.0
TEMPS = 20.0 + 0.25 * np.arange(M)[:, None] + np.array([0, 0, 1.5, 0, 0, 0])
ONE_TEMP = 20.0 + 0.25 * np.arange(M)
PAYLOAD = np.full(M, 12.5)
COM = np.tile([1.0, -2.0, 55.0], (M, 1))

#: Each covariate alone (and the centre of mass, which needs the mass), and all of them.
SETS = {
    "time": Covariates(time=TIME),
    "temp": Covariates(temperatures=ONE_TEMP),
    "temp1-6": Covariates(temperatures=TEMPS),
    "payload_kg": Covariates(payload_kg=PAYLOAD),
    "payload_com": Covariates(payload_kg=PAYLOAD, payload_com=COM),
    "all": Covariates(time=TIME, temperatures=TEMPS, payload_kg=PAYLOAD, payload_com=COM),
}

SETUPS = {
    "pose": None,
    "tool": "units: mm\ninstrument_frame: {x: 2500, y: -800, z: 300, a_deg: 0, b_deg: 0, c_deg: 35}\n"
    "tool: {x: 0, y: 0, z: 60, a: 0, b: 0, c: 0}\n",
    "targets": "units: mm\ninstrument_frame: {x: 2500, y: -800, z: 300, a_deg: 0, b_deg: 0, c_deg: 35}\n"
    "targets:\n  t1: [0, 0, 60]\n  t2: [120, 0, 60]\n  t3: [0, 120, 60]\n",
    "ballbar": "units: mm\nballbar: {pivot: [0, 0, 600], ball: [0, 0, 0], length: 150.0}\n",
}


def run(capsys, *argv) -> tuple[int, str, str]:
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = int(exc.code)
    out, err = capsys.readouterr()
    return status, out, err


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hexcal: error: ") and "Traceback" not in err, err
    return lines[0]


def same(a: Covariates, b: Covariates) -> None:
    """The same covariates: the same quantities and values (and ``temp`` kept as one)."""
    assert a.names() == b.names() and a.one_temperature == b.one_temperature
    for name in a.names():
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


@pytest.fixture(scope="module")
def poses() -> tuple[np.ndarray, tuple[str, ...]]:
    nominal = hexcal.preset("paper-hmt")
    corners = hexcal.workspace_corners(nominal)
    return corners[:: len(corners) // M][:M], tuple(f"p{k:02d}" for k in range(M))


def _setup(tmp_path: Path, kind: str) -> Path | None:
    if SETUPS[kind] is None:
        return None
    path = tmp_path / f"{kind}.yaml"
    path.write_text(SETUPS[kind], encoding="utf-8")
    return path


def _session(tmp_path: Path, kind: str, poses, covariates: Covariates) -> hexcal.Session:
    nominal, true = hexcal.preset("paper-hmt"), hexcal.preset("paper-hmt-true")
    instrument = hexcal.io.load_instrument(_setup(tmp_path, kind), nominal.euler)
    return hexcal.simulate_session(nominal, true, instrument, poses[0], None, 0, poses[1], covariates)


# -- the value type --------------------------------------------------------------------------


def test_the_covariates_hold_what_they_are_given():
    cov = SETS["all"]
    assert cov.names() == ("time", "temperatures", "payload_kg", "payload_com") and len(cov) == M
    assert cov.temperatures.shape == (M, 6) and cov.payload_com.shape == (M, 3) and cov.time.shape == (M,)
    assert list(cov.to_columns()) == [c for c in COVARIATE_COLUMNS if c != "temp"]
    one = SETS["temp"]
    assert one.one_temperature and one.temperatures.shape == (M, 6)
    np.testing.assert_array_equal(one.temperatures, np.repeat(ONE_TEMP[:, None], 6, axis=1))
    assert list(one.to_columns()) == ["temp"]
    assert not Covariates() and len(Covariates()) == 0 and Covariates().names() == ()
    same(Covariates.from_columns(cov.to_columns()), cov)
    with pytest.raises(ValueError):
        cov.time[0] = 1.0  # read-only, like the data's arrays


def test_a_subset_keeps_the_covariates_of_its_rows_in_any_order():
    cov = SETS["all"]
    part = cov.subset([5, 1])  # a fold drawn at random: time no longer increases, still the same rows
    np.testing.assert_array_equal(part.time, TIME[[5, 1]])
    np.testing.assert_array_equal(part.temperatures, TEMPS[[5, 1]])
    assert SETS["temp"].subset(np.arange(M) > 6).one_temperature
    assert Covariates().subset([0]).names() == ()


@pytest.mark.parametrize(
    ("fields", "says"),
    [
        ({"time": [0.0, 1.0, 1.0]}, "row 3, time: 1 s is not after the row before's 1 s"),
        ({"temperatures": [20.0, 300.0]}, "row 2, temp: 300 °C is outside the plausible -60 ... 200 °C"),
        ({"payload_kg": [-1.0]}, "row 1, payload_kg: -1 kg: a payload's mass cannot be negative"),
        ({"payload_com": [[0.0, 0, 0]]}, "a payload centre of mass needs the payload's mass"),
        ({"time": [0.0, 1.0], "payload_kg": [1.0]}, "different numbers of rows [1, 2]"),
        ({"temperatures": np.zeros((2, 5))}, "temperatures must have shape (m, 6)"),
        ({"time": [0.0, np.nan]}, "row 2, time: nan is not a finite number"),
    ],
)
def test_covariates_built_in_python_are_checked_alike(fields, says):
    with pytest.raises(UsageError, match=None) as info:
        Covariates(**fields)
    assert says in str(info.value) and "\n" not in str(info.value)


def test_require_names_what_the_data_lack_in_one_line():
    SETS["all"].require(["temperatures", "payload_kg"], "a.csv: the thermal leg model")  # present
    with pytest.raises(InputError) as info:
        SETS["time"].require(["temperatures", "payload_kg"], "a.csv: the thermal leg model")
    assert str(info.value) == (
        "a.csv: the thermal leg model needs the legs' temperatures (columns temp1 ... temp6, or temp, °C) "
        "and the payload's mass (column payload_kg), which the data do not have"
    )
    with pytest.raises(UsageError, match="unknown covariate"):
        Covariates().require(["temperature"], "x")


def test_every_data_class_carries_them_through_subsets_and_copies(tmp_path, poses):
    for kind in SETUPS:
        session = _session(tmp_path, kind, poses, SETS["all"])
        data, instrument = session.data, session.instrument
        same(instrument.covariates(data), SETS["all"].subset([poses[1].index(i) for i in data.ids]))
        part = session.subset(np.array([4, 2, 7]))
        same(part.instrument.covariates(part.data), instrument.covariates(data).subset([4, 2, 7]))
        same(data.replace(readings=data.readings + 1.0).covariates, data.covariates)
        for _, _, variant in instrument.variants(data):  # re-readings in other units
            same(variant.covariates, data.covariates)
        fewer = instrument.without_values(data, 3, np.arange(instrument.size))
        same(fewer.covariates, data.covariates.subset(np.delete(np.arange(len(data)), 3)))
    plain = hexcal.Measurements(np.zeros((2, 6)), np.zeros((2, 6)))
    assert plain.covariates.names() == () and plain.subset([1]).covariates.names() == ()
    with pytest.raises(UsageError, match="covariates of 12 rows for 2 poses"):
        plain.replace(covariates=SETS["time"])


def test_a_target_left_out_keeps_the_pose_and_its_covariates(tmp_path, poses):
    session = _session(tmp_path, "targets", poses, SETS["all"])
    assert isinstance(session.instrument, TargetModel)
    fewer = session.instrument.without_values(session.data, 3, np.arange(3))  # one target of pose 3
    assert len(fewer) == len(session.data)
    same(fewer.covariates, session.data.covariates)


# -- files of every instrument: read, and written back ---------------------------------------


@pytest.mark.parametrize("kind", sorted(SETUPS))
@pytest.mark.parametrize("name", sorted(SETS))
def test_each_instrument_file_round_trips_each_covariate(tmp_path, poses, kind, name):
    """Written by the session writer, read back by the session reader: the same values, shapes,
    and column names (``temp`` stays ``temp``)."""
    session = _session(tmp_path, kind, poses, SETS[name])
    path = tmp_path / "data.csv"
    write_session_data(path, session, "XYZ", comment="test")
    header = next(line for line in path.read_text(encoding="utf-8").splitlines() if not line.startswith("#"))
    assert header.endswith(",".join(SETS[name].to_columns()))
    back = read_session(path, _setup(tmp_path, kind), "XYZ")
    same(back.instrument.covariates(back.data), SETS[name])
    if name == "all":
        assert back.data.covariates.temperatures.shape == (M, 6)
        assert back.data.covariates.payload_com.shape == (M, 3)


def test_pose_and_leg_files_round_trip_and_say_so_only_when_asked(tmp_path, poses):
    cov = SETS["all"]
    path = tmp_path / "poses.csv"
    hexcal.write_poses(path, poses[0], poses[1], covariates=cov)
    read, ids = hexcal.read_poses(path, "XYZ")  # today's callers: two values
    again, ids3, back = hexcal.read_poses(path, "XYZ", covariates=True)
    np.testing.assert_allclose(again, poses[0])
    np.testing.assert_array_equal(read, again)
    assert ids == ids3 == poses[1]
    same(back, cov)
    blocks = list(iter_poses(path, "XYZ", block_rows=5, covariates=True))
    assert [len(b[0]) for b in blocks] == [5, 5, 2] and all(len(b) == 3 for b in blocks)
    np.testing.assert_array_equal(np.concatenate([b[2].time for b in blocks]), TIME)
    assert all(len(b) == 2 for b in iter_poses(path, "XYZ", block_rows=5))

    legs = tmp_path / "legs.csv"
    lengths = hexcal.inverse_kinematics(hexcal.preset("paper-hmt"), poses[0])
    write_legs(legs, lengths, lengths - 600.0, poses[1], covariates=SETS["temp"])
    same(read_legs(legs).covariates, SETS["temp"])
    parts = [b.covariates for b in iter_legs(legs, block_rows=5)]
    np.testing.assert_array_equal(np.concatenate([c.temperatures for c in parts]), SETS["temp"].temperatures)
    assert all(c.one_temperature for c in parts)


def test_a_column_map_and_a_unit_row_name_the_covariates(tmp_path, poses):
    cov = SETS["all"]
    path = tmp_path / "poses.csv"
    hexcal.write_poses(path, poses[0], poses[1], covariates=cov)
    rows = list(csv.reader(path.read_text(encoding="utf-8").splitlines()))
    renamed = {"time": "t_s", "temp3": "T3", "payload_kg": "mass"}
    units = {"time": "[s]", "payload_kg": "kg", "payload_x": "mm"} | {f"temp{i}": "°C" for i in range(1, 7)}
    header = [renamed.get(c, c) for c in rows[0]]
    unit_row = [units.get(c, "") for c in rows[0]]
    with (tmp_path / "export.csv").open("w", encoding="utf-8", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows([header, unit_row, *rows[1:]])
    columns = {"time": "t_s", "temp3": "T3", "payload_kg": "mass"}
    _, _, back = hexcal.read_poses(tmp_path / "export.csv", "XYZ", columns=columns, covariates=True)
    same(back, cov)
    unit_row[rows[0].index("temp3")] = "K"
    with (tmp_path / "kelvin.csv").open("w", encoding="utf-8", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows([header, unit_row, *rows[1:]])
    with pytest.raises(InputError, match=r"kelvin\.csv: line 2, column 'T3': unit 'K'; only °C here"):
        hexcal.read_poses(tmp_path / "kelvin.csv", "XYZ", columns=columns)


def test_time_must_increase_across_the_blocks_of_a_long_file(tmp_path, poses):
    time = TIME.copy()
    time[5] = time[4]  # the first row of the second block of 5 rows
    path = tmp_path / "poses.csv"
    hexcal.write_poses(path, poses[0], poses[1], covariates=Covariates(time=np.arange(M)))
    text = path.read_text(encoding="utf-8").splitlines()
    cells = [r.split(",")[:-1] for r in text[1:]]
    lines = [text[0]] + [",".join([*c, f"{t:g}"]) for c, t in zip(cells, time, strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(InputError) as info:
        list(iter_poses(path, "XYZ", block_rows=5))
    assert str(info.value) == (
        f"{path}: line 7, column 'time': 250 s is not after the row before's 250 s: rows are in "
        "acquisition order, time increasing"
    )


# -- refusals, each one line through the command line ----------------------------------------


@pytest.fixture(scope="module")
def measured(tmp_path_factory, poses) -> Path:
    """A measurement file of the full pose with every covariate (``temp1..6`` as ``temp3``...)."""
    folder = tmp_path_factory.mktemp("measured")
    session = _session(folder, "pose", poses, SETS["all"])
    path = folder / "measured.csv"
    write_session_data(path, session, "XYZ")
    return path


def _spoiled(tmp_path: Path, source: Path, changes: dict[str, tuple[int, str]], drop=(), add=None) -> Path:
    """``source`` with cells changed (column -> (data row, text), or a list of them), columns
    dropped or one added (its cells 1)."""
    rows = list(csv.reader(source.read_text(encoding="utf-8").splitlines()))
    header = rows[0]
    for column, change in changes.items():
        for row, text in change if isinstance(change, list) else [change]:
            rows[1 + row][header.index(column)] = text
    keep = [k for k, c in enumerate(header) if c not in drop]
    rows = [[r[k] for k in keep] for r in rows]
    if add:
        rows = [[*r, add if k == 0 else "1"] for k, r in enumerate(rows)]
    path = tmp_path / "bad.csv"
    with path.open("w", encoding="utf-8", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows(rows)
    return path


REFUSALS = {
    "empty cell": ({"temp2": (3, "")}, (), None, "line 5, column 'temp2': not a number: ''"),
    "nan": ({"payload_kg": (0, "nan")}, (), None, "line 2, column 'payload_kg': nan is not a finite number"),
    "inf": ({"time": (2, "inf")}, (), None, "line 4, column 'time': inf is not a finite number"),
    "text": ({"payload_y": (1, "high")}, (), None, "line 3, column 'payload_y': not a number: 'high'"),
    "kelvin": (
        {"temp4": (6, "296.15")},
        (),
        None,
        "line 8, column 'temp4': 296.15 °C is outside the plausible -60 ... 200 °C; it looks like kelvin "
        "(23 °C): give degrees Celsius",
    ),
    "too cold": ({"temp1": (0, "-80")}, (), None, "-80 °C is outside the plausible -60 ... 200 °C"),
    "negative mass": ({"payload_kg": (2, "-3")}, (), None, "-3 kg: a payload's mass cannot be negative"),
    "absurd mass": ({"payload_kg": (2, "2e5")}, (), None, "200000 kg is beyond 100,000 kg"),
    "time back": (
        {"time": (4, "10")},
        (),
        None,
        "line 6, column 'time': 10 s is not after the row before's 212.5 s: rows are in acquisition order, "
        "time increasing",
    ),
    "time still": ({"time": (3, "175")}, (), None, "line 5, column 'time': 175 s is not after the row"),
    "temp and temp1": ({}, (), "temp", "columns 'temp' and 'temp1' both give leg temperatures"),
    "five temperatures": ({}, ("temp6",), None, "temp2, temp3, temp4, temp5 without temp6: give all six"),
    "part of the centre": ({}, ("payload_z",), None, "payload_x, payload_y and payload_z; payload_z missing"),
    "centre without mass": (
        {},
        ("payload_kg",),
        None,
        "columns payload_x, payload_y, payload_z give the payload's centre of mass, but there is no column "
        "'payload_kg'",
    ),
}


@pytest.mark.parametrize("command", ["identify", "validate"])
@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_a_bad_covariate_is_one_line_and_nothing_is_written(capsys, tmp_path, measured, command, case):
    changes, drop, add, says = REFUSALS[case]
    bad = _spoiled(tmp_path, measured, changes, drop, add)
    outputs = ["--out", tmp_path / "out.yaml"] if command == "identify" else ["--json", tmp_path / "v.json"]
    status, out, err = run(capsys, command, "--geometry", "paper-hmt", "--data", bad, *outputs)
    assert status == 1 and not out
    line = one_line(err)
    assert line.startswith(f"hexcal: error: {bad}: ") and says in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_time_going_back_names_every_row_that_does(tmp_path, measured):
    bad = _spoiled(tmp_path, measured, {"time": [(4, "10"), (8, "20"), (10, "30")]})
    with pytest.raises(InputError) as info:
        hexcal.read_measurements(bad, "XYZ")
    assert str(info.value) == (
        f"{bad}: line 6, column 'time': 10 s is not after the row before's 212.5 s: rows are in acquisition "
        "order, time increasing (and 2 more row(s): line 10, 12)"
    )


@pytest.mark.parametrize("kind", ["tool", "targets", "ballbar"])
def test_every_instrument_reader_refuses_a_bad_covariate(capsys, tmp_path, poses, kind):
    session = _session(tmp_path, kind, poses, SETS["all"])
    good = tmp_path / "good.csv"
    write_session_data(good, session, "XYZ")
    bad = _spoiled(tmp_path, good, {"temp3": (2, "373.15")})
    status, _, err = run(
        capsys, "validate", "--geometry", "paper-hmt", "--data", bad, "--setup", _setup(tmp_path, kind)
    )
    assert status == 1
    assert one_line(err).endswith(
        f"{bad}: line 4, column 'temp3': 373.15 °C is outside the plausible -60 ... 200 °C; it looks like "
        "kelvin (100 °C): give degrees Celsius"
    )


# -- the commands that read pose and leg files ------------------------------------------------


@pytest.fixture
def pose_file(tmp_path, poses) -> Path:
    path = tmp_path / "poses.csv"
    hexcal.write_poses(path, poses[0], poses[1], covariates=SETS["all"])
    return path


def test_ik_fk_and_compensate_carry_the_covariates_of_their_input(capsys, tmp_path, pose_file, poses):
    status, _, err = run(capsys, "ik", "--geometry", "paper-hmt", "--poses", pose_file,
                         "--out", tmp_path / "l.csv")  # fmt: skip
    assert status == 0, err
    legs = read_legs(tmp_path / "l.csv")
    same(legs.covariates, SETS["all"])
    expected = hexcal.inverse_kinematics(hexcal.preset("paper-hmt"), poses[0])
    np.testing.assert_allclose(legs.lengths, expected, atol=1e-9)  # the covariates do not move the legs yet
    status, _, err = run(capsys, "fk", "--geometry", "paper-hmt", "--legs", tmp_path / "l.csv",
                         "--out", tmp_path / "back.csv")  # fmt: skip
    assert status == 0, err
    back, ids, cov = hexcal.read_poses(tmp_path / "back.csv", "XYZ", covariates=True)
    assert ids == poses[1]
    np.testing.assert_allclose(back, poses[0], atol=1e-6)
    same(cov, SETS["all"])
    status, _, err = run(capsys, "compensate", "--geometry", "paper-hmt-true", "--nominal", "paper-hmt",
                         "--poses", pose_file, "--out", tmp_path / "c.csv", "--skip-infeasible",
                         "--corrected-poses", tmp_path / "corrected.csv")  # fmt: skip
    assert status == 0, err
    commands = read_legs(tmp_path / "c.csv")
    kept = SETS["all"].subset([poses[1].index(i) for i in commands.ids])  # the feasible targets
    same(commands.covariates, kept)
    same(hexcal.read_poses(tmp_path / "corrected.csv", "XYZ", covariates=True)[2], kept)


def test_ik_refuses_a_bad_covariate_of_its_pose_file_and_writes_nothing(capsys, tmp_path, pose_file):
    bad = _spoiled(tmp_path, pose_file, {}, add="temp")
    status, _, err = run(capsys, "ik", "--geometry", "paper-hmt", "--poses", bad, "--out", tmp_path / "l.csv")
    assert status == 1 and "columns 'temp' and 'temp1' both give leg temperatures" in one_line(err)
    assert not (tmp_path / "l.csv").exists()


@pytest.mark.parametrize("kind", sorted(SETUPS))
def test_synthesize_passes_the_pose_file_covariates_into_the_data(capsys, tmp_path, pose_file, kind):
    setup = _setup(tmp_path, kind)
    rate = ["--missing-rate", "0.6", "--seed", "3"] if kind == "targets" else []
    status, _, err = run(capsys, "synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true",
                         "--poses", pose_file, "--out", tmp_path / "data.csv",
                         *(["--setup", setup] if setup else []), *rate)  # fmt: skip
    assert status == 0, err
    session = read_session(tmp_path / "data.csv", setup, "XYZ")
    kept = [int(i[1:]) for i in session.ids]
    if kind == "targets":
        assert len(kept) < M  # poses with every target lost are not recorded: the others keep theirs
    same(session.instrument.covariates(session.data), SETS["all"].subset(kept))
