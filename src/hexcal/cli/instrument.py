"""The instrument paths of the workflow commands: ``--setup FILE`` (issue 9).

A setup file (FORMATS.md "Measurement setup file") says what the instrument sees: target
positions (a laser tracker's reflectors) or a tool pose (a 6-DOF probe), in the instrument's
own frame, given or ``auto``. Each command of :mod:`hexcal.cli.calibrate`,
:mod:`hexcal.cli.plan` and :mod:`hexcal.cli.simulate` hands over to the function here when
``--setup`` is given:

- :func:`identify_with_setup`: maximum likelihood of machine and setup, with the frame
  registered (``auto``), the gauges removed by the documented convention, outliers checked (one
  target observation or a whole pose; ``--robust`` leaves them out); writes the calibrated
  geometry and, with ``--setup-out``, the calibrated setup;
- :func:`validate_with_setup`: held-out target (tool) positions predicted from leg readings;
- :func:`synthesize_with_setup`: simulated exports, targets lost at ``--missing-rate``;
- planning and Monte Carlo (``observability``, ``select``, ``simulate``): in
  :mod:`hexcal.cli.instrument_plan`.

Imports only the standard library and :mod:`hexcal.cli.common` at its top.
"""

from __future__ import annotations

import argparse
from typing import Any

from hexcal.cli.common import (
    CommandError,
    check_outputs,
    load_geometry,
    noise_from_args,
    parse_noise,
    warn,
)

#: ``--delimiter`` values and the characters they stand for.
DELIMITER_WORDS = {",": ",", ";": ";", "tab": "\t"}


def _delimiter(args: argparse.Namespace) -> str | None:
    word = getattr(args, "delimiter", None)
    return None if word is None else DELIMITER_WORDS[word]


def load_setup_for(path: str, geometry: Any) -> Any:
    from hexcal.io import load_setup

    return load_setup(path).in_euler(geometry.euler)


def read_instrument_data(path: str, setup: Any, geometry: Any, args: argparse.Namespace) -> Any:
    """Target measurements or tool poses of an export, as the setup says."""
    from hexcal.io import read_target_measurements, read_tool_measurements

    decimal = getattr(args, "decimal", None)
    if setup.kind == "targets":
        return read_target_measurements(path, setup, _delimiter(args), decimal)
    return read_tool_measurements(path, geometry.euler, _delimiter(args), decimal)


def setup_fit(args: argparse.Namespace, setup: Any) -> str:
    """``--fit`` plus the setup's groups (hold them with ``--fix frame`` / ``--fix targets``)."""
    groups = [g.strip() for g in args.fit.split(",") if g.strip()]
    return ",".join(groups + [g for g in ("frame", setup.kind) if g not in groups])


def _flagged(diag: Any, data: Any) -> tuple[str, ...]:
    """Labels of the groups an outlier check flags (``pose 7``, ``pose 7 target t2``)."""
    import numpy as np

    limit = diag.limit
    out = [f"pose {data.ids[j]}" for j in np.flatnonzero(np.nan_to_num(diag.pose_pvalue, nan=1.0) < limit)]
    for j, i in zip(*np.nonzero(np.nan_to_num(diag.target_pvalue, nan=1.0) < limit), strict=True):
        out.append(f"pose {data.ids[j]} target {data.names[i]}")
    return tuple(out)


# -- identify, validate, synthesize ---------------------------------------------------------


def identify_with_setup(args: argparse.Namespace) -> None:
    """``hexcal identify --setup``: machine and setup by maximum likelihood."""
    from hexcal.estimation import identify_instrument, identify_instrument_robust, instrument_diagnostics
    from hexcal.io import atomic_write, save_geometry, save_setup
    from hexcal.report import identification_dict, identification_report_dict, render
    from hexcal.report.instrument import instrument_dict

    if args.html:
        raise CommandError("--html is not available with --setup yet; use --report or --json")
    if args.method != "ml":
        raise CommandError(f"--method {args.method}: with --setup the estimator is ml (maximum likelihood)")
    check_outputs(args.out, args.setup_out, args.report, args.json)
    nominal = load_geometry(args.geometry, args.euler)
    setup = load_setup_for(args.setup, nominal)
    data = read_instrument_data(args.data, setup, nominal, args)
    noise = noise_from_args(args)
    fit, fix = setup_fit(args, setup), list(args.fix or ())
    if args.robust:
        robust = identify_instrument_robust(nominal, data, setup, noise, fit, fix)
        out, outliers, flagged = robust.fit, robust.outliers, ()
    else:
        out = identify_instrument(nominal, data, setup, noise, fit, fix)
        flagged = _flagged(instrument_diagnostics(out, data, noise, fit, fix), data)
        outliers = ()
    result = out.result
    inst = instrument_dict(out, outliers, flagged)
    text = render("identification", identification_report_dict(result, outliers, flagged))
    text += "\n" + render("instrument", inst)
    calibration = result.calibration_metadata()
    calibration.update(data=str(args.data), setup=str(args.setup), outliers=list(outliers))
    calibration["gauge"] = inst["convention"]
    name = f"{nominal.name}-calibrated" if nominal.name else "calibrated"
    save_geometry(result.geometry.replace(name=name, calibration=calibration), args.out)
    if args.setup_out:
        save_setup(out.setup, args.setup_out)
    if args.report:
        with atomic_write(args.report) as fh:
            fh.write(text + "\n")
    if args.json:
        with atomic_write(args.json) as fh:
            body = identification_dict(result, outliers, flagged) | {"instrument": inst}
            fh.write(render("identification", body, "json"))
    print(text)
    print(f"wrote the calibrated geometry to {args.out}")
    if args.setup_out:
        print(f"wrote the calibrated setup to {args.setup_out}")
    elif setup.auto:
        warn("hexcal: warning: the registered frame is not saved: give --setup-out FILE to validate later")


