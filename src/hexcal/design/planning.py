"""Campaign planning as the command line uses it: the A-optimal poses of the boundary grid,
the poses of the seed paper's strategy, and the predicted accuracy of a pose set beside
the paper's strategy and random interior poses.

Imports :mod:`hexcal.core`, :mod:`hexcal.estimation` and the rest of :mod:`hexcal.design`
(through the packages); returns plain arrays or dataclasses with ``to_dict()``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import Geometry, NoiseModel, box_corners, random_interior
from hexcal.design import (
    MIN_SINGULARITY_DISTANCE,
    analyse_poses,
    candidate_poses,
    check_feasibility,
    information_blocks,
    least_squares_covariance,
    mean_abs_error,
    random_subsets,
    select_poses,
)
from hexcal.errors import SelectionError

#: Random pose sets averaged for each comparison strategy.
COMPARISON_DRAWS = 20


def optimal_poses(
    nominal: Geometry, n: int, noise: NoiseModel, seed: int, instrument: Any = None
) -> NDArray[np.float64]:
    """``n`` A-optimal poses of the workspace boundary grid for the nominal geometry.

    A-optimality minimises the sum of the parameter variances, the criterion closest to
    the mean absolute parameter error that Table I reports. ``hexcal paper`` and
    ``hexcal simulate --strategies selected`` measure at these poses.

    Parameters
    ----------
    nominal : Geometry
        Nominal geometry, with a workspace box.
    n : int
        Number of poses.
    noise : NoiseModel
        Measurement noise the selection weighs the poses with.
    seed : int
        Seed of the selection's random tie-breaking.

    Returns
    -------
    ndarray, shape (n, 6)
        Poses (mm, rad) of the feasible boundary grid.

    Examples
    --------
    >>> from hexcal.core import NoiseModel, preset
    >>> optimal_poses(preset("paper-hmt"), 15, NoiseModel(), seed=0).shape
    (15, 6)
    """
    candidates = candidate_poses(nominal, "grid")
    candidates = candidates[check_feasibility(nominal, candidates).feasible]
    chosen = select_poses(
        information_blocks(nominal, candidates, noise, instrument=instrument), n, "A", rng=seed
    )
    return candidates[chosen.indices]


def feasible_corners(
    geometry: Geometry, min_distance: float | None = None
) -> tuple[NDArray[np.float64], NDArray[np.intp]] | tuple[None, None]:
    """The feasible corners of the workspace box and their indices among the 64.

    Returns ``(None, None)`` when the geometry has no workspace box.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> corners, index = feasible_corners(preset("paper-hmt"))
    >>> corners.shape, index[:3].tolist()
    ((64, 6), [0, 1, 2])
    """
    if geometry.workspace is None:
        return None, None
    threshold = MIN_SINGULARITY_DISTANCE if min_distance is None else min_distance
    corners = box_corners(geometry.workspace)
    index = np.flatnonzero(check_feasibility(geometry, corners, threshold).feasible)
    return corners[index], index


def predicted_error(
    geometry: Geometry,
    pose_sets: ArrayLike,
    noise: NoiseModel,
    mask: ArrayLike | None = None,
    instrument: Any = None,
    fix: Any = (),
) -> tuple[float, float]:
    """Mean over pose sets of the predicted mean absolute parameter error (mm).

    Parameters
    ----------
    geometry : Geometry
    pose_sets : array_like, shape (T, n, 6)
        ``T`` sets of ``n`` poses (mm, rad).
    noise : NoiseModel
    mask : array_like of bool, shape (48,), optional
        Parameters identified (default: joints and l0).

    Returns
    -------
    (float, float)
        Of ``identify`` (method length), and of the Cramér–Rao bound.

    Examples
    --------
    >>> from hexcal.core import NoiseModel, preset, workspace_corners
    >>> geometry = preset("paper-hmt")
    >>> est, bound = predicted_error(geometry, workspace_corners(geometry)[None, :15], NoiseModel())
    >>> 0 < bound <= est
    True
    """
    from hexcal.estimation import cramer_rao_covariance

    sets = np.asarray(pose_sets, dtype=float)
    from hexcal.design.instrument_table import planned_instrument

    if planned_instrument(geometry, instrument) is not None:
        errors = [
            analyse_poses(
                geometry, s, noise, mask, method="ml", weighted=True, instrument=instrument, fix=fix
            ).mean_error_bound
            for s in sets
        ]
        return float(np.mean(errors)), float(np.mean(errors))
    est = [mean_abs_error(least_squares_covariance(geometry, s, noise, mask), mask) for s in sets]
    bound = [mean_abs_error(cramer_rao_covariance(geometry, s, noise, mask), mask) for s in sets]
    return float(np.mean(est)), float(np.mean(bound))


@dataclass
class StrategyComparison:
    """Predicted mean absolute parameter error (mm) of a pose set beside other strategies.

    ``rows`` maps ``selected``, ``paper`` (random feasible corners, the seed paper's
    strategy) and ``interior`` (random interior poses) to (estimator, bound); a strategy
    the geometry does not allow is absent. ``descriptions`` says what each comparison is.
    """

    n: int
    rows: dict[str, tuple[float, float]]
    descriptions: dict[str, str] = field(default_factory=dict)
    stroke: dict[str, Any] | None = None

    @property
    def gain(self) -> float | None:
        """Relative reduction of the predicted error, selected against the paper's strategy."""
        if "paper" not in self.rows:
            return None
        return 1 - self.rows["selected"][0] / self.rows["paper"][0]

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form: ``predicted_mean_abs_error_mm`` (as ``hexcal select --json``) for
        ``identify``'s default estimator, maximum likelihood (``estimator``: its covariance is
        the Cramér–Rao ``bound``), with the unweighted least squares under ``length``; and
        ``comparisons`` (the descriptions)."""
        return {
            "predicted_mean_abs_error_mm": {
                key: {"estimator": bound, "bound": bound, "length": est}
                for key, (est, bound) in self.rows.items()
            },
            "comparisons": dict(self.descriptions),
            "method": "ml",
        } | ({"stroke_coverage": self.stroke} if self.stroke is not None else {})


def compare_strategies(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel,
    mask: ArrayLike | None = None,
    rng: np.random.Generator | int | None = None,
    corners: NDArray[np.float64] | None = None,
    draws: int = COMPARISON_DRAWS,
    instrument: Any = None,
    fix: Any = (),
) -> StrategyComparison:
    """Predicted accuracy of ``poses`` beside the seed paper's strategy and random interior poses.

    Parameters
    ----------
    geometry : Geometry
    poses : array_like, shape (n, 6)
        The selected poses (mm, rad).
    noise : NoiseModel
    mask : array_like of bool, shape (48,), optional
    rng : Generator or int, optional
        Draws the comparison pose sets: first ``draws`` subsets of the corners, then
        ``draws * n`` interior poses.
    corners : ndarray, shape (k, 6), optional
        Feasible corners for the paper's strategy (compared only if ``n <= k``); the
        interior comparison needs a workspace box.
    draws : int
        Pose sets averaged per comparison.
    instrument : MeasurementModel, optional
        What measures the poses (default the full pose); one that does not give the pose is
        compared by its maximum-likelihood bound.
    fix : sequence of str
        Parameters or groups held (an instrument's quantities).

    Raises
    ------
    SelectionError
        If ``poses`` do not identify all the parameters.

    Examples
    --------
    >>> from hexcal.core import NoiseModel, preset
    >>> geometry = preset("paper-hmt")
    >>> corners, _ = feasible_corners(geometry)
    >>> comparison = compare_strategies(geometry, corners[:15], NoiseModel(), rng=0, corners=corners)
    >>> sorted(comparison.rows)
    ['interior', 'paper', 'selected']
    """
    poses = np.asarray(poses, dtype=float)
    n = len(poses)
    rng = np.random.default_rng(rng)
    from hexcal.design.instrument_table import planned_instrument

    quiet = planned_instrument(geometry, instrument) is not None
    options = {"method": "ml", "weighted": True, "instrument": instrument, "fix": fix} if quiet else {}
    analysis = analyse_poses(geometry, poses, noise, mask, **options)
    if analysis.unidentifiable:
        lost = analysis.unidentifiable
        beyond = f" beyond the {len(analysis.gauges)} gauge freedoms" if analysis.gauges else ""
        raise SelectionError(
            f"the selected poses identify only rank {analysis.rank} of "
            f"{len(analysis.names) - len(analysis.gauges)} parameters{beyond}; "
            f"lost: {', '.join(lost[:4])}{' ...' if len(lost) > 4 else ''}"
        )
    rows = {"selected": (analysis.mean_error_estimator, analysis.mean_error_bound)}
    descriptions: dict[str, str] = {}
    if corners is not None and n <= len(corners):
        sets = corners[random_subsets(len(corners), n, draws, rng)]
        rows["paper"] = predicted_error(geometry, sets, noise, mask, instrument, fix)
        descriptions["paper"] = f"{n} random corners (the seed paper), mean of {draws} draws"
    if geometry.workspace is not None:
        interior = random_interior(geometry.workspace, draws * n, rng).reshape(-1, n, 6)
        rows["interior"] = predicted_error(geometry, interior, noise, mask, instrument, fix)
        descriptions["interior"] = f"{n} random interior poses, mean of {draws} draws"
    stroke = analysis.stroke.to_dict() if analysis.stroke is not None else None
    return StrategyComparison(n, rows, descriptions, stroke)


@dataclass
class PoseSelection:
    """Measurement poses chosen by a strategy, with their predicted accuracy.

    ``strategy`` is ``optimal`` (``selection`` the :class:`hexcal.design.SelectionResult`
    by ``criterion`` from the ``candidates`` spec) or ``paper`` (random feasible corners;
    ``selection`` None). ``poses`` (n, 6) in mm and rad, ``ids`` their names, ``label``
    says what was selected, ``seconds`` the time of the selection; ``noise`` the measurement
    noise the selection and its predictions assumed, ``instrument`` what measures.
    """

    strategy: str
    n: int
    seed: int
    poses: NDArray[np.float64]
    ids: list[str]
    label: str
    seconds: float
    comparison: StrategyComparison
    selection: Any | None = None
    criterion: str | None = None
    candidates: str = "corners"
    noise: NoiseModel | None = None
    instrument: str = "full pose in the base frame"

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form: the keys of ``hexcal select --json`` (in order), then ``comparisons``,
        ``label``, ``greedy_text`` and ``value_text`` (criterion values in words, or None),
        ``noise`` (the noise assumed, as :meth:`hexcal.NoiseModel.to_dict`, or None) and
        ``instrument``.

        Examples
        --------
        >>> from hexcal.core import NoiseModel, preset
        >>> geometry = preset("paper-hmt")
        >>> corners, _ = feasible_corners(geometry)
        >>> poses = corners[[0, 9, 18, 27, 36, 45, 54, 63, 5, 12, 23, 30, 41, 50, 58]]
        >>> comparison = compare_strategies(geometry, poses, NoiseModel(), rng=0)
        >>> chosen = PoseSelection("paper", 15, 0, poses, ["c00"] * 15, "15 corners", 0.0, comparison)
        >>> list(chosen.to_dict())[:6]
        ['strategy', 'criterion', 'n', 'seed', 'candidates', 'ids']
        """
        from hexcal.design import describe_value

        r = self.selection
        return {
            "strategy": self.strategy,
            "criterion": self.criterion if r is not None else None,
            "n": self.n,
            "seed": self.seed,
            "candidates": self.candidates if r is not None else "corners",
            "ids": list(self.ids),
            "indices": [int(k) for k in r.indices] if r is not None else None,
            "value": r.value if r is not None else None,
            "greedy_value": r.greedy_value if r is not None else None,
            "swaps": r.swaps if r is not None else 0,
            "seconds": self.seconds,
            **self.comparison.to_dict(),
            "label": self.label,
            "greedy_text": describe_value(r.greedy_value, self.criterion) if r is not None else None,
            "value_text": describe_value(r.value, self.criterion) if r is not None else None,
            "noise": None if self.noise is None else self.noise.to_dict(),
            "instrument": self.instrument,
        }


def plan_selection(
    geometry: Geometry,
    n: int,
    noise: NoiseModel,
    mask: ArrayLike | None = None,
    rng: np.random.Generator | int | None = None,
    *,
    strategy: str = "optimal",
    candidates: NDArray[np.float64] | None = None,
    candidate_ids: list[str] | None = None,
    criterion: str = "A",
    exchange: bool = True,
    min_distance: float | None = None,
    spec: str = "grid",
    seed: int = 0,
    instrument: Any = None,
    fix: Any = (),
) -> PoseSelection:
    """Measurement poses by a strategy, with their predicted accuracy beside the others.

    ``strategy`` ``optimal``: ``criterion``-optimal poses among the feasible ``candidates``
    (greedy and exchange on the per-pose information of ``instrument``, default the full
    pose); ``paper``: ``n`` random feasible corners (the seed paper's strategy). The
    comparison (:func:`compare_strategies`) is for the same instrument. ``spec`` and ``seed``
    only describe the selection.

    Raises
    ------
    SelectionError
        A strategy the geometry does not allow, too few candidates, or poses that do not
        identify the parameters.
    """
    import time

    from hexcal.core.machine import leg_columns
    from hexcal.core.noise import require_noise
    from hexcal.design.instrument_table import default_flags

    require_noise(noise, "every predicted accuracy")
    flags = default_flags(geometry) if mask is None else np.asarray(mask, dtype=bool)
    per_leg = int(np.max(flags[leg_columns(geometry.leg_model)].sum(axis=1)))
    if n < per_leg:
        raise SelectionError(f"{n} poses: at least {per_leg} are needed to identify the parameters")
    rng = np.random.default_rng(rng)
    corners, corner_ids = feasible_corners(geometry, min_distance)
    start = time.perf_counter()
    result = None
    if strategy == "paper":
        if corners is None:
            raise SelectionError("the paper's strategy needs a geometry with a workspace box")
        if n > len(corners):
            raise SelectionError(
                f"{n} poses: the paper's strategy draws from only {len(corners)} feasible corners"
            )
        chosen = random_subsets(len(corners), n, 1, rng)[0]
        poses, ids = corners[chosen], [f"c{int(corner_ids[k]):02d}" for k in chosen]
        label = f"{n} random feasible corners (the seed paper's strategy), seed {seed}"
    elif strategy == "optimal":
        if candidates is None or len(candidates) < n:
            have = 0 if candidates is None else len(candidates)
            raise SelectionError(f"{n} poses: only {have} feasible candidate pose(s)")
        blocks = information_blocks(geometry, candidates, noise, mask, instrument, fix)
        result = select_poses(blocks, n, criterion, rng, exchange=exchange)
        kept = candidate_ids or [str(k) for k in range(len(candidates))]
        poses, ids = candidates[result.indices], [kept[k] for k in result.indices]
        label = f"{criterion}-optimal from {len(kept)} feasible candidates ({spec}), seed {seed}"
    else:
        raise SelectionError(f"unknown strategy {strategy!r}; choose from optimal, paper")
    seconds = time.perf_counter() - start
    comparison = compare_strategies(
        geometry, poses, noise, mask, rng, corners, instrument=instrument, fix=fix
    )
    return PoseSelection(
        strategy,
        n,
        seed,
        poses,
        ids,
        label,
        seconds,
        comparison,
        selection=result,
        criterion=criterion,
        candidates=spec,
        noise=noise,
        instrument="full pose in the base frame" if instrument is None else instrument.describe(),
    )
