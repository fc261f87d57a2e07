"""Issue 28: a verdict that tells measurement noise from model error.

A bumped laser tracker and legs that warm up, with the noise learned from the data, used to
pass: the error was absorbed into a larger learned noise. Here (seeded simulated campaigns of
the seed paper's machine, a tracker with three targets 2.6 m away, frame ``auto``, legs σ 5 µm,
targets σ 15 µm, normal) each is found, placed, sized and named, and the remedy works: the
bumped session split at the step calibrates as well as an unbumped one. The false alarms and
the smallest bumps and drifts found, over hundreds of campaigns per instrument, are measured
by ``benchmarks/sequence.py``; here a few clean campaigns only show the clean path.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import hexcal
from hexcal.calibration import estimate, group_references, reference_noises, split_sessions
from hexcal.core import NoiseModel, preset, random_poses
from hexcal.errors import CalibrationFailed, InputError, UsageError
from hexcal.estimation import Problem, estimate_noise
from hexcal.instruments import Session, TargetModel
from hexcal.instruments.ballbar_setup import BallbarSetup
from hexcal.instruments.known_noise import DEVICES, LEG_ENCODERS, device_for
from hexcal.instruments.setup import Setup
from hexcal.simulation import simulate_session

NOMINAL, TRUE = preset("paper-hmt"), preset("paper-hmt-true")
NOISE = NoiseModel(0.005, 0.015, 0.0, distribution="normal")
FRAME = np.array([2500.0, -800.0, 300.0, *np.deg2rad([2.0, -3.0, 35.0])])
TARGETS = {"t1": [0.0, 0.0, 60.0], "t2": [150.0, 20.0, 55.0], "t3": [-40.0, 160.0, 70.0]}
#: What the user knows: the frame unknown, the targets to about a millimetre.
START = Setup(None, {k: np.array(v) + [1.0, -1.0, 1.0] for k, v in TARGETS.items()})


def moved(frame: np.ndarray, translation_mm: float, rotation_deg: float, seed: int) -> np.ndarray:
    """The frame after a bump: the instrument moved ``translation_mm`` and turned
    ``rotation_deg`` (random directions)."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    turn = Rotation.from_rotvec(np.deg2rad(rotation_deg) * axis / np.linalg.norm(axis))
    rot = turn * Rotation.from_euler("XYZ", frame[3:])
    shift = rng.normal(size=3)
    return np.concatenate([frame[:3] + translation_mm * shift / np.linalg.norm(shift), rot.as_euler("XYZ")])


def campaign(m: int = 60, seed: int = 1, bump_at: int | None = None, bump=(2.0, 0.1), drift_mm: float = 0.0):
    """A tracker session of ``m`` random poses; the tracker bumped before pose ``bump_at``, or
    each leg growing by up to ``drift_mm`` over the session."""
    poses = random_poses(NOMINAL, m, seed)
    true = TargetModel(Setup(FRAME, TARGETS))
    if bump_at is None:
        session = simulate_session(NOMINAL, TRUE, true, poses, NOISE, seed)
        data = session.data
    else:
        bumped = TargetModel(Setup(moved(FRAME, *bump, seed), TARGETS))
        first = simulate_session(NOMINAL, TRUE, true, poses[:bump_at], NOISE, seed)
        second = simulate_session(NOMINAL, TRUE, bumped, poses[bump_at:], NOISE, seed + 1000)
        data = type(first.data)(
            np.concatenate([first.data.readings, second.data.readings]),
            np.concatenate([first.data.targets, second.data.targets]),
            first.data.names,
        )
    if drift_mm:
        growth = np.random.default_rng(seed).uniform(0.5, 1.0, 6) * drift_mm
        # a leg longer by g at the same pose reads g / gain less
        readings = data.readings - np.linspace(0.0, 1.0, m)[:, None] * growth / TRUE.leg_gains
        data = data.replace(readings=readings)
    ids = tuple(f"p{k:02d}" for k in range(m))
    return Session(data.replace(ids=ids), TargetModel(START), "run.csv")


def codes(result, severity=None):
    return result.verdict.codes(severity)


# -- what the instruments are known to do ----------------------------------------------------


