"""The commands with a leg model that reads the conditions (issue 30): ``ik``, ``fk`` and
``compensate`` take the covariate columns or ``--temperature``/``--payload``, say them, and
refuse in one line what they cannot do."""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.core import preset
from hexcal.core.covariate_legs import CovariateLegs
from hexcal.core.stroke_legs import with_leg_model
from hexcal.io import read_legs, read_poses, save_geometry

KT = [0.006, 0.0066, 0.0072, 0.0078, 0.0084, 0.009]


def run(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def files(tmp_path):
    nominal = preset("paper-hmt")
    save_geometry(nominal, tmp_path / "paper.yaml")
    warm = with_leg_model(nominal, CovariateLegs(thermal=True)).replace(leg_terms=np.array(KT)[:, None])
    save_geometry(warm, tmp_path / "warm.yaml")
    load = with_leg_model(nominal, CovariateLegs(thermal=True, compliance=True, platform_mass=30.0))
    save_geometry(load.replace(leg_terms=np.column_stack([KT, np.full(6, 3e-5)])), tmp_path / "load.yaml")
    (tmp_path / "poses.csv").write_text(
        "id,x,y,z,a_deg,b_deg,c_deg\nmid,0,0,800,0,0,0\ncorner,100,50,760,3,0,2\n"
    )
    (tmp_path / "p.ngc").write_text("G21 G90\nG1 X10 Y0 Z800 A0 B0 C0 F100\nG1 X20 Y5 Z800\nM2\n")
    return tmp_path


def test_ik_fk_round_trip_at_a_temperature(capsys, files):
    status, out, _ = run(capsys, "ik", "--geometry", files / "warm.yaml", "--poses", files / "poses.csv",
                         "--out", files / "legs.csv", "--temperature", 30)  # fmt: skip
    assert status == 0 and "thermal legs: legs at 30 °C" in out
    legs = read_legs(files / "legs.csv")
    np.testing.assert_array_equal(legs.covariates.temperatures, 30.0)
    # at 30 °C each leg is kt * 10 K longer than its reading says at 20 °C: the reading is shorter
    status, _, _ = run(capsys, "ik", "--geometry", files / "paper.yaml", "--poses", files / "poses.csv",
                       "--out", files / "plain.csv")  # fmt: skip
    np.testing.assert_allclose(
        read_legs(files / "plain.csv").readings - legs.readings,
        np.tile(np.multiply(KT, 10), (2, 1)),
        atol=1e-9,
    )
    status, out, _ = run(capsys, "fk", "--geometry", files / "warm.yaml", "--legs", files / "legs.csv",
                         "--out", files / "back.csv")  # fmt: skip
    assert status == 0 and "legs at 30 °C" in out
    poses, _ = read_poses(files / "back.csv", "xyz")
    np.testing.assert_allclose(poses[1, :3], [100, 50, 760], atol=1e-9)


def test_compliance_ik_fk_within_first_order(capsys, files):
    status, out, _ = run(capsys, "ik", "--geometry", files / "load.yaml", "--poses", files / "poses.csv",
                         "--out", files / "legs.csv", "--temperature", 25,
                         "--payload", "80,0,0,50")  # fmt: skip
    assert status == 0 and "payload 80 kg at (0, 0, 50) mm" in out
    status, _, _ = run(capsys, "fk", "--geometry", files / "load.yaml", "--legs", files / "legs.csv",
                       "--out", files / "back.csv")  # fmt: skip
    poses, _ = read_poses(files / "back.csv", "xyz")
    # the forces taken at the pose found without them, then again: within 1e-4 mm of the target
    np.testing.assert_allclose(poses[:, :3], [[0, 0, 800], [100, 50, 760]], atol=1e-4)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (("ik", "--poses", "poses.csv"), "the thermal leg model needs the legs' temperatures"),
        (("compensate", "--poses", "poses.csv"), "the thermal leg model needs the legs' temperatures"),
        (("compensate", "--gcode", "p.ngc", "--nominal", "paper.yaml", "--start", "0,0,800,0,0,0"),
         "the thermal leg model needs the legs' temperatures"),
        (("ik", "--poses", "legs_warm.csv", "--temperature", "21"), "carries the legs' temperatures"),
    ],
)  # fmt: skip
def test_one_line_refusals(capsys, files, argv, message):
    (files / "legs_warm.csv").write_text("id,x,y,z,a,b,c,temp\nmid,0,0,800,0,0,0,21\n")
    argv = [files / a if a.endswith((".csv", ".ngc", ".yaml")) else a for a in argv]
    status, _, err = run(
        capsys, *argv[:1], "--geometry", files / "warm.yaml", *argv[1:], "--out", files / "o.out"
    )
    assert status == 1 and message in err and len(err.strip().splitlines()) == 1
    assert not (files / "o.out").exists()


