"""Planning subcommands of ``hexcal``: error maps, observability, candidates, pose selection.

- ``hexcal errormap``: the seed paper's Figs. 4-9 (PNG) and the numbers behind them (CSV),
  with the numbers that test its boundary and height claims;
- ``hexcal observability``: indices O1-O5, rank, lost parameter combinations, predicted
  parameter and pose errors of a pose file;
- ``hexcal candidates``: feasible candidate poses (corners, grids, random, files);
- ``hexcal select``: optimal measurement poses (greedy + exchange), beside the seed
  paper's strategy and random interior poses.

Known failures raise :class:`hexcal.cli.CommandError` or a ``ValueError`` subclass, which
``hexcal.cli.main`` prints as one line.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Figure names of the error maps, after the seed paper's figure numbers.
ERRORMAP_FIGURES = {
    "x": "fig4_x.png",
    "y": "fig5_y.png",
    "z": "fig6_z.png",
    "a-b": "fig7_a-b.png",
    "a-c": "fig8_a-c.png",
    "b-c": "fig9_b-c.png",
}

COMPARISON_DRAWS = 20


def register(sub: Any, geometry_help: str) -> None:
    """Add the planning subcommands to the ``hexcal`` parser's subparsers."""
    noise_help = "noise half-widths (uniform) or sigmas (normal), e.g. leg=0.01,pos=0.025,ang=0.001"

    p = sub.add_parser("errormap", help="pose error maps of random parameter errors (paper Figs. 4-9)")
    p.add_argument("--geometry", required=True, help=f"nominal {geometry_help} (with a workspace box)")
    p.add_argument("--out", required=True, help="folder for the figures, CSV tables and claims.json")
    p.add_argument("--levels", type=int, default=100, help="curves per sweep / z levels (paper: 100)")
    p.add_argument("--points", type=int, default=41, help="points along each line sweep")
    p.add_argument("--grid", type=int, default=21, help="points per angle of the angle grids")
    p.add_argument("--draws", type=int, default=200, help="random parameter error draws")
    p.add_argument("--amplitude", type=float, default=0.1, help="parameter errors uniform in ±this, mm")
    p.add_argument(
        "--fit", default="joints,l0", help="parameters with errors: joints, base, platform, l0, gains"
    )
    p.add_argument(
        "--method", default="linear", help="linear (first-order map) or exact (forward kinematics)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_errormap)

    p = sub.add_parser("observability", help="observability indices and predicted accuracy of a pose set")
    p.add_argument("--geometry", required=True, help=f"nominal {geometry_help}")
    p.add_argument("--poses", required=True, help="pose CSV file of the planned measurement poses")
    p.add_argument("--json", help="save the results as JSON")
    p.add_argument("--noise", help=noise_help)
    p.add_argument("--noise-dist", default="uniform", help="uniform (default) or normal")
    p.add_argument("--fit", default="joints,l0", help="parameter groups: joints, base, platform, l0, gains")
    p.add_argument("--test-poses", help="pose CSV file where to predict the pose error (default: corners)")
    p.add_argument("--scaling", default="norm", help="column scaling of the indices: norm, parameter, none")
    p.add_argument("--weighted", action="store_true", help="indices of the noise-whitened Jacobian")
    p.add_argument("--method", default="length", help="estimator residual predicted: length or paper")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_observability)

    p = sub.add_parser("candidates", help="feasible candidate measurement poses")
    p.add_argument("--geometry", required=True, help=f"nominal {geometry_help}")
    p.add_argument(
        "--candidates", default="grid", help="corners, grid[:L], edges[:L], random:N, FILE; join with +"
    )
    p.add_argument("--out", required=True, help="pose CSV file of the feasible candidates")
    p.add_argument("--min-distance", type=float, help="minimum singularity distance (default 0.05)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_candidates)

    p = sub.add_parser("select", help="select optimal measurement poses (greedy + exchange)")
    p.add_argument("--geometry", required=True, help=f"nominal {geometry_help}")
    p.add_argument("--n", type=int, default=15, help="number of poses (default 15, as the paper)")
    p.add_argument("--criterion", default="D", help="D, A, E or O4 (default D)")
    p.add_argument(
        "--candidates", default="grid", help="corners, grid[:L], edges[:L], random:N, FILE; join with +"
    )
    p.add_argument("--strategy", default="optimal", help="optimal (default) or paper (n random corners)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, help="pose CSV file of the selected poses")
    p.add_argument("--json", help="save the selection and predictions as JSON")
    p.add_argument("--noise", help=noise_help)
    p.add_argument("--noise-dist", default="uniform", help="uniform (default) or normal")
    p.add_argument("--fit", default="joints,l0", help="parameter groups: joints, base, platform, l0, gains")
    p.add_argument("--min-distance", type=float, help="minimum singularity distance (default 0.05)")
    p.add_argument("--no-exchange", action="store_true", help="greedy selection only")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_select)


# -- helpers ---------------------------------------------------------------------------------


def _choice(value: str, allowed: tuple[str, ...], option: str) -> str:
    from hexcal.cli import CommandError

    if value not in allowed:
        raise CommandError(f"{option}: unknown {value!r}; choose from {', '.join(allowed)}")
    return value


def _mask(fit: str) -> NDArray[np.bool_]:
    from hexcal.cli import CommandError
    from hexcal.core.parameters import select_parameters

    try:
        return select_parameters(fit)
    except ValueError as exc:
        raise CommandError(f"--fit: {exc}") from None


def _noise(args: argparse.Namespace) -> Any:
    from hexcal.cli import parse_noise

    return parse_noise(args.noise, _choice(args.noise_dist, ("uniform", "normal"), "--noise-dist"))


def _number(text: str, token: str, low: int) -> int:
    from hexcal.cli import CommandError

    try:
        value = int(text)
    except ValueError:
        raise CommandError(f"--candidates: {token!r}: {text!r} is not a whole number") from None
    if value < low:
        raise CommandError(f"--candidates: {token!r}: the number must be at least {low}")
    return value


def _candidates(spec: str, geometry: Any, seed: int) -> tuple[NDArray[np.float64], list[str]]:
    """Candidate poses and ids of a spec like ``corners+grid:3+random:1000+file.csv``."""
    from hexcal.cli import CommandError
    from hexcal.design.candidates import candidate_poses
    from hexcal.io import read_poses

    tokens = [t.strip() for t in spec.split("+") if t.strip()]
    if not tokens:
        raise CommandError("--candidates: empty; give corners, grid[:L], edges[:L], random:N or a file")
    rng = np.random.default_rng(seed)
    parts: list[NDArray[np.float64]] = []
    ids: list[str] = []
    for token in tokens:
        kind, _, arg = token.partition(":")
        if kind in ("corners", "grid", "edges", "random"):
            if kind == "corners" and arg:
                raise CommandError(f"--candidates: {token!r}: corners take no number")
            if kind == "random" and not arg:
                raise CommandError("--candidates: random needs a number, e.g. random:1000")
            count = _number(arg, token, 1 if kind == "random" else 2) if arg else None
            if kind in ("grid", "edges") and count is not None and count > 12:
                raise CommandError(f"--candidates: {token!r}: at most 12 grid levels (12⁶ poses)")
            try:
                poses = candidate_poses(geometry, kind, count, rng)
            except ValueError as exc:
                raise CommandError(f"--candidates: {token}: {exc}") from None
            prefix = {"corners": "c", "grid": "g", "edges": "e", "random": "r"}[kind]
            width = len(str(len(poses)))
            ids += [f"{prefix}{k:0{width}d}" for k in range(len(poses))]
        else:
            if not Path(token).exists():
                raise CommandError(
                    f"--candidates: {token!r} is neither corners, grid[:L], edges[:L], random:N nor a file"
                )
            poses, file_ids = read_poses(token, geometry.euler)
            ids += list(file_ids)
        parts.append(poses)
    seen: set[str] = set()
    for i in ids:
        if i in seen:
            raise CommandError(f"--candidates: pose id {i!r} appears twice; give the files distinct ids")
        seen.add(i)
    return np.concatenate(parts), ids


def _feasible(
    geometry: Any, poses: NDArray[np.float64], ids: list[str], min_distance: float | None
) -> tuple[NDArray[np.float64], list[str], str | None]:
    """Feasible candidates, their ids, and a warning naming the infeasible ones (or None).

    The warning is printed once the command has succeeded, so that a failure stays one line.
    """
    from hexcal.cli import CommandError, _id_list
    from hexcal.design.candidates import MIN_SINGULARITY_DISTANCE, check_feasibility

    threshold = MIN_SINGULARITY_DISTANCE if min_distance is None else min_distance
    if not (math.isfinite(threshold) and threshold >= 0):
        raise CommandError(f"--min-distance must be a finite value >= 0, got {threshold}")
    report = check_feasibility(geometry, poses, threshold)
    keep = np.flatnonzero(report.feasible)
    if keep.size == 0:
        raise CommandError(f"no feasible candidate pose: {report.summary()}")
    warning = None
    if report.n_infeasible:
        bad = np.flatnonzero(~report.feasible)
        detail = "; ".join(f"{ids[k]}: {report.reasons(k)}" for k in bad[:5])
        more = f" ... ids {_id_list([ids[k] for k in bad])}" if bad.size > 5 else ""
        warning = f"hexcal: warning: candidates: {report.summary()}; never proposed ({detail}{more})"
    return poses[keep], [ids[k] for k in keep], warning


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _fmt(value: float, unit: str = "mm", digits: int = 4) -> str:
    return f"{value:.{digits}g} {unit}" if math.isfinite(value) else "not identifiable"


# -- errormap -----------------------------------------------------------------------------------


def cmd_errormap(args: argparse.Namespace) -> None:
    from hexcal.cli import CommandError, _geometry
    from hexcal.design.errormap import claims, error_maps, format_claims
    from hexcal.io import atomic_write, write_table

    geometry = _geometry(args.geometry, args.euler)
    method = _choice(args.method, ("linear", "exact"), "--method")
    mask = _mask(args.fit)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CommandError(f"--out {out}: exists and is not a folder")
    if not out.parent.is_dir():
        raise CommandError(f"--out {out}: the folder {out.parent} does not exist")
    for name, value, low in (
        ("--levels", args.levels, 1),
        ("--points", args.points, 2),
        ("--grid", args.grid, 2),
    ):
        if value < low:
            raise CommandError(f"{name} must be at least {low}, got {value}")
    if args.draws < 1:
        raise CommandError(f"--draws must be at least 1, got {args.draws}")
    if not (math.isfinite(args.amplitude) and args.amplitude > 0):
        raise CommandError(f"--amplitude must be a finite value > 0, got {args.amplitude}")
    if geometry.workspace is None:
        raise CommandError("the geometry has no workspace box: add a 'workspace:' mapping")
    maps = error_maps(
        geometry,
        levels=args.levels,
        points=args.points,
        grid=args.grid,
        draws=args.draws,
        amplitude=args.amplitude,
        mask=mask,
        rng=args.seed,
        method=method,
    )
    summary = claims(maps)
    from hexcal.report.figures import plot_error_angles, plot_error_lines

    out.mkdir(exist_ok=True)
    pose_cols = ["x", "y", "z", "a", "b", "c"]
    for axis, line in maps.lines.items():
        rows = np.column_stack(
            [
                line.poses.reshape(-1, 6),
                np.repeat(line.levels, line.values.size),
                line.position.mean(-1).ravel(),
                line.position.std(-1).ravel(),
                line.orientation.mean(-1).ravel(),
                line.orientation.std(-1).ravel(),
            ]
        )
        write_table(
            out / f"errormap_{axis}.csv",
            [
                *pose_cols,
                f"level_{line.level_axis}",
                "position_mm",
                "position_sd_mm",
                "orientation_rad",
                "orientation_sd_rad",
            ],
            rows,
            comment=f"pose error along {axis}, mean and sd over {maps.draws} draws of parameter errors "
            f"uniform in ±{maps.amplitude:g} mm ({maps.method}); angles in rad",
        )
        plot_error_lines(line, out / ERRORMAP_FIGURES[axis])
    for name, grid in maps.angles.items():
        rows = np.column_stack([grid.poses.reshape(-1, 6), grid.position.ravel(), grid.orientation.ravel()])
        write_table(
            out / f"errormap_{name}.csv",
            [*pose_cols, "position_mm", "orientation_rad"],
            rows,
            comment=f"mean pose error over {name} at every z level, {maps.draws} parameter draws; rad",
        )
        plot_error_angles(grid, out / ERRORMAP_FIGURES[name])
    for name, ref in (("corners", maps.corners), ("interior", maps.interior)):
        write_table(
            out / f"errormap_{name}.csv",
            [*pose_cols, "position_mm", "orientation_rad"],
            np.column_stack([ref["poses"], ref["position"], ref["orientation"]]),
            comment=f"mean pose error at the {name} reference poses, {maps.draws} parameter draws; rad",
        )
    settings = {
        "geometry": geometry.name or str(args.geometry),
        "levels": args.levels,
        "points": args.points,
        "grid": args.grid,
        "draws": args.draws,
        "amplitude_mm": args.amplitude,
        "method": method,
        "seed": args.seed,
        "parameters": list(maps.parameters),
    }
    with atomic_write(out / "claims.json") as fh:
        json.dump({"settings": settings, "claims": summary}, fh, indent=2)
        fh.write("\n")
    print(
        f"Error maps of {geometry.name or args.geometry}: parameter errors uniform in "
        f"±{args.amplitude:g} mm, {args.draws} draws, {args.levels} levels ({method})"
    )
    print(format_claims(summary))
    print(
        f"wrote {len(ERRORMAP_FIGURES)} figures, {len(ERRORMAP_FIGURES) + 2} CSV tables and "
        f"claims.json to {out}"
    )


# -- observability ------------------------------------------------------------------------------


def _analysis_json(analysis: Any, n_test: int) -> dict[str, Any]:
    out: dict[str, Any] = {
        "n_poses": analysis.n_poses,
        "n_parameters": len(analysis.names),
        "rank": analysis.rank,
        **analysis.indices.as_dict(),
        "weighted": analysis.weighted,
        "unidentifiable": analysis.unidentifiable,
        "method": analysis.method,
        "noise": {
            "leg": analysis.noise.leg,
            "position": analysis.noise.position,
            "orientation": analysis.noise.orientation,
            "distribution": analysis.noise.distribution,
            "sigmas": list(analysis.noise.sigmas),
        },
        "predicted_mean_abs_error_mm": {
            "estimator": _finite(analysis.mean_error_estimator),
            "bound": _finite(analysis.mean_error_bound),
        },
        "parameters": {
            name: {"std_estimator": _finite(se), "std_bound": _finite(sb)}
            for name, se, sb in zip(analysis.names, analysis.std_estimator, analysis.std_bound, strict=True)
        },
    }
    out["condition_number"] = _finite(analysis.indices.condition_number)
    if n_test:
        pos, rot = analysis.test_position_rms, analysis.test_orientation_rms
        out["test_poses"] = {
            "n": n_test,
            "position_rms_mm": [_finite(v) for v in pos],
            "orientation_rms_rad": [_finite(v) for v in rot],
            "position_rms_mean_mm": _finite(float(np.mean(pos))),
            "position_rms_max_mm": _finite(float(np.max(pos))),
            "orientation_rms_mean_rad": _finite(float(np.mean(rot))),
            "orientation_rms_max_rad": _finite(float(np.max(rot))),
        }
    return out


def format_analysis(analysis: Any, fit: str, n_test: int) -> str:
    """The text report of ``hexcal observability``."""
    ind = analysis.indices
    n = len(analysis.names)
    sv = ind.singular_values
    noise = analysis.noise
    verdict = "all identifiable" if ind.rank == n else f"{n - ind.rank} combination(s) NOT identifiable"
    lines = [
        f"Observability of {analysis.n_poses} pose(s) for {n} parameters ({fit}); "
        f"{'noise-whitened ' if analysis.weighted else ''}identification Jacobian, "
        f"column scaling {ind.scaling}",
        f"  rank {ind.rank} of {n}: {verdict}",
        f"  singular values: {sv[0]:.4g} ... {sv[-1]:.4g} (condition number {ind.condition_number:.4g})",
        f"  O1 = {ind.O1:.4g}   geometric mean of the singular values (D-optimality; Borm & Menq 1991)",
        f"  O2 = {ind.O2:.4g}   σmin/σmax, inverse condition number (Driels & Pathre 1990)",
        f"  O3 = {ind.O3:.4g}   σmin (E-optimality; Nahvi, Hollerbach & Hayward 1994)",
        f"  O4 = {ind.O4:.4g}   σmin²/σmax, noise amplification index (Nahvi & Hollerbach 1996)",
        f"  O5 = {ind.O5:.4g}   1/Σ(1/σi) (A-optimality; Sun & Hollerbach 2008)",
    ]
    if analysis.unidentifiable:
        lines.append("  parameter changes these poses cannot see (each a direction δθ ∝ the sum):")
        lines += [f"    {c}" for c in analysis.unidentifiable]
    lines.append(
        f"Noise ({noise.distribution}): legs {noise.leg:g} mm, position {noise.position:g} mm, "
        f"orientation {noise.orientation:g} rad; standard deviations "
        + ", ".join(f"{s:.3g}" for s in noise.sigmas)
    )
    lines.append(
        f"Predicted mean absolute parameter error: {_fmt(analysis.mean_error_estimator)} "
        f"(identify, method {analysis.method}); Cramér-Rao bound {_fmt(analysis.mean_error_bound)}"
    )
    lines.append("Predicted standard deviation per parameter (estimator / bound; gains x1e-3):")
    cells = []
    for name, se, sb in zip(analysis.names, analysis.std_estimator, analysis.std_bound, strict=True):
        k = 1e3 if name.startswith("g") else 1.0
        cells.append(
            f"{name:>5} {se * k:.3f}/{sb * k:.3f}" if math.isfinite(se) else f"{name:>5}  not identifiable"
        )
    for start in range(0, len(cells), 6):
        lines.append("  " + "  ".join(cells[start : start + 6]))
    if n_test:
        pos, rot = analysis.test_position_rms, analysis.test_orientation_rms
        lines.append(
            f"Predicted pose error after calibration at {n_test} test pose(s), RMS: position mean "
            f"{_fmt(float(np.mean(pos)))}, max {_fmt(float(np.max(pos)))}; orientation mean "
            f"{_fmt(float(np.mean(rot)) * 1e3, 'mrad')}, max {_fmt(float(np.max(rot)) * 1e3, 'mrad')}"
        )
    return "\n".join(lines)


def cmd_observability(args: argparse.Namespace) -> None:
    from hexcal.cli import CommandError, _check_outputs, _geometry, _id_list
    from hexcal.core.workspace import workspace_corners
    from hexcal.design.candidates import check_feasibility
    from hexcal.design.identifiability import SCALINGS, analyse_poses
    from hexcal.io import atomic_write, read_poses

    _check_outputs(args.json)
    geometry = _geometry(args.geometry, args.euler)
    scaling = _choice(args.scaling, SCALINGS, "--scaling")
    method = _choice(args.method, ("length", "paper"), "--method")
    mask = _mask(args.fit)
    noise = _noise(args)
    poses, ids = read_poses(args.poses, geometry.euler)
    if args.test_poses:
        test, _ = read_poses(args.test_poses, geometry.euler)
    elif geometry.workspace is not None:
        test = workspace_corners(geometry)
    else:
        test = None
    try:
        analysis = analyse_poses(geometry, poses, noise, mask, test, scaling, method, args.weighted)
    except np.linalg.LinAlgError as exc:
        raise CommandError(f"{args.poses}: cannot analyse these poses ({exc})") from None
    report = check_feasibility(geometry, poses)
    if report.n_infeasible:
        bad = [ids[k] for k in np.flatnonzero(~report.feasible)]
        print(f"hexcal: warning: {args.poses}: {report.summary()} (ids {_id_list(bad)})", file=sys.stderr)
    n_test = 0 if test is None else len(test)
    print(format_analysis(analysis, args.fit, n_test))
    if args.json:
        with atomic_write(args.json) as fh:
            json.dump(_analysis_json(analysis, n_test), fh, indent=2)
            fh.write("\n")
        print(f"wrote {args.json}")


# -- candidates and select ---------------------------------------------------------------------


def cmd_candidates(args: argparse.Namespace) -> None:
    from hexcal.cli import _check_outputs, _geometry
    from hexcal.io import write_poses

    _check_outputs(args.out)
    geometry = _geometry(args.geometry, args.euler)
    poses, ids = _candidates(args.candidates, geometry, args.seed)
    feasible, kept, warning = _feasible(geometry, poses, ids, args.min_distance)
    if warning:
        print(warning, file=sys.stderr)
    write_poses(args.out, feasible, kept, comment=f"feasible candidates {args.candidates} (seed {args.seed})")
    print(f"wrote {len(kept)} feasible of {len(ids)} candidate pose(s) to {args.out}")


def _predicted(geometry: Any, pose_sets: NDArray[np.float64], noise: Any, mask: Any) -> tuple[float, float]:
    """Mean over pose sets (T, n, 6) of the predicted mean absolute error: estimator, bound."""
    from hexcal.design.identifiability import least_squares_covariance, mean_abs_error
    from hexcal.estimation.bounds import cramer_rao_covariance

    est = [mean_abs_error(least_squares_covariance(geometry, s, noise, mask), mask) for s in pose_sets]
    bound = [mean_abs_error(cramer_rao_covariance(geometry, s, noise, mask), mask) for s in pose_sets]
    return float(np.mean(est)), float(np.mean(bound))


def cmd_select(args: argparse.Namespace) -> None:
    import time

    from hexcal.cli import CommandError, _check_outputs, _geometry
    from hexcal.core.parameters import MIN_POSES
    from hexcal.core.workspace import box_corners, random_interior
    from hexcal.design.candidates import MIN_SINGULARITY_DISTANCE, check_feasibility
    from hexcal.design.selection import (
        CRITERIA,
        describe_value,
        information_blocks,
        random_subsets,
        select_poses,
    )
    from hexcal.io import atomic_write, write_poses

    _check_outputs(args.out, args.json)
    geometry = _geometry(args.geometry, args.euler)
    criterion = _choice(args.criterion, CRITERIA, "--criterion")
    strategy = _choice(args.strategy, ("optimal", "paper"), "--strategy")
    mask = _mask(args.fit)
    noise = _noise(args)
    n = args.n
    min_poses = MIN_POSES + (1 if mask[42:].any() else 0)
    if n < min_poses:
        raise CommandError(f"--n {n}: at least {min_poses} poses are needed to identify the parameters")
    rng = np.random.default_rng(args.seed)
    warning = None
    corners = corner_ids = None
    if geometry.workspace is not None:
        threshold = MIN_SINGULARITY_DISTANCE if args.min_distance is None else args.min_distance
        corner_ids = np.flatnonzero(
            check_feasibility(geometry, box_corners(geometry.workspace), threshold).feasible
        )
        corners = box_corners(geometry.workspace)[corner_ids]
    start = time.perf_counter()
    if strategy == "paper":
        if corners is None:
            raise CommandError("--strategy paper needs a geometry with a workspace box")
        if n > len(corners):
            raise CommandError(
                f"--n {n}: the paper's strategy draws from only {len(corners)} feasible corners"
            )
        chosen = random_subsets(len(corners), n, 1, rng)[0]
        poses, ids = corners[chosen], [f"c{int(corner_ids[k]):02d}" for k in chosen]
        label = f"{n} random feasible corners (the seed paper's strategy), seed {args.seed}"
        result = None
    else:
        candidates, cand_ids = _candidates(args.candidates, geometry, args.seed)
        feasible, kept, warning = _feasible(geometry, candidates, cand_ids, args.min_distance)
        if n > len(kept):
            dropped = f" ({len(cand_ids) - len(kept)} infeasible left out)" if warning else ""
            raise CommandError(f"--n {n}: only {len(kept)} feasible candidate pose(s){dropped}")
        blocks = information_blocks(geometry, feasible, noise, mask)
        result = select_poses(blocks, n, criterion, rng, exchange=not args.no_exchange)
        poses, ids = feasible[result.indices], [kept[k] for k in result.indices]
        label = (
            f"{criterion}-optimal from {len(kept)} feasible candidates ({args.candidates}), seed {args.seed}"
        )
    elapsed = time.perf_counter() - start
    from hexcal.design.identifiability import analyse_poses

    analysis = analyse_poses(geometry, poses, noise, mask)
    if analysis.rank < len(analysis.names):
        lost = analysis.unidentifiable
        raise CommandError(
            f"the selected poses identify only rank {analysis.rank} of {len(analysis.names)} parameters; "
            f"lost: {', '.join(lost[:4])}{' ...' if len(lost) > 4 else ''}"
        )
    rows = {"selected": (analysis.mean_error_estimator, analysis.mean_error_bound)}
    comparisons: dict[str, str] = {}
    if corners is not None and n <= len(corners):
        sets = corners[random_subsets(len(corners), n, COMPARISON_DRAWS, rng)]
        rows["paper"] = _predicted(geometry, sets, noise, mask)
        comparisons["paper"] = f"{n} random corners (the seed paper), mean of {COMPARISON_DRAWS} draws"
    if geometry.workspace is not None:
        interior = random_interior(geometry.workspace, COMPARISON_DRAWS * n, rng).reshape(-1, n, 6)
        rows["interior"] = _predicted(geometry, interior, noise, mask)
        comparisons["interior"] = f"{n} random interior poses, mean of {COMPARISON_DRAWS} draws"
    print(f"Selected {n} poses: {label}")
    if result is not None:
        print(
            f"  greedy {describe_value(result.greedy_value, criterion)} -> after {result.swaps} exchange(s) "
            f"{describe_value(result.value, criterion)} ({elapsed:.2f} s)"
        )
        print(f"  candidate indices: {' '.join(str(int(k)) for k in result.indices)}")
    print(f"  ids: {' '.join(ids)}")
    print("Predicted mean absolute parameter error (mm): identify (method length) | Cramér-Rao bound")
    print(f"  {'selected poses':<58} {rows['selected'][0]:8.4f} | {rows['selected'][1]:.4f}")
    for key, text in comparisons.items():
        est, bound = rows[key]
        print(f"  {text:<58} {est:8.4f} | {bound:.4f}")
    if "paper" in rows and strategy == "optimal":
        gain = 1 - rows["selected"][0] / rows["paper"][0]
        word = "lower" if gain >= 0 else "higher"
        print(f"  selected vs the paper's strategy: {abs(gain):.0%} {word} predicted error")
    if warning:
        print(warning, file=sys.stderr)
    write_poses(args.out, poses, ids, comment=f"hexcal select: {label}")
    if args.json:
        data = {
            "strategy": strategy,
            "criterion": criterion if result is not None else None,
            "n": n,
            "seed": args.seed,
            "candidates": args.candidates if result is not None else "corners",
            "ids": ids,
            "indices": [int(k) for k in result.indices] if result is not None else None,
            "value": result.value if result is not None else None,
            "greedy_value": result.greedy_value if result is not None else None,
            "swaps": result.swaps if result is not None else 0,
            "seconds": elapsed,
            "predicted_mean_abs_error_mm": {
                key: {"estimator": _finite(v[0]), "bound": _finite(v[1])} for key, v in rows.items()
            },
        }
        with atomic_write(args.json) as fh:
            json.dump(data, fh, indent=2)
            fh.write("\n")
    print(f"wrote {n} pose(s) to {args.out}")