def test_every_instrument_kind_has_a_noise_range_with_its_source():
    for device in DEVICES.values():
        assert device.source and device.ranges
        for r in device.ranges.values():
            assert 0 < r.low < r.typical < r.high
    assert 0 < LEG_ENCODERS.low < LEG_ENCODERS.typical < LEG_ENCODERS.high
    assert device_for("targets").name == "laser-tracker" and device_for("ballbar").name == "ballbar"


def test_a_setup_declares_its_instrument_and_noise_and_bad_ones_are_one_line():
    setup = Setup.from_dict(
        {
            "units": "mm",
            "instrument_frame": "auto",
            "tool": {"x": 0, "y": 0, "z": 0, "a": 0, "b": 0, "c": 0},
            "instrument": "motion-capture",
            "noise": {"position": 0.2, "orientation_deg": 0.1},
        }
    )
    assert setup.device.name == "motion-capture"
    assert setup.noise == pytest.approx({"position": 0.2, "orientation": np.deg2rad(0.1)})
    assert Setup.from_dict(setup.to_dict()).noise == pytest.approx(setup.noise)  # written back
    base = {"units": "mm", "instrument_frame": "auto", "targets": {"t1": [0, 0, 0]}}
    for extra, message in (
        ({"instrument": "motion-capture"}, "does not measure a setup with targets"),
        ({"instrument": "theodolite"}, "unknown kind"),
        ({"noise": {"orientation": 1e-4}}, "not a noise of this setup"),
        ({"noise": {"position": 0}}, "must be a number > 0"),
        ({"noise": "0.01"}, "must be a mapping"),
        # a σ ten times beyond what any such instrument shows is no such instrument (the
        # verdict fails a learned one there): 1e9 mm, a slip of units
        ({"noise": {"position": 1e9}}, r"1e\+09 mm is no noise of a laser tracker \(they show 0\.003 \.\.\."),
        ({"noise": {"position": 1e-6}}, "is no noise of a laser tracker"),
    ):
        with pytest.raises(InputError, match=message):
            Setup.from_dict(base | extra)
    assert Setup.from_dict(base | {"noise": {"position": 0.4}}).noise == {"position": 0.4}  # 8x: judged later
    tool = {k: v for k, v in setup.to_dict().items() if k != "calibration"}
    with pytest.raises(InputError, match="orientation_deg: 10 deg is no noise of a motion-capture system"):
        Setup.from_dict(tool | {"noise": {"orientation_deg": 10}})
    bar = {"units": "mm", "ballbar": {"pivot": [0, 0, 750], "ball": [0, 0, -50], "length": 150}}
    with pytest.raises(InputError, match=r"noise\.d: 1 mm is no noise of a telescoping ballbar"):
        BallbarSetup.from_dict(bar | {"noise": {"d": 1}})


def test_a_group_the_data_cannot_determine_is_held_at_the_declared_noise_whatever_the_start():
    # legs σ 0.02 mm hide a tracker-grade pose (the variance components' hidden case): the
    # pose groups are held at the declared σ, the same from any start (not where it stopped)
    from hexcal.simulation import simulate_measurements

    noise = NoiseModel(0.02, 0.002, 2e-5, distribution="normal")
    problem = Problem(NOMINAL, simulate_measurements(NOMINAL, TRUE, random_poses(NOMINAL, 100, 1), noise, 1))
    fallback = NoiseModel(0.005, 0.003, 3e-5, distribution="normal")
    found = [
        estimate_noise(problem, start=start, fallback=fallback)[0]
        for start in (NoiseModel(), NoiseModel(0.05, 0.1, 1e-3, distribution="normal"))
    ]
    for est in found:
        held = ~est.estimated
        assert held.any()
        np.testing.assert_array_equal(est.sigmas[held], np.array(fallback.sigmas)[held])
    np.testing.assert_allclose(found[0].sigmas, found[1].sigmas, rtol=5e-3)  # the iteration's rtol


def test_the_fallback_is_the_declared_noise_else_the_kinds_typical():
    declared = TargetModel(Setup(None, TARGETS, noise={"position": 0.007}))
    plain = TargetModel(Setup(None, TARGETS))
    assert reference_noises([declared])[0].sigmas[1] == 0.007
    assert reference_noises([plain])[0].sigmas[1] == DEVICES["laser-tracker"].ranges["position"].typical
    refs = group_references([declared])
    assert [(r.group, r.high) for r in refs] == [("leg", LEG_ENCODERS.high), ("position", 0.007)]


