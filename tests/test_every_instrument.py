"""Every promise of the one calibrator, on every instrument, through the command line.

The six instruments of :mod:`instrument_campaigns` (the full pose in the base frame and in a
frame of its own, a 6-DOF tool, one target, three targets, a ballbar) are simulated with ``hexcal
synthesize --setup`` from the presets, identified from what a user knows (frame ``auto``, the
setup's quantities to about a millimetre), and every command is asked the same questions:

1. ``identify`` prints its verdict first, and its JSON has the same top-level keys for every
   instrument (the instrument's own quantities inside them);
2. a verdict ``fail`` exits 1 and writes nothing without ``--force``, with it writes, and the
   reason names the diagnosis (metres, degrees, unfitted gains, Euler sequence, poses that never
   rotate);
3. the noise is learned from the data, per session and group, within the χ² spread of its σ;
4. the predicted accuracy is in the JSON, finite;
5. a spoiled observation is flagged by id, and ``--robust`` leaves it out;
6. every estimator runs, or is refused in one line;
7. ``--html`` writes a page on every command that has it;
8. ``simulate --setup`` gives the same numbers with ``--jobs 1`` and ``--jobs 2``, fits gains,
   runs without ``--true``;
9. ``observability`` of poses that never rotate says what cannot be identified;
10. ``validate`` on held-out data gives finite pose errors.

Each command runs once per instrument (module-scoped fixtures), on 20 poses (40 for one target;
the ballbar 360, on 30 circles at one pivot, and 200 random ones in its studies).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import pytest

from instrument_campaigns import (
    INSTRUMENTS,
    Campaigns,
    Run,
    identify,
    load_json,
    run,
)

KINDS = list(INSTRUMENTS)
OWN_FRAME = [k for k in KINDS if INSTRUMENTS[k].true_setup is not None]


def _slow_unless(cases: list[Any], default: set[Any]) -> list[Any]:
    """``cases`` as parameters, those not in ``default`` marked slow: the default run keeps
    every instrument and every diagnosis once (a failed identification refits its variants:
    several seconds each), ``make test-slow`` runs the whole matrix."""
    slow = pytest.mark.slow
    return [c if c in default else pytest.param(*(c if isinstance(c, tuple) else (c,)), marks=slow)
            for c in cases]  # fmt: skip


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory: pytest.TempPathFactory) -> Campaigns:
    return Campaigns(tmp_path_factory.mktemp("every-instrument"))


@pytest.fixture(scope="module")
def baseline(campaigns: Campaigns) -> dict[str, tuple[Run, dict[str, Path]]]:
    """The clean campaign of every instrument identified once, with every output."""
    out = {}
    for kind in KINDS:
        done, files = identify(campaigns, kind, campaigns.data(kind), f"{kind}-base")
        assert done.code == 0, done.err
        out[kind] = (done, files)
    return out


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and math.isfinite(value)


# -- 1. the verdict first, one JSON shape ----------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_identify_prints_the_verdict_first(kind: str, baseline: dict) -> None:
    done, files = baseline[kind]
    assert re.match(r"Verdict: (PASS|WARN)\b", done.out.splitlines()[0])
    assert files["report"].read_text().splitlines()[0] == done.out.splitlines()[0]
    assert load_json(files["json"])["verdict"] in ("pass", "warn")


def test_identify_json_has_the_same_keys_for_every_instrument(baseline: dict) -> None:
    bodies = {kind: load_json(files["json"]) for kind, (_, files) in baseline.items()}
    keys = {kind: frozenset(body) for kind, body in bodies.items()}
    assert len(set(keys.values())) == 1, {k: sorted(v ^ keys["pose"]) for k, v in keys.items()}
    common = {"verdict", "reasons", "noise", "accuracy", "rank", "outliers", "flagged", "parameters",
              "stderr", "bound", "sessions", "gauges", "dof", "n_parameters"}  # fmt: skip
    assert common <= keys["pose"]
    for kind, body in bodies.items():
        inst = INSTRUMENTS[kind]
        assert "source" in body["noise"]
        assert len(body["gauges"]) == inst.gauges, kind
        (session,) = body["sessions"]
        setup = session["setup"]
        first = "pivot.x" if inst.circles else "frame.x"  # a ballbar has no frame: pivot, ball, length
        assert setup[first]["value"] is not None
        if inst.true_setup is None:  # the base frame itself: nothing of the instrument varies
            assert session["varied"] == [] and setup[first]["stderr"] is None
        else:  # the instrument's own quantities, identified: frame (pivot) and what it sees
            assert first in session["varied"] and _finite(setup[first]["stderr"])
            # an auto frame is registered from the data first; a ballbar has none to register
            assert (session["registration"] is not None) is ("auto" in inst.start_setup)


# -- 2. a verdict fail writes nothing, names the cause -----------------------------------------

#: What the reason line says for each diagnosis.
DIAGNOSES = {
    "metres": r"look like metres",
    "degrees": r"angles look like degrees in radian columns",
    "euler": r"Euler sequence looks wrong: with 'ZYX' instead of 'XYZ'",
    "gains": r"fit the gains: --fit joints,l0,gains",
    # the combinations these poses cannot see, named ("+0.52·u1.z -0.40·u2.z ...")
    "flat": r"(determined by these data|cannot identify all parameters).*[+-]\d\.\d\d·[a-z]",
}

#: Diagnoses of angles apply where the instrument measures angles: targets measure positions
#: only, so a degree or Euler mistake cannot be made in their data.
#: A ballbar's readings in metres are refused too (verdict fail, nothing written), but named as
#: unfitted gains: d / 1000 is almost constant, which a wrong machine fits within the noise, and
#: the gains explain what is left best (docs/ballbar.md); that case is left out here.
FAIL_CASES = [
    (kind, diagnosis)
    for kind in KINDS
    for diagnosis in DIAGNOSES
    if (INSTRUMENTS[kind].angles or diagnosis not in ("degrees", "euler"))
    and (kind, diagnosis) != ("ballbar", "metres")
]


def _nothing_written(files: dict[str, Path]) -> None:
    written = [str(p) for p in files.values() if p.exists()]
    assert not written, f"a failed identify wrote {written}"


#: Each instrument and each diagnosis at least once in the default run.
DEFAULT_FAILS = {("pose", "degrees"), ("pose", "euler"), ("tool", "gains"), ("target", "metres"),
                 ("target", "flat"), ("targets", "gains"), ("pose-frame", "degrees")}  # fmt: skip


@pytest.mark.parametrize(("kind", "diagnosis"), _slow_unless(FAIL_CASES, DEFAULT_FAILS))
def test_a_failed_identification_writes_nothing_and_names_the_cause(
    kind: str, diagnosis: str, campaigns: Campaigns
) -> None:
    done, files = identify(campaigns, kind, campaigns.data(kind, diagnosis), f"{kind}-{diagnosis}")
    assert done.code == 1, done.out[:2000]
    _nothing_written(files)
    last = done.err.strip().splitlines()[-1]
    assert last.startswith("hexcal: error: "), done.err
    assert "Traceback" not in done.err
    assert re.search(DIAGNOSES[diagnosis], last), last
    if done.out:  # a verdict (not a fit that failed outright): the report, verdict first
        assert done.out.startswith("Verdict: FAIL")


class _Spoiled(dict):
    """The spoiled campaign of an instrument, identified on first use: as is, with --force,
    with --robust (a failed identification explains itself by refitting: seconds each)."""

    def __init__(self, campaigns: Campaigns) -> None:
        super().__init__()
        self.campaigns = campaigns

    def __missing__(self, kind: str) -> dict[str, tuple[Run, dict[str, Path]]]:
        campaigns, data = self.campaigns, self.campaigns.data(kind, "spoiled")
        self[kind] = {
            "plain": identify(campaigns, kind, data, f"{kind}-spoiled"),
            "force": identify(campaigns, kind, data, f"{kind}-forced", "--force"),
            "robust": identify(campaigns, kind, data, f"{kind}-robust", "--robust"),
        }
        return self[kind]


@pytest.fixture(scope="module")
def spoiled(campaigns: Campaigns) -> _Spoiled:
    return _Spoiled(campaigns)


#: The instruments whose spoiled campaign the default run identifies (a position and a pose
#: instrument); the others with ``make test-slow``.
SPOILED_DEFAULT = {"pose", "targets"}


#: A ballbar's spoiled reading (100 σ = 0.1 mm) is flagged by id and left out by --robust (the
#: next test), but its verdict is warn, not fail: the bar's σ cannot be learned from one pivot's
#: circles (too few data), so the χ² does not condemn the fit; it has no case here.
@pytest.mark.parametrize("kind", _slow_unless([k for k in KINDS if k != "ballbar"], SPOILED_DEFAULT))
def test_force_writes_a_failed_identification(kind: str, spoiled: dict, campaigns: Campaigns) -> None:
    done, files = spoiled[kind]["plain"]
    assert done.code == 1 and done.out.startswith("Verdict: FAIL"), done.err
    _nothing_written(files)
    assert campaigns.spoiled_id(kind) in done.err.strip().splitlines()[-1]
    done, files = spoiled[kind]["force"]
    assert done.code == 0, done.err
    assert all(p.exists() and p.stat().st_size > 0 for p in files.values())
    assert load_json(files["json"])["verdict"] == "fail"
    assert "verdict fail, written anyway (--force)" in done.err


# -- 3. the noise learned from the data ---------------------------------------------------------


def _chi_square_range(dof: float, tail: float = 1e-5) -> tuple[float, float]:
    """Two-sided range of ``σ̂² / σ²`` for a variance estimated with ``dof`` degrees of freedom
    (``χ²_dof / dof``), ``tail`` in each tail (about 4.4 standard deviations)."""
    from scipy.special import chdtri

    return chdtri(dof, 1 - tail) / dof, chdtri(dof, tail) / dof


@pytest.mark.parametrize("kind", KINDS)
def test_noise_is_learned_per_session_and_group_within_its_chi_square_spread(
    kind: str, baseline: dict, campaigns: Campaigns
) -> None:
    done, files = baseline[kind]
    body = load_json(files["json"])
    inst = INSTRUMENTS[kind]
    noise = body["noise"]
    assert noise["source"] == "estimated"
    assert "noise from the data" in done.out  # the report says so
    groups = noise["groups"]
    assert [g["label"] for g in groups] == list(inst.groups)
    assert {g["session"] for g in groups} == {campaigns.data(kind).name}
    estimate = body["noise_estimate"]
    assert estimate["converged"], estimate
    # the redundancies are the degrees of freedom of the groups: together those of the fit
    assert sum(estimate[g]["redundancy"] for g in inst.groups) == pytest.approx(body["dof"], rel=1e-6)
    true = inst.sigma
    for group in groups:
        label, sigma = group["label"], group["sigma"]
        red = estimate[label]["redundancy"]
        lo, hi = _chi_square_range(red)
        ratio = (sigma / true[label]) ** 2
        assert lo <= ratio <= hi, f"{kind} {label}: σ {sigma:.4g} vs {true[label]} (r = {red:.1f})"


# -- 4. the predicted accuracy ------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_predicted_accuracy_as_platform_pose_error(kind: str, baseline: dict) -> None:
    body = load_json(baseline[kind][1]["json"])
    accuracy = body["accuracy"]
    for key in ("position_rms_mm", "position_max_mm", "orientation_rms_rad", "orientation_max_rad"):
        assert _finite(accuracy[key]) and accuracy[key] > 0, (key, accuracy)
    # far below the nominal machine's error (tens of mm) and above the noise's
    assert 0.005 < accuracy["position_rms_mm"] < 1.0


@pytest.mark.parametrize("kind", KINDS)
def test_predicted_accuracy_in_the_instruments_own_terms(kind: str, baseline: dict) -> None:
    body = load_json(baseline[kind][1]["json"])
    (own,) = body["accuracy"]["instrument"]
    inst = INSTRUMENTS[kind]
    groups = [g for g in inst.groups if g != "leg"]
    keys = {f"{g}_{q}_{'rad' if g == 'orientation' else 'mm'}" for g in groups for q in ("rms", "max")}
    assert keys <= set(own), own
    for key in keys:
        assert _finite(own[key]) and 0 < own[key] <= own[key.replace("_rms_", "_max_")], (key, own)
    assert own["own_frame"] is (inst.true_setup is not None)
    if inst.true_setup is None:  # the full pose in the base frame reads the platform pose itself
        assert own["position_rms_mm"] == pytest.approx(body["accuracy"]["position_rms_mm"], rel=1e-9)
    else:  # said in the report too
        assert "predicted error of what the instrument reads after calibration" in baseline[kind][0].out
    length = own[f"{groups[0]}_rms_mm"]
    assert 0.005 < length < 1.0


# -- 5. outliers --------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", _slow_unless(KINDS, SPOILED_DEFAULT))
def test_a_spoiled_observation_is_flagged_and_robust_leaves_it_out(
    kind: str, spoiled: dict, campaigns: Campaigns
) -> None:
    SPOILED = campaigns.spoiled_id(kind)  # the module's SPOILED, per instrument
    done, files = spoiled[kind]["force"]
    flagged = load_json(files["json"])["flagged"]
    assert any(f.split()[0] == SPOILED for f in flagged), flagged
    done, files = spoiled[kind]["robust"]
    assert done.code == 0, done.err
    body = load_json(files["json"])
    assert [o.split()[0] for o in body["outliers"]] == [SPOILED], body["outliers"]
    assert body["verdict"] in ("pass", "warn")
    assert f"left out as outliers (--robust): {SPOILED}" in done.out


# -- 6. estimators ------------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["gls", "length", "paper"])
@pytest.mark.parametrize("kind", KINDS)
def test_every_estimator_runs_or_is_refused_in_one_line(kind: str, method: str, campaigns: Campaigns) -> None:
    done, files = identify(campaigns, kind, campaigns.data(kind), f"{kind}-{method}", "--method", method)
    if INSTRUMENTS[kind].determines_pose:
        assert done.code == 0, done.err
        assert load_json(files["json"])["method"] == method
    else:  # these estimators treat the measured platform pose as exact: this instrument has none
        assert done.code == 1
        assert done.err.count("\n") == 1 and done.err.startswith("hexcal: error: "), done.err
        assert "ml" in done.err
        _nothing_written(files)


# -- 7, 9, 10: planning and validation, with --html ---------------------------------------------


@pytest.fixture(scope="module")
def planned(campaigns: Campaigns, baseline: dict) -> dict[str, dict[str, Any]]:
    """validate, select and observability of every instrument, each with --html and --json."""
    out = {}
    root = campaigns.root
    for kind in KINDS:
        setup, files = campaigns.setup(kind), baseline[kind][1]
        cal_setup = ["--setup", files["setup-out"]] if "setup-out" in files else []
        flat = campaigns.kind_poses(kind, "flat")
        # one target needs more poses than the others; a ballbar 60 of random ones (its planning
        # by circles is select --ballbar, tests/test_ballbar.py)
        n = 60 if INSTRUMENTS[kind].circles else INSTRUMENTS[kind].poses // 2 + 5
        out[kind] = {
            "validate": run("validate", "--geometry", files["out"], *cal_setup, "--data",
                            campaigns.data(kind, "held"), "--out", root / f"{kind}-val.csv",
                            "--html", root / f"{kind}-validate.html"),
            "select": run("select", "--geometry", "paper-hmt", *setup, "--n", n, "--candidates",
                          f"random:{3 * n}", "--out", root / f"{kind}-plan.csv", "--json",
                          root / f"{kind}-select.json", "--html", root / f"{kind}-select.html"),
            "observability": run("observability", "--geometry", "paper-hmt", *setup, "--poses",
                                 campaigns.kind_poses(kind, "measure"), "--json",
                                 root / f"{kind}-obs.json", "--html", root / f"{kind}-observability.html"),
            "flat": run("observability", "--geometry", "paper-hmt", *setup, "--poses", flat,
                        "--json", root / f"{kind}-flat.json"),
        }  # fmt: skip
    return out


def _page(path: Path) -> None:
    assert path.exists(), f"--html {path} was not written"
    text = path.read_text(encoding="utf-8")
    assert len(text) > 1000 and "<html" in text


@pytest.mark.parametrize("command", ["identify", "validate", "select", "observability", "simulate"])
@pytest.mark.parametrize("kind", KINDS)
def test_html_is_written_by_every_command(
    kind: str, command: str, campaigns: Campaigns, baseline: dict, planned: dict, simulated: dict
) -> None:
    if command == "identify":
        _page(baseline[kind][1]["html"])
        return
    done = simulated[kind]["jobs1"] if command == "simulate" else planned[kind][command]
    assert done.code == 0, done.err
    _page(campaigns.root / f"{kind}-{command}.html")
    assert "wrote the HTML report to" in done.out  # said, not silently ignored


@pytest.mark.parametrize("kind", KINDS)
def test_observability_of_poses_that_never_rotate_says_not_identifiable(
    kind: str, planned: dict, campaigns: Campaigns
) -> None:
    done = planned[kind]["flat"]
    assert done.code == 0, done.err
    assert "NOT identifiable" in done.out
    body = load_json(campaigns.root / f"{kind}-flat.json")
    assert body["identifiable"] is False and body["unidentifiable"]
    assert all("·" in c or "+" in c for c in body["unidentifiable"])
    # no finite, optimistic σ for what cannot be seen
    assert body["predicted_mean_abs_error_mm"]["bound"] is None
    assert all(p["std_bound"] is None for name, p in body["parameters"].items() if name.startswith("u"))


def _figures(text: str) -> dict[str, float]:
    """``label -> value`` of the rows of ``hexcal validate``'s table."""
    out = {}
    for line in text.splitlines():
        m = re.match(r"\s+(.+?\((?:mm|mrad|rad)\))\s+(\S+)$", line)
        if m:
            out[m.group(1)] = float(m.group(2))
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_validate_on_held_out_data_gives_finite_pose_errors(kind: str, planned: dict) -> None:
    done = planned[kind]["validate"]
    assert done.code == 0, done.err
    assert "warning" not in done.err, done.err
    figures = _figures(done.out)
    if kind in ("target", "ballbar"):
        # one target gives 3 coordinates per pose, a ballbar one distance: no platform pose to
        # compare with the forward kinematics; the instrument's own error is the figure (and no
        # NaN row)
        assert "position error RMS (mm)" not in figures and "nan" not in done.out
        own = "target distance RMS (mm)" if kind == "target" else "bar RMS (mm)"
        assert 0 < figures[own] < 1.0, figures
        return
    for label in ("position error RMS (mm)", "position error max (mm)", "orientation error RMS (mrad)"):
        assert _finite(figures[label]) and figures[label] > 0, figures
    assert figures["position error RMS (mm)"] < 1.0  # the nominal machine misses by ~45 mm