def validate_with_setup(args: argparse.Namespace) -> None:
    """``hexcal validate --setup``: held-out instrument values predicted from leg readings."""
    import numpy as np

    from hexcal.instruments import validate_instrument
    from hexcal.io import write_table
    from hexcal.report import render
    from hexcal.report.instrument import instrument_validation_dict

    if args.html:
        raise CommandError("--html is not available with --setup yet")
    if args.nominal:
        raise CommandError(
            "--nominal with --setup: the setup was calibrated with the machine; validate the "
            "nominal machine with its own identified setup instead"
        )
    check_outputs(args.out)
    geometry = load_geometry(args.geometry, args.euler)
    setup = load_setup_for(args.setup, geometry)
    if setup.auto:
        raise CommandError(
            f"{args.setup}: the instrument frame is auto; validate with the calibrated setup "
            "(hexcal identify --setup-out FILE)"
        )
    data = read_instrument_data(args.data, setup, geometry, args)
    result = validate_instrument(geometry, setup, data)
    label = geometry.name or str(args.geometry)
    print(render("instrument_validation", instrument_validation_dict({label: result}, setup.kind)))
    if args.out:
        errors = np.asarray(result.errors, dtype=float).reshape(len(data.readings), -1)
        columns = [f"{t}.error" for t in setup.target_names] if setup.kind == "targets" else ["error"]
        write_table(
            args.out,
            columns,
            errors,
            list(data.ids),
            comment="distance measured - predicted, mm; empty: target not seen",
            missing=True,
        )
        print(f"wrote the per-pose table to {args.out}")


def synthesize_with_setup(args: argparse.Namespace) -> None:
    """``hexcal synthesize --setup``: a simulated instrument export of a known machine and setup."""
    from hexcal.instruments import simulate_target_measurements, simulate_tool_measurements
    from hexcal.io import read_poses, write_measurements, write_target_measurements

    check_outputs(args.out)
    if not 0.0 <= args.missing_rate < 1.0:
        raise CommandError(f"--missing-rate must be in [0, 1), got {args.missing_rate}")
    nominal = load_geometry(args.nominal, args.euler)
    true = load_geometry(args.true, nominal.euler)
    setup = load_setup_for(args.setup, nominal)
    if setup.auto:
        raise CommandError(f"{args.setup}: simulation needs the true instrument frame, not auto")
    poses, _ = read_poses(args.poses, nominal.euler)
    noise = parse_noise(args.noise, args.noise_dist)
    comment = (
        f"simulated: nominal {args.nominal}, true {args.true}, setup {args.setup}, seed {args.seed}, "
        f"noise {noise}"
    )
    if setup.kind == "targets":
        data = simulate_target_measurements(nominal, true, setup, poses, noise, args.missing_rate, args.seed)
        comment += f", missing rate {args.missing_rate:g}"
        write_target_measurements(args.out, data, comment=comment)
        lost = int((~data.seen).sum())
        print(
            f"wrote {len(data)} simulated pose(s) of {len(setup.target_names)} target(s) to {args.out} "
            f"({lost} target observation(s) lost, {len(poses) - len(data)} pose(s) with none seen)"
        )
    else:
        if args.missing_rate:
            raise CommandError("--missing-rate applies to targets; the setup has a tool")
        data = simulate_tool_measurements(nominal, true, setup, poses, noise, args.seed)
        write_measurements(args.out, data, nominal.euler, args.orientation, comment=comment)
        print(f"wrote {len(data)} simulated tool pose(s) to {args.out}")