# -- a bumped tracker: found, placed, sized; split, it calibrates as well as an unbumped one --


@pytest.fixture(scope="module")
def bumped():
    return campaign(bump_at=30, seed=1)


@pytest.fixture(scope="module")
def bumped_result(bumped):
    return estimate(NOMINAL, [bumped])


def test_a_bumped_tracker_fails_naming_the_place_and_the_size(bumped_result):
    result = bumped_result
    assert result.failed  # it used to pass, the machine 53 times worse than without the bump
    step = next(r for r in result.verdict.reasons if r.code == "step")
    assert step.severity == "fail"
    assert (step.data["before"], step.data["after"]) == ("p29", "p30")
    assert step.data["family"] == "frame"
    # the size, linearised at the bumped fit: 2 mm and 0.1° within a quarter
    assert step.data["size"]["translation_mm"] == pytest.approx(2.0, rel=0.25)
    assert step.data["size"]["rotation_deg"] == pytest.approx(0.1, rel=0.25)
    assert "--split run.csv:p30" in step.message
    # a learned noise absorbed it (the legs' or the targets', as the fit shares it out): named as
    # model error against what leg encoders and laser trackers do
    model = next(r for r in result.verdict.reasons if r.code == "model-error")
    assert model.data["factor"] > 3


def test_split_at_the_step_calibrates_as_well_as_an_unbumped_campaign(bumped, bumped_result):
    split = hexcal.calibrate(NOMINAL, [bumped], split="auto")
    assert split.splits == ("run.csv:p30",) and split.before_split.failed
    assert split.status == "pass", split.failure()
    clean = estimate(NOMINAL, [campaign(seed=1)])
    held_out = campaign(m=40, seed=9)  # another session, the tracker re-registered on it

    def error(result):
        return hexcal.validate(result.geometry, held_out).calibrated.summary()["position_rms"]

    # the split campaign predicts held-out poses as well as the unbumped one (within the spread
    # of two campaigns' errors), the bumped one several times worse (measured: 0.235 mm against
    # 0.043 mm, the held-out noise of about 0.03 mm included in both)
    assert error(split.result) < 1.5 * error(clean)
    assert error(bumped_result) > 4 * error(split.result)
    sigma = split.result.noise_estimate.sigmas
    np.testing.assert_allclose(sigma[[0, 2]], 0.005, rtol=0.3)  # each part's legs at the truth
    # the same split by hand, from Python and by label
    parts, done = split_sessions([bumped], ["run.csv:p30"])
    assert done == ("run.csv:p30",) and [len(p) for p in parts] == [30, 30]


def test_a_gross_step_is_placed_where_it_explains_the_most():
    # a 2 mm bump explains all the residuals: its p underflows to 0 at several split points
    # around it, and the first of them was taken (this seed: between p28 and p29, one pose
    # early); split there, the bumped session left p29 in the second part, an outlier of 30 σ
    # and a warn (the benchmark's tracker cases: 2 of 3 seeds)
    bumped = campaign(bump_at=30, seed=7)
    result = estimate(NOMINAL, [bumped])
    step = next(r for r in result.verdict.reasons if r.code == "step")
    assert step.data["p_value"] == 0.0  # the case in point: beyond floating point
    assert (step.data["before"], step.data["after"]) == ("p29", "p30")
    split = hexcal.calibrate(NOMINAL, [bumped], split="auto")
    assert split.splits == ("run.csv:p30",) and split.status == "pass", split.failure()


