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

__version__ = "0.1.0"

# public name -> the layer package that exports it (each layer resolves its own submodule)
_PUBLIC = {
    "Geometry": "core",
    "preset": "core",
    "inverse_kinematics": "core",
    "forward_kinematics": "core",
    "pose_jacobian": "core",
    "leg_lengths": "core",
    "leg_readings": "core",
    "workspace_corners": "core",
    "random_poses": "core",
    "ParameterSet": "core",
    "select_parameters": "core",
    "Measurements": "instruments",
    "TargetMeasurements": "instruments",
    "MeasurementModel": "instruments",
    "FullPoseModel": "instruments",
    "ToolModel": "instruments",
    "TargetModel": "instruments",
    "Session": "instruments",
    "Setup": "instruments",
    "instrument_for": "instruments",
    "NoiseModel": "core",
    "estimate": "calibration",
    "ESTIMATORS": "estimation",
    "IdentificationResult": "estimation",
    "Problem": "estimation",
    "identify_robust": "estimation",
    "validate": "calibration",
    "compensate": "core",
    "analyse_poses": "design",
    "select_poses": "design",
    "candidate_poses": "design",
    "run_paper_experiment": "simulation",
    "run_study": "simulation",
    "load_geometry": "io",
    "save_geometry": "io",
    "load_setup": "io",
    "save_setup": "io",
    "read_target_measurements": "io",
    "read_tool_measurements": "io",
    "read_measurements": "io",
    "read_poses": "io",
    "write_poses": "io",
    "HexcalError": "errors",
}

__getattr__, __dir__, __all__ = attach(__name__, _PUBLIC)
__all__ = [*__all__, "__version__"]
