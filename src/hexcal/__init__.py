"""hexcal: kinematic calibration of hexapods (Stewart-Gough platforms, hexapod machine tools).

The public API below is lazy (PEP 562): ``import hexcal`` is cheap, and each name loads
its layer when first used. Layers: :mod:`hexcal.core` -> :mod:`hexcal.instruments` ->
:mod:`hexcal.estimation` -> :mod:`hexcal.calibration` -> :mod:`hexcal.design` -> :mod:`hexcal.simulation` ->
:mod:`hexcal.report` -> :mod:`hexcal.io` / :mod:`hexcal.cli`.

A notebook session: the seed paper's machine, the leg lengths of its home pose and back,
then a calibration from 20 simulated measurements at workspace corners.

>>> import hexcal
>>> nominal = hexcal.preset("paper-hmt")
>>> legs = hexcal.inverse_kinematics(nominal, nominal.home_pose)
>>> legs.round(2)
array([828.36, 828.36, 828.36, 828.36, 828.36, 828.36])
>>> hexcal.forward_kinematics(nominal, legs, guess=nominal.home_pose).poses.round(6)
array([  0.,   0., 800.,   0.,   0.,   0.])
>>> from hexcal.simulation import simulate_measurements
>>> poses = hexcal.workspace_corners(nominal)[:20]
>>> data = simulate_measurements(nominal, hexcal.preset("paper-hmt-true"), poses, hexcal.NoiseModel(), rng=0)
>>> result = hexcal.estimate(nominal, data, "length")
>>> result.rank, len(result.names)
(42, 42)

With an instrument in its own frame (a laser tracker, docs/formats.md "Setup file"), the
same few names do the whole calibration: ``setup = hexcal.load_setup("tracker.yaml")``,
``sessions = hexcal.read_sessions(["monday.csv", "tuesday.csv"], [setup], geometry.euler)``,
``result = hexcal.estimate(geometry, sessions, noise="auto")`` (one machine, each session
its own instrument frame, the noise learned from the data as ``hexcal identify`` does;
``result.verdict.status`` is pass, warn or fail), then
``hexcal.validate(result.geometry, held_out_session)`` (what ``hexcal validate`` does).

Public names
------------
- ``Geometry``, ``preset``, ``PRESETS``, ``load_geometry``, ``save_geometry``: the machine
  and its geometry file (docs/formats.md "Geometry file").
- ``inverse_kinematics``, ``forward_kinematics``, ``pose_jacobian``, ``leg_lengths``,
  ``leg_readings``, ``workspace_corners``, ``random_poses``: kinematics and the workspace.
- ``ParameterSet``, ``select_parameters``, ``NoiseModel``: the parameters a fit varies and
  the measurement noise.
- ``Setup``, ``load_setup``, ``save_setup``, ``instrument_for``, ``MeasurementModel``,
  ``FullPoseModel``, ``ToolModel``, ``TargetModel``: instruments and their setup files.
- ``Session``, ``read_session``, ``read_sessions``, ``write_session_data``, ``Measurements``,
  ``TargetMeasurements``, ``Covariates``, ``read_measurements``, ``write_measurements``,
  ``read_target_measurements``, ``write_target_measurements``, ``read_tool_measurements``:
  measurement sessions and their files (docs/formats.md "Sessions"); the covariates of their
  rows (time, leg temperatures, payload).
- ``read_poses``, ``write_poses``, ``read_legs``, ``write_legs``: pose and leg files.
- ``calibrate``, ``Calibration``: the calibration workflow (noise, leg model, outliers, the
  verdict, splits, predicted accuracy) and its result, reports and file.
- ``estimate``, ``ESTIMATORS``, ``IdentificationResult``, ``Problem``, ``identify_robust``,
  ``Verdict``: identification from one or several sessions, with its verdict.
- ``validate``, ``Validation``, ``ValidationResult``: the validation workflow on held-out data
  (the re-registration, what the calibration expected, the nominal machine beside, the ISO
  tests) and its result, reports and files; one geometry's prediction errors.
- ``compensate``: leg commands that bring the calibrated machine to targets.
- ``candidate_poses``, ``check_feasibility``, ``analyse_poses``, ``plan_selection``,
  ``select_poses``: planning (candidate poses, observability, optimal selection).
- ``simulate_session``, ``simulate_measurements``, ``run_study``, ``run_paper_experiment``:
  simulated sessions and Monte Carlo studies.
- ``HexcalError``, ``__version__``: the base class of hexcal's one-line errors; the version.
"""