def test_split_options_that_name_nothing_are_one_line(bumped):
    with pytest.raises(UsageError, match="has no pose"):
        split_sessions([bumped], ["run.csv:p99"])
    with pytest.raises(UsageError, match="first pose"):
        split_sessions([bumped], ["p00"])
    with pytest.raises(UsageError, match="LABEL:ID"):
        split_sessions([bumped, bumped.replace(label="b.csv")], ["other.csv:p10"])
    # a part too small to register its instrument again is named, not left to the
    # identifiability check ("the poses cannot identify ... session2.t2.y")
    one = r"split run\.csv:p59: a part of run\.csv would hold 1 pose\(s\) \(p59"
    with pytest.raises(UsageError, match=one):
        split_sessions([bumped], ["p59"])
    two = r"split run\.csv:p02: a part of run\.csv would hold 2 pose\(s\) \(p00"
    with pytest.raises(UsageError, match=two):
        split_sessions([bumped], ["p02"])
    with pytest.raises(UsageError, match=r"would hold 3 pose\(s\) \(p30 \.\.\. p32\)"):
        split_sessions([bumped], ["p30", "p33"])
    assert [len(p) for p in split_sessions([bumped], ["p05", "p55"])[0]] == [5, 50, 5]


def test_warming_legs_are_called_a_drift():
    result = estimate(NOMINAL, [campaign(seed=2, drift_mm=0.15)])
    drift = next(r for r in result.verdict.reasons if r.code == "drift")
    assert drift.severity in ("warn", "fail") and drift.data["family"] == "legs"
    assert "temp1" in drift.message  # the remedy: the legs' temperatures
    grown = np.asarray(drift.data["size"]["legs_mm"])
    assert np.all(grown > 0.03) and np.all(grown < 0.3)  # grew 0.075-0.15 mm: sign and size


def test_a_drift_in_time_is_seen_in_the_time_column():
    # 60 poses, the first 40 in 10 minutes, the last 20 over the next 50 (a pause, the machine
    # warming on): the legs grow with time, not with the row. With the time column the drift's
    # regressor is the right one and explains more of the residuals than the row order does.
    from hexcal.instruments.covariates import Covariates

    time = np.concatenate([np.linspace(0, 600, 40), np.linspace(700, 3600, 20)])
    session = campaign(seed=6)
    growth = np.random.default_rng(6).uniform(0.5, 1.0, 6) * 0.15
    readings = session.data.readings - (time / time[-1])[:, None] * growth / TRUE.leg_gains
    in_rows = session.replace(data=session.data.replace(readings=readings))
    in_time = in_rows.replace(data=in_rows.data.replace(covariates=Covariates(time=time)))
    found = {}
    for name, s in (("rows", in_rows), ("time", in_time)):
        result = estimate(NOMINAL, [s])
        found[name] = next(r for r in result.verdict.reasons if r.code in ("drift", "step"))
    assert found["time"].code == "drift" and found["time"].data["family"] == "legs"
    assert found["time"].data["explained"] > found["rows"].data["explained"]


@pytest.mark.parametrize("seed", [3, 4])
def test_clean_campaigns_have_no_step_and_no_drift(seed):
    result = estimate(NOMINAL, [campaign(m=40, seed=seed)])
    assert not {"step", "drift", "model-error"} & set(codes(result, "warn") + codes(result, "fail"))


# -- one judgement: Python and the command line alike; nothing failed is saved ----------------


def test_a_failed_calibration_is_not_saved_from_python(bumped, tmp_path):
    failed = hexcal.calibrate(NOMINAL, [bumped])
    with pytest.raises(CalibrationFailed, match=r"verdict fail: run\.csv: a step between poses p29 and p30"):
        failed.save(tmp_path / "cal.yaml")
    assert not (tmp_path / "cal.yaml").exists()
    failed.save(tmp_path / "cal.yaml", force=True)
    assert hexcal.load_geometry(tmp_path / "cal.yaml").calibration["verdict"] == "fail"


def test_estimate_and_calibrate_hold_the_command_lines_defaults():
    from hexcal.calibration.limits import MAX_CHANGE, SIGMA_LIMIT

    session = campaign(m=40, seed=5)
    assert estimate(NOMINAL, [session]).noise_source == "estimated"
    fraction = estimate(NOMINAL, [session], sigma_limit=SIGMA_LIMIT, max_change=MAX_CHANGE)
    default = estimate(NOMINAL, [session])
    assert [r.message for r in fraction.verdict.reasons] == [r.message for r in default.verdict.reasons]


