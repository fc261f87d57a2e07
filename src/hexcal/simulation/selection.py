"""The pose selection study (``hexcal study selection``) as a study over the one runner.

How much do the measurement poses matter? By Monte Carlo, with the ``length`` estimator
(the paper's noise and machines by default), the mean absolute parameter error and its
Cramér–Rao bound of three pose strategies: random interior poses (new every trial), the
seed paper's 15 random of the 64 workspace corners (new every trial), and A-optimally
selected poses of the boundary grid (one fixed set per size, chosen before measuring,
:func:`hexcal.design.planning.optimal_poses`); and the same as the number of poses grows.
All strategies and sizes identify the same true machines (trial seeds of
:class:`~hexcal.simulation.protocol.TrialSeeds`), in batches.
"""

from __future__ import annotations

from collections.abc import Sequence

from hexcal.core import Geometry, NoiseModel
from hexcal.simulation.runner import Executor, Progress
from hexcal.simulation.study import STRATEGIES, StudyResult, fixed_strategy, run_study

#: Numbers of poses of the selection study (8 is the fewest ``length`` identifies 42
#: parameters from with redundancy; 64 all corners).
SELECTION_POSES = (8, 10, 15, 20, 30, 45, 64)


def run_selection_study(
    nominal: Geometry,
    true: Geometry | None = None,
    noise: NoiseModel | None = None,
    trials: int = 100,
    rng: int = 0,
    pose_counts: Sequence[int] = SELECTION_POSES,
    method: str = "length",
    jobs: int | None = 1,
    progress: Progress | None = None,
    *,
    executor: Executor | None = None,
    chunk_size: int | None = None,
) -> StudyResult:
    """Mean parameter error and bound of interior, corner and selected poses, per pose count.

    Parameters
    ----------
    nominal : Geometry
        The controller's geometry, with a workspace box.
    true : Geometry, optional
        The real machine (default nominal plus uniform ±5 mm in every trial).
    noise : NoiseModel, optional
        Default the seed paper's.
    trials : int
    rng : int
        Seed of the trials and of the selection's tie-breaking.
    pose_counts : sequence of int
        Numbers of poses (at most 64, the corners).
    method : str
        The estimator.
    jobs, progress, executor, chunk_size
        As in :func:`~hexcal.simulation.study.run_study`.

    Returns
    -------
    StudyResult
        Cells in the order strategy (``interior``, ``corners``, ``selected``), pose count.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> cells = run_selection_study(preset("paper-hmt"), preset("paper-hmt-true"), trials=2,
    ...                             pose_counts=(15,))
    >>> [(c.strategy, c.n_poses, c.row()["failures"]) for c in cells]
    [('interior', 15, 0), ('corners', 15, 0), ('selected', 15, 0)]
    """
    from hexcal.design.planning import optimal_poses

    counts = tuple(int(n) for n in pose_counts)
    if not counts or min(counts) < 1 or max(counts) > 64:
        raise ValueError(f"pose counts must be between 1 and 64, got {list(counts)}")
    noise = NoiseModel() if noise is None else noise
    selected = fixed_strategy({n: optimal_poses(nominal, n, noise, rng) for n in counts})
    strategies = {"interior": STRATEGIES["interior"], "corners": STRATEGIES["corners"], "selected": selected}
    return run_study(
        nominal,
        true,
        (method,),
        strategies,
        counts,
        {"paper": noise},
        trials,
        rng,
        jobs=jobs,
        progress=progress,
        executor=executor,
        chunk_size=chunk_size,
    )
