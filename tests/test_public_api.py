"""The public API a notebook user reads (issue 18 item 6, "One calibrator").

Every package says in its docstring's "Public names" section exactly what its ``__all__``
exports; every exported name resolves and is documented; the solver and linear-algebra
internals are exported by no package; and the tracker workflow (geometry and setup files,
two measurement sessions read from files, identification, verdict, validation, planning,
simulation) runs with ``import hexcal`` alone.
"""

from __future__ import annotations

import importlib
import inspect
import re
import subprocess
import sys
from types import ModuleType

import numpy as np
import pytest

import hexcal

LAYERS = ("core", "instruments", "estimation", "calibration", "design", "simulation", "report", "io")
PACKAGES = ("hexcal", *(f"hexcal.{name}" for name in LAYERS))

#: Modules whose every own function and class is internal (solver and linear-algebra pieces).
INTERNAL_MODULES = (
    "hexcal.estimation.levenberg",
    "hexcal.estimation.stacked",
    "hexcal.core.linalg",
)
#: Internal names issue 18 names, wherever they are defined.
INTERNAL_NAMES = {"cholesky_lower", "cholesky_solve", "damped", "LEG_INDEX", "identify_chunk", "Stack"}


def _package(name: str) -> ModuleType:
    return importlib.import_module(name)


def _listed(package: ModuleType) -> list[str]:
    """The names of the docstring's "Public names" section (each in double backquotes)."""
    doc = package.__doc__ or ""
    match = re.search(r"^Public names\n-+\n(.*?)(?:\n\n|\Z)", doc, re.S | re.M)
    assert match, f"{package.__name__}: no 'Public names' section in the docstring"
    return re.findall(r"``(\w+)``", match.group(1))


@pytest.mark.parametrize("name", PACKAGES)
def test_the_docstring_lists_exactly_what_the_package_exports(name: str) -> None:
    package = _package(name)
    listed = _listed(package)
    assert len(listed) == len(set(listed)), f"{name}: a name is listed twice"
    assert sorted(listed) == sorted(package.__all__)
    assert sorted(dir(package)) == sorted(package.__all__)  # completion shows the API only


@pytest.mark.parametrize("name", PACKAGES)
def test_every_exported_name_resolves_and_is_documented(name: str) -> None:
    package = _package(name)
    for attr in package.__all__:
        value = getattr(package, attr)
        if inspect.isclass(value) or inspect.isfunction(value):
            doc = value.__dict__.get("__doc__") if inspect.isclass(value) else value.__doc__
            assert doc and doc.strip(), f"{name}.{attr} has no docstring"
            # a dataclass without a docstring gets its signature as one
            assert not doc.startswith(f"{value.__name__}("), f"{name}.{attr} has no docstring"
        else:  # a constant: its line in the "Public names" section says what it is
            assert attr in _listed(package), f"{name}.{attr}"


def test_the_solver_internals_are_exported_by_no_package() -> None:
    internal = set(INTERNAL_NAMES)
    for module_name in INTERNAL_MODULES:
        module = importlib.import_module(module_name)
        own = {
            n
            for n, v in vars(module).items()
            if (inspect.isfunction(v) or inspect.isclass(v)) and v.__module__ == module_name
        }
        assert own, module_name
        internal |= own
    assert {"cholesky_lower", "damped", "scaled_svd", "gram_pinv"} <= internal
    for name in PACKAGES:
        exported = set(_package(name).__all__)
        assert not exported & internal, f"{name} exports {sorted(exported & internal)}"
        assert all(not n.startswith("_") for n in exported - {"__version__"}), name


def test_the_top_level_is_lazy_and_holds_the_workflow() -> None:
    probe = "import sys, hexcal; dir(hexcal); hexcal.__all__; print('numpy' in sys.modules)"
    run = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=True
    )
    assert run.stdout.strip() == "False"
    workflow = {
        "load_geometry", "load_setup", "read_session", "read_sessions", "estimate", "validate",
        "analyse_poses", "plan_selection", "candidate_poses", "simulate_session", "Setup",
    }  # fmt: skip
    assert workflow <= set(hexcal.__all__)