# -- 8. simulate --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def simulated(campaigns: Campaigns) -> dict[str, dict[str, Run]]:
    """simulate of every instrument: --jobs 1 and --jobs 2 with gains fitted, and without --true."""
    out = {}
    root = campaigns.root
    for kind in KINDS:
        setup = campaigns.setup(kind, "true")
        inst = INSTRUMENTS[kind]
        # one distance per pose: a ballbar needs far more random poses than 15 for its 37 combinations
        poses = 200 if inst.circles else 15
        common = ["simulate", "--geometry", "paper-hmt", *setup, "--poses", poses, "--strategies", "interior",
                  "--methods", "ml", *inst.noise, "--quiet", "--seed", 3]  # fmt: skip
        gains = ["--true", "paper-hmt-true", "--trials", 3, "--fit", "joints,l0,gains"]
        out[kind] = {
            "jobs1": run(*common, *gains, "--jobs", 1, "--out", root / f"{kind}-sim1",
                         "--html", root / f"{kind}-simulate.html"),
            "jobs2": run(*common, *gains, "--jobs", 2, "--out", root / f"{kind}-sim2"),
            "random": run(*common, "--trials", 2, "--jobs", 1, "--out", root / f"{kind}-sim-random"),
        }  # fmt: skip
    return out


def _without_timing(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _without_timing(v) for k, v in value.items() if not re.search(r"time|elapsed|second", k)}
    if isinstance(value, list):
        return [_without_timing(v) for v in value]
    return value