def test_the_same_session_twice_is_refused(bumped):
    copy = Session(bumped.data, bumped.instrument, "copy.csv")
    with pytest.raises(
        UsageError, match=r"the same session twice \(run\.csv and copy\.csv hold the same observations"
    ):
        estimate(NOMINAL, [bumped, copy])
    # the same rows in another order are the same observations
    reversed_rows = bumped.data.subset(np.arange(len(bumped.ids))[::-1])
    with pytest.raises(UsageError, match=r"run\.csv and rev\.csv hold the same observations"):
        estimate(NOMINAL, [bumped, Session(reversed_rows, bumped.instrument, "rev.csv")])
    # the same poses measured again (new values) are another session
    again = campaign(seed=1, bump_at=30).data
    noisy = again.replace(targets=again.targets + 0.001)
    estimate(
        NOMINAL, [bumped, Session(noisy, bumped.instrument, "again.csv")], with_bound=False, verdict=False
    )


def test_calibrate_refuses_no_session_and_a_level_outside_0_1_in_one_line(bumped):
    # the red-team pass of issue 31: calibrate(nominal, []) ended in AttributeError ('list'
    # object has no attribute 'ids') and alpha=2 ran the outlier check at a level of 200 %
    with pytest.raises(UsageError, match=r"^no session: give at least one"):
        hexcal.calibrate(NOMINAL, [])
    for alpha in (2, 0, -0.1, float("nan"), "0.05", True):
        with pytest.raises(UsageError, match=r"^alpha \(the outlier check's level\) must be between 0 and 1"):
            hexcal.calibrate(NOMINAL, [bumped], alpha=alpha)


def test_a_bump_over_a_pause_in_the_time_column_is_a_step_not_a_drift():
    # the red-team pass of issue 31: a tracker bumped during a pause (times 0-29 s, then from
    # 1e9 s on) was called "a drift from the first pose to the last", whose remedy is no
    # split: a drift in time over one jump is the step at the jump
    from hexcal.instruments.covariates import Covariates

    session = campaign(bump_at=30)
    time = np.concatenate([np.arange(30.0), 1e9 + np.arange(30.0)])
    timed = session.replace(data=session.data.replace(covariates=Covariates(time=time)))
    found = next(r for r in estimate(NOMINAL, [timed]).verdict.reasons if r.code in ("drift", "step"))
    assert found.code == "step" and found.data["after"] == "p30", found.message
    # times of any size: 1e306 s and more (their sum overflowed)
    times = Covariates(time=1e306 * (1 + np.arange(60.0)))
    huge = session.replace(data=session.data.replace(covariates=times))
    found = next(r for r in estimate(NOMINAL, [huge]).verdict.reasons if r.code in ("drift", "step"))
    assert found.code == "step" and found.data["after"] == "p30", found.message


def test_calibrate_and_its_files_refuse_what_python_users_mistype_in_one_line(bumped, tmp_path):
    # the red-team pass of issue 31: each of these ended in a TypeError, AttributeError or
    # KeyError, or was silently misread (robust="no" is truthy; save_setups("s.yaml") wrote
    # the files "s", ".", "y", ...; fewer paths than sessions wrote fewer setups)
    for call, line in (
        (lambda: hexcal.calibrate("paper-hmt", [bumped]), r"^calibrate: the nominal Geometry"),
        (lambda: hexcal.calibrate(NOMINAL, "run.csv"), r"give sessions, not a file name"),
        (lambda: hexcal.calibrate(NOMINAL, [bumped], split=5), r"^split must be 'auto' or LABEL:ID"),
        (lambda: hexcal.calibrate(NOMINAL, [bumped], robust="no"), r"^robust must be True or False"),
    ):
        with pytest.raises(UsageError, match=line):
            call()
    split = hexcal.calibrate(NOMINAL, [bumped], split=["p30"])
    with pytest.raises(UsageError, match=r"^report: fmt is 'text' or 'json'"):
        split.report("pdf")
    three = [tmp_path / f"{k}.yaml" for k in range(3)]
    for paths in (str(tmp_path / "s.yaml"), [tmp_path / "one.yaml"], three):
        with pytest.raises(UsageError, match=r"^save_setups: one path per session, 2 in order \(run\.csv#1"):
            split.save_setups(paths)
    assert list(tmp_path.iterdir()) == []
    split.save_setups([tmp_path / "a.yaml", tmp_path / "b.yaml"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.yaml", "b.yaml"]