def test_gcode_states_its_temperature_and_refuses_forces(capsys, files):
    base = ("compensate", "--gcode", files / "p.ngc", "--nominal", files / "paper.yaml", "--quiet",
            "--start", "0,0,800,0,0,0", "--out", files / "out.ngc")  # fmt: skip
    status, _, _ = run(capsys, *base, "--geometry", files / "warm.yaml", "--temperature", 30)
    assert status == 0
    assert "(made for: legs at 30 C)" in (files / "out.ngc").read_text().splitlines()
    status, _, err = run(
        capsys, *base, "--geometry", files / "load.yaml", "--temperature", 30, "--payload", 5
    )
    assert status == 1 and "axial forces change along the path" in err


def test_synthesize_takes_one_temperature_and_states_it(capsys, files):
    """``synthesize --temperature``: the true thermal machine's legs at 30 °C (each leg's
    reading kt · 10 K shorter than on the cold machine, poses the same), the file's ``temp``
    column and its comment say so; a file with the column refuses the option in one line."""
    argv = ("synthesize", "--nominal", files / "paper.yaml", "--poses", files / "poses.csv",
            "--noise", "leg=0,pos=0,ang=0")  # fmt: skip
    status, out, _ = run(
        capsys, *argv, "--true", files / "warm.yaml", "--temperature", 30, "--out", files / "w.csv"
    )
    assert status == 0 and "(legs at 30 °C)" in out
    assert "legs at 30 °C" in (files / "w.csv").read_text().splitlines()[0]
    warm = read_legs(files / "w.csv")
    np.testing.assert_array_equal(warm.covariates.temperatures, 30.0)
    status, _, _ = run(capsys, *argv, "--true", files / "paper.yaml", "--out", files / "c.csv")
    # the same commanded readings; the warm legs kt * 10 K longer: the poses they reach have
    # those lengths on the nominal geometry
    from hexcal.core.kinematics import inverse_kinematics
    from hexcal.io import read_measurements

    nominal = preset("paper-hmt")
    reached = [read_measurements(files / f, nominal.euler).poses for f in ("w.csv", "c.csv")]
    grown = inverse_kinematics(nominal, reached[0]) - inverse_kinematics(nominal, reached[1])
    np.testing.assert_allclose(grown, np.tile(KT, (2, 1)) * 10, atol=1e-7)
    (files / "t.csv").write_text("id,x,y,z,a,b,c,temp\nmid,0,0,800,0,0,0,21\n")
    status, _, err = run(
        capsys, *argv[:-2], "--true", files / "warm.yaml", "--poses", files / "t.csv", "--temperature", 30,
        "--out", files / "o.csv",
    )  # fmt: skip
    assert status == 1 and "carries the legs' temperatures" in err and len(err.strip().splitlines()) == 1
    assert not (files / "o.csv").exists()


def test_validate_takes_one_temperature_and_states_it(capsys, files):
    """``validate --temperature``: held-out poses measured at 30 °C in a file without a
    temperature column validate a thermal machine exactly (noise-free: errors at rounding) and
    the output says the conditions; without the option the one line names what is missing; a
    file with the column refuses the option; Python's ``hexcal.validate`` records them alike."""
    argv = ("synthesize", "--nominal", files / "paper.yaml", "--true", files / "warm.yaml",
            "--poses", files / "poses.csv", "--noise", "leg=0,pos=0,ang=0", "--temperature", 30)  # fmt: skip
    assert run(capsys, *argv, "--out", files / "w.csv")[0] == 0
    lines = (files / "w.csv").read_text().splitlines()
    header = lines[1].split(",")
    keep = [k for k, name in enumerate(header) if name != "temp"]
    stripped = [",".join(row.split(",")[k] for k in keep) for row in lines[1:]]
    (files / "bare.csv").write_text("\n".join(stripped) + "\n")
    status, out, _ = run(capsys, "validate", "--geometry", files / "warm.yaml", "--data", files / "bare.csv",
                         "--temperature", 30)  # fmt: skip
    assert status == 0 and "conditions of every pose (--temperature, --payload): legs at 30 °C" in out
    rms = float(next(line for line in out.splitlines() if "position error RMS" in line).split()[-1])
    assert rms < 1e-6  # the true machine at the temperature it was measured at
    status, _, err = run(capsys, "validate", "--geometry", files / "warm.yaml", "--data", files / "bare.csv")
    assert status == 1 and "needs the legs' temperatures" in err and len(err.strip().splitlines()) == 1
    status, _, err = run(capsys, "validate", "--geometry", files / "warm.yaml", "--data", files / "w.csv",
                         "--temperature", 30)  # fmt: skip
    assert status == 1 and "carries the legs' temperatures" in err
    import hexcal

    geometry = hexcal.load_geometry(files / "warm.yaml")
    session = hexcal.read_session(files / "bare.csv", None, geometry.euler)
    result = hexcal.validate(geometry, session, temperature=30.0)
    assert result.inputs["conditions"] == "legs at 30 °C"
    assert result.to_dict()["position_rms_mm"] < 1e-6