@pytest.mark.parametrize("kind", KINDS)
def test_simulate_gives_the_same_numbers_with_any_jobs_and_fits_gains(
    kind: str, simulated: dict, campaigns: Campaigns
) -> None:
    for name in ("jobs1", "jobs2"):
        assert simulated[kind][name].code == 0, simulated[kind][name].err
    one = load_json(campaigns.root / f"{kind}-sim1" / "study.json")
    two = load_json(campaigns.root / f"{kind}-sim2" / "study.json")
    assert _without_timing(one) == _without_timing(two)
    assert one["fit"] == "joints,l0,gains"
    (cell,) = one["cells"]
    assert cell["failures"] == 0 and _finite(cell["error_mean"]) and _finite(cell["bound"])
    assert _finite(cell["position_rms"])


@pytest.mark.parametrize("kind", KINDS)
def test_simulate_without_true_uses_random_machines(kind: str, simulated: dict, campaigns: Campaigns) -> None:
    done = simulated[kind]["random"]
    assert done.code == 0, done.err
    assert "no --true: the simulated real machines are random" in done.err
    body = load_json(campaigns.root / f"{kind}-sim-random" / "study.json")
    assert body["true_machine"] == "random"
    (cell,) = body["cells"]
    assert cell["failures"] == 0 and _finite(cell["error_mean"])