SETUP_YAML = """\
units: mm
instrument_frame: auto
targets:
  t1: [1, -1, 61]
  t2: [149, 21, 54]
  t3: [-41, 158, 71]
"""

#: Where the tracker stood in each session (mm, rad): metres away, turned, moved in between.
FRAMES = ([2500.0, -800.0, 300.0, 0.03, -0.05, 0.6], [-1800.0, 2200.0, 150.0, 0.0, 0.02, -1.1])


def test_a_tracker_campaign_from_files_with_import_hexcal_only(tmp_path) -> None:
    """Two sessions of a three-target tracker moved in between, each 15 poses, identified
    together; the seed paper's machine ``paper-hmt-true`` is the real one."""
    hexcal.save_geometry(hexcal.preset("paper-hmt"), tmp_path / "nominal.yaml")
    geometry = hexcal.load_geometry(tmp_path / "nominal.yaml")
    true = hexcal.preset("paper-hmt-true")
    (tmp_path / "tracker.yaml").write_text(SETUP_YAML)
    setup = hexcal.load_setup(tmp_path / "tracker.yaml")
    assert setup.auto and setup.target_names == ("t1", "t2", "t3")
    noise = hexcal.NoiseModel(0.005, 0.015, 0.001)

    files = []
    for k, frame in enumerate(FRAMES):
        instrument = hexcal.instrument_for(hexcal.Setup(np.array(frame), dict(setup.targets)))
        poses = hexcal.random_poses(geometry, 15, 10 + k)
        session = hexcal.simulate_session(geometry, true, instrument, poses, noise, rng=k)
        files.append(tmp_path / f"session{k}.csv")
        hexcal.write_session_data(files[-1], session, geometry.euler)
    sessions = hexcal.read_sessions(files, [tmp_path / "tracker.yaml"], geometry.euler)
    assert [len(s) for s in sessions] == [15, 15]

    result = hexcal.estimate(geometry, sessions, noise=noise)
    assert result.verdict.status == "pass", result.verdict.codes()
    # 42 machine parameters and 15 per session (frame and targets); 12 gauge freedoms
    assert (len(result.names), result.rank) == (42 + 2 * 15, 42 + 2 * 15 - 12)
    first = result.calibrated_instruments()[0].setup
    np.testing.assert_allclose(first.frame[:3], FRAMES[0][:3], atol=5.0)  # the gauge moves it by mm
    hexcal.save_setup(first, tmp_path / "calibrated.yaml")

    held_out = hexcal.simulate_session(
        geometry, true, hexcal.instrument_for(hexcal.Setup(np.array(FRAMES[0]), dict(setup.targets))),
        hexcal.random_poses(geometry, 20, 99), noise, rng=5,
    )  # fmt: skip
    hexcal.write_session_data(tmp_path / "held_out.csv", held_out, geometry.euler)
    check = hexcal.read_session(tmp_path / "held_out.csv", tmp_path / "calibrated.yaml", geometry.euler)
    validation = hexcal.validate(result.geometry, check, nominal=geometry)
    summary, nominal = validation.calibrated.summary(), validation.nominal.summary()
    # uniform noise of half-width 0.015 mm per coordinate: σ 0.0087 mm; the calibrated model's
    # target error stays within a few σ of it, where the nominal machine's is millimetres
    assert summary["instrument_target_rms"] < 0.1
    assert nominal["instrument_target_rms"] > 10 * summary["instrument_target_rms"]

    instrument = hexcal.instrument_for(setup)
    corners = hexcal.candidate_poses(geometry, "corners")
    analysis = hexcal.analyse_poses(geometry, corners[:30], instrument=instrument, method="ml")
    assert analysis.rank == 45  # 57 varied, 12 gauges
    plan = hexcal.plan_selection(geometry, 20, noise, rng=0, candidates=corners, instrument=instrument)
    assert plan.poses.shape == (20, 6)
