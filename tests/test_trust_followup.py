"""Issue 22 follow-ups, through the command line, for every instrument where it applies.

- absolute strut lengths (a controller's joint positions, LinuxCNC's genhexkins joints) given as
  readings ``dl``: ``identify`` ends in one line that names the file and says the readings look
  absolute (the fit re-read as ``dl - l0`` fits), nothing written; ``fk`` says the same of rows
  outside the leg limits whose ``dl`` are themselves within them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from instrument_campaigns import INSTRUMENTS, Campaigns, identify, run


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory: pytest.TempPathFactory) -> Campaigns:
    return Campaigns(tmp_path_factory.mktemp("followup"))


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("hexcal: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("kind", list(INSTRUMENTS))
def test_absolute_readings_are_named_for_every_instrument(kind, campaigns):
    data = campaigns.data(kind, "absolute")
    done, files = identify(campaigns, kind, data, f"{kind}-absolute")
    assert done.code == 1
    line = _one_line(done.err)
    assert "absolute strut lengths" in line and data.name in line and "HOME_OFFSET" in line
    assert not any(path.exists() for path in files.values())


def test_fk_says_readings_look_absolute(campaigns, tmp_path: Path):
    data = campaigns.data("pose", "absolute")
    done = run("fk", "--geometry", "paper-hmt", "--legs", data, "--out", tmp_path / "f.csv")
    assert done.code == 1 and "absolute strut lengths" in _one_line(done.err)
    assert not (tmp_path / "f.csv").exists()


def _covariance(path: Path, position: float, angle: float) -> Path:
    import numpy as np

    np.savetxt(path, np.diag([position] * 3 + [angle] * 3))
    return path


@pytest.mark.parametrize("command", ["identify", "simulate"])
def test_a_pose_covariance_is_refused_for_targets(command, campaigns, tmp_path: Path):
    cov = _covariance(tmp_path / "cov.txt", 1e-4, 1e-8)
    if command == "identify":
        data = campaigns.data("targets")
        done, files = identify(campaigns, "targets", data, "cov", "--pose-covariance", cov)
        written = [p for p in files.values() if p.exists()]
    else:
        out = tmp_path / "sim"
        done = run("simulate", "--geometry", "paper-hmt", *campaigns.setup("targets", "true"),
                   "--pose-covariance", cov, "--trials", 2, "--poses", 20, "--out", out)  # fmt: skip
        written = [out] if out.exists() else []
    assert done.code != 0 and not written
    line = _one_line(done.err)
    assert "--pose-covariance" in line and "no pose is measured" in line and "--noise pos=" in line


@pytest.mark.slow  # fast representative: test_likelihood.py::test_full_pose_covariance_is_used
def test_a_pose_covariance_acts_for_a_tool(campaigns, tmp_path: Path):
    import json

    results = []
    for k, (position, angle) in enumerate([(2.25e-4, 4e-8), (1.0, 4e-8)]):
        cov = _covariance(tmp_path / f"cov{k}.txt", position, angle)
        done, files = identify(campaigns, "tool", campaigns.data("tool"), f"cov{k}", "--pose-covariance", cov,
                               "--force")  # fmt: skip
        assert done.code == 0, done.err
        data = json.loads(files["json"].read_text())
        assert data["noise"]["given"]["pose_covariance"][0][0] == position
        results.append(data["bound"]["u1.x"])
    # a position σ of 1 mm instead of 0.015 mm: the bound of a joint coordinate grows many times
    assert results[1] > 5 * results[0]


@pytest.mark.parametrize("kind", ["pose", "targets"])
def test_a_reading_that_makes_a_leg_negative_is_named(kind, campaigns):
    data = campaigns.data(kind)
    bad = data.with_name(f"{kind}-negative.csv")
    from instrument_campaigns import edit_columns

    edit_columns(data, bad, ("dl1",), lambda v, c: -900.0, rows={"r05"})
    done, files = identify(campaigns, kind, bad, f"{kind}-negative")
    line = _one_line(done.err)
    assert done.code == 1 and "pose r05: dl1 = -900" in line and bad.name in line and "no real leg" in line
    assert not any(path.exists() for path in files.values())


@pytest.mark.parametrize("option", [("--max-change", "0.0001"), ("--sigma-limit", "1e-9")])
def test_verdict_limits_act_with_a_setup(option, campaigns):
    """With a tracker setup, --max-change (every change implausible) and --sigma-limit (every
    parameter undetermined) turn a healthy calibration into a fail that writes nothing."""
    done, files = identify(campaigns, "targets", campaigns.data("targets"), f"limit{option[0]}", *option)
    assert done.code == 1 and "FAIL" in done.out
    assert not any(path.exists() for path in files.values())


def test_masked_leg_noise_is_said_never_nan(tmp_path: Path):
    """Pose noise far above the leg noise, 15 poses: the leg σ is barely learnable; no report
    prints nan for it (a σ that cannot be learned is said in words)."""
    poses = tmp_path / "p.csv"
    assert run("candidates", "--geometry", "paper-hmt", "--candidates", "random:15", "--seed", 3,
               "--out", poses).code == 0  # fmt: skip
    data = tmp_path / "m.csv"
    assert run("synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true", "--poses", poses,
               "--noise", "leg=1e-5,pos=0.2,ang=0.01", "--noise-dist", "normal", "--seed", 4,
               "--out", data).code == 0  # fmt: skip
    out = {k: tmp_path / f"r.{k}" for k in ("yaml", "txt", "json", "html")}
    done = run("identify", "--geometry", "paper-hmt", "--data", data, "--out", out["yaml"], "--report",
               out["txt"], "--json", out["json"], "--html", out["html"], "--force")  # fmt: skip
    assert done.code in (0, 1), done.err
    texts = [done.out, *(p.read_text() for p in out.values() if p.exists())]
    assert len(texts) == 5
    for text in texts:
        assert "± nan" not in text and " nan mm" not in text and "σ nan" not in text and "nan ±" not in text


def test_errormap_budget_names_the_option_to_lower(tmp_path: Path):
    done = run("errormap", "--geometry", "paper-hmt", "--draws", 1_000_000_000, "--out", tmp_path / "e")
    assert done.code != 0 and "--draws" in _one_line(done.err) and not (tmp_path / "e").exists()


def test_a_long_number_under_the_field_limit_is_quick_and_not_echoed(campaigns, tmp_path: Path):
    """A field of 100,000 digits (under the 131,072-character field limit): one short line at once."""
    from instrument_campaigns import edit_columns, read_csv, write_csv

    bad = tmp_path / "long.csv"
    edit_columns(campaigns.data("pose"), bad, ("dl3",), lambda v, c: v, rows={"r05"})
    comments, header, body = read_csv(bad)
    body[5][header.index("dl3")] = "1" * 100_000
    write_csv(bad, comments, header, body)
    done = run("identify", "--geometry", "paper-hmt", "--data", bad, "--out", tmp_path / "x.yaml")
    line = _one_line(done.err)
    # not repeated in full (the error line once took 30-40 s of regular-expression backtracking
    # over it, and was 100 kB long)
    assert done.code == 1 and "(100,000 characters)" in line and len(line) < 400