import os as _os
import sys as _sys

# hexcal's linear algebra is many small matrices (6x6 blocks, 90x42 Jacobians), for which
# OpenBLAS's threads cost far more than they give: on a busy 2-core machine one 15-pose
# identification took 19 ms with threads and 2 ms without. Only a default: an explicit
# setting wins, and it has no effect if numpy was imported before hexcal.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

if _sys.argv[:1] == ["-m"] or _os.path.basename(_sys.argv[0] if _sys.argv else "") == "hexcal":
    # started as the command (``python -m hexcal`` or the ``hexcal`` script): SIGINT, SIGTERM
    # or SIGHUP (unless ignored, as under ``nohup``) during the start-up ends with one line,
    # no traceback, exit status 128 + the signal's number (``main`` installs the handlers
    # that clean up once a command runs)
    import signal as _signal

    _WORDS = {_signal.SIGINT: "interrupted", _signal.SIGTERM: "terminated", _signal.SIGHUP: "hung up"}

    def _startup_signal(signum: int, _frame: object) -> None:
        _os.write(2, f"hexcal: {_WORDS.get(signum, 'terminated')}\n".encode())
        _os._exit(128 + signum)

    for _sig in _WORDS:
        if _sig != _signal.SIGHUP or _signal.getsignal(_sig) != _signal.SIG_IGN:
            _signal.signal(_sig, _startup_signal)

from hexcal._lazy import attach  # noqa: E402


def _package_version() -> str:
    """The installed distribution's version: pyproject.toml's ``version`` is its one source."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("hexcal")
    except PackageNotFoundError:  # imported from a source tree that was never installed
        return "0+unknown"


__version__ = _package_version()

# public name -> the layer package that exports it (each layer resolves its own submodule)
_PUBLIC = {
    "Geometry": "core",
    "preset": "core",
    "PRESETS": "core",
    "inverse_kinematics": "core",
    "forward_kinematics": "core",
    "pose_jacobian": "core",
    "leg_lengths": "core",
    "leg_readings": "core",
    "workspace_corners": "core",
    "random_poses": "core",
    "ParameterSet": "core",
    "select_parameters": "core",
    "NoiseModel": "core",
    "compensate": "core",
    "Measurements": "instruments",
    "TargetMeasurements": "instruments",
    "Covariates": "instruments",
    "MeasurementModel": "instruments",
    "FullPoseModel": "instruments",
    "ToolModel": "instruments",
    "TargetModel": "instruments",
    "Session": "instruments",
    "Setup": "instruments",
    "instrument_for": "instruments",
    "ESTIMATORS": "estimation",
    "IdentificationResult": "estimation",
    "Problem": "estimation",
    "identify_robust": "estimation",
    "calibrate": "workflow",
    "Calibration": "workflow",
    "estimate": "calibration",
    "validate": "workflow",
    "Validation": "workflow",
    "ValidationResult": "calibration",
    "Verdict": "calibration",
    "analyse_poses": "design",
    "plan_selection": "design",
    "select_poses": "design",
    "candidate_poses": "design",
    "check_feasibility": "design",
    "simulate_session": "simulation",
    "simulate_measurements": "simulation",
    "run_paper_experiment": "simulation",
    "run_study": "simulation",
    "load_geometry": "io",
    "save_geometry": "io",
    "load_setup": "io",
    "save_setup": "io",
    "read_session": "io",
    "read_sessions": "io",
    "write_session_data": "io",
    "read_target_measurements": "io",
    "write_target_measurements": "io",
    "read_tool_measurements": "io",
    "read_measurements": "io",
    "write_measurements": "io",
    "read_poses": "io",
    "write_poses": "io",
    "read_legs": "io",
    "write_legs": "io",
    "HexcalError": "errors",
}

__getattr__, _dir, __all__ = attach(__name__, _PUBLIC)
__all__ = [*__all__, "__version__"]


def __dir__() -> list[str]:
    return sorted(__all__)
