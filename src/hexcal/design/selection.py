"""Optimal selection of measurement poses: greedy selection, then exchange.

:func:`select_poses` first picks poses greedily, one at a time (a small ridge keeps the
information invertible until the set identifies every parameter; E and O4 pick by D
until then), then exchanges poses of the set for candidates while that improves the
criterion (Fedorov 1972; Cook & Nachtsheim 1980's modified Fedorov exchange: each
position of the set in turn is given the best replacement among all candidates). A swap
is kept only when the exact criterion improves, so the exchange never ends worse than
its greedy start. The criteria and the rank-6 updates that score every candidate at once
are in :mod:`hexcal.design.criteria`. Imports :mod:`hexcal.core` and that module.

References
----------
.. [1] V. V. Fedorov, Theory of Optimal Experiments, Academic Press, 1972.
.. [2] T. J. Mitchell, "An algorithm for the construction of D-optimal experimental
   designs," Technometrics 16(2), 203-210, 1974. doi:10.1080/00401706.1974.10489175
.. [3] R. D. Cook and C. J. Nachtsheim, "A comparison of algorithms for constructing exact
   D-optimal designs," Technometrics 22(3), 315-324, 1980. doi:10.1080/00401706.1980.10486162
.. [4] Y. Sun and J. M. Hollerbach, "Observability index selection for robot calibration,"
   IEEE ICRA 2008, 831-836. doi:10.1109/ROBOT.2008.4543242
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.progress import task
from hexcal.design.criteria import (
    GREEDY_RIDGE,
    SCORING_RIDGE,
    Scorer,
    best_by_eigenvalues,
    check_criterion,
    criterion_value,
    full_rank,
    information_matrix,
)
from hexcal.errors import SelectionError


def _argmax(scores: NDArray[np.float64], available: NDArray[np.bool_]) -> int:
    return int(np.argmax(np.where(available, scores, -np.inf)))


def _mean_diagonal(blocks: NDArray[np.float64]) -> float:
    n_cand, _, p = blocks.shape
    return float(np.einsum("mij,mij->", blocks, blocks)) / (n_cand * p)


@dataclass(frozen=True)
class SelectionResult:
    """Outcome of :func:`select_poses`.

    Attributes
    ----------
    indices : ndarray of int, shape (n,)
        Chosen candidates (indices into the candidate array), in the order the greedy
        phase chose them (exchanged positions keep their place).
    criterion : str
    value : float
        Criterion of the chosen set (:func:`criterion_value`; larger is better).
    greedy_indices : ndarray of int, shape (n,)
    greedy_value : float
        The set and value after the greedy phase, before any exchange.
    swaps : int
        Exchanges made.
    passes : int
        Cycles of the exchange over the positions of the set (started ones count).
    """

    indices: NDArray[np.intp]
    criterion: str
    value: float
    greedy_indices: NDArray[np.intp]
    greedy_value: float
    swaps: int
    passes: int

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (for JSON).

        >>> result = select_poses(np.eye(2)[:, None, :], 2, "D")
        >>> result.to_dict()["indices"], result.to_dict()["swaps"]
        ([0, 1], 0)
        """
        return {
            "criterion": self.criterion,
            "indices": [int(k) for k in self.indices],
            "value": float(self.value),
            "greedy_indices": [int(k) for k in self.greedy_indices],
            "greedy_value": float(self.greedy_value),
            "swaps": int(self.swaps),
            "passes": int(self.passes),
        }


def greedy_selection(
    blocks: ArrayLike,
    n: int,
    criterion: str = "D",
    start: ArrayLike = (),
) -> NDArray[np.intp]:
    """Pick ``n`` candidates one at a time, each the best addition to those before.

    Parameters
    ----------
    blocks : array_like, shape (N, 6, p)
        Per-candidate information blocks (:func:`information_blocks`).
    n : int
        Size of the set (including ``start``).
    criterion : {"D", "A", "E", "O4"}
    start : array_like of int
        Candidates the set starts from.

    Returns
    -------
    ndarray of int, shape (n,)

    Examples
    --------
    >>> greedy_selection(np.array([[[1.0, 0.0]], [[0.0, 1.0]], [[2.0, 2.0]]]), 2).tolist()
    [2, 0]

    Notes
    -----
    While the set does not yet identify every parameter the information carries a ridge,
    ``GREEDY_RIDGE`` times the mean diagonal of one candidate's information, and E and O4
    pick by D (both are 0 for every candidate until the rank is full).
    """
    check_criterion(criterion)
    b = np.asarray(blocks, dtype=float)
    n_cand, _, p = b.shape
    chosen = [int(i) for i in np.asarray(start, dtype=np.intp).reshape(-1)]
    if n > n_cand:
        raise SelectionError(f"cannot select {n} poses from {n_cand} candidates")
    available = np.ones(n_cand, dtype=bool)
    available[chosen] = False
    info = information_matrix(b, chosen) if chosen else np.zeros((p, p))
    scale = _mean_diagonal(b)
    full = full_rank(b, chosen)
    scorer: Scorer | None = None
    with task("greedy selection", n - len(chosen)) as step:
        for _ in range(n - len(chosen)):
            step()
            ridge = (SCORING_RIDGE if full else GREEDY_RIDGE) * scale * np.eye(p)
            crit = criterion if full or criterion in ("D", "A") else "D"
            if crit in ("D", "A"):
                if scorer is None or scorer.criterion != crit:
                    scorer = Scorer(b, info + ridge, crit)
                j = _argmax(scorer.scores(), available)
            else:
                j, _ = best_by_eigenvalues(info + ridge, b, available, crit)
            chosen.append(j)
            available[j] = False
            info = info + b[j].T @ b[j]
            if not full and full_rank(b, chosen):
                full, scorer = True, None  # drop the ridge: rebuild the scorer without it
            elif scorer is not None:
                scorer.change(j, 1.0)
    return np.asarray(chosen, dtype=np.intp)


def exchange_selection(
    blocks: ArrayLike,
    indices: ArrayLike,
    criterion: str = "D",
    max_passes: int = 50,
    rtol: float = 1e-9,
) -> tuple[NDArray[np.intp], int, int]:
    """Improve a set by exchanging its poses for candidates (modified Fedorov exchange).

    The positions of the set are visited in turn, cyclically; the pose at a position is
    replaced by the candidate that gives the best criterion with the other poses, when
    that beats the current value by more than ``rtol`` (relative). The exchange ends
    when a whole cycle of positions since the last swap changed nothing (a local optimum
    for single exchanges), or after ``max_passes`` cycles.

    Returns
    -------
    indices : ndarray of int, shape (n,)
    swaps : int
    passes : int
        Cycles over the positions (started ones count).

    Examples
    --------
    >>> blocks = np.array([[[2.0, 0.0]], [[0.0, 1.0]], [[1.0, 2.0]]])
    >>> indices, swaps, passes = exchange_selection(blocks, [0, 1], "D")
    >>> indices.tolist(), swaps
    ([0, 2], 1)

    Notes
    -----
    A set that does not identify every parameter is first improved on the D criterion of
    its ridged information (as in the greedy phase), then on ``criterion``.
    """
    check_criterion(criterion)
    b = np.asarray(blocks, dtype=float)
    n_cand, _, p = b.shape
    chosen = np.array(indices, dtype=np.intp)
    info = information_matrix(b, chosen)
    scale = _mean_diagonal(b)

    def setting(full: bool) -> tuple[str, NDArray, NDArray]:
        """(criterion, ridge of the scores, ridge of the accepted value)."""
        if full:
            return criterion, SCORING_RIDGE * scale * np.eye(p), np.zeros((p, p))
        ridge = GREEDY_RIDGE * scale * np.eye(p)
        return ("D" if criterion in ("E", "O4") else criterion), ridge, ridge

    crit, ridge, value_ridge = setting(full_rank(b, chosen))
    value = criterion_value(info + value_ridge, crit)
    fallback = GREEDY_RIDGE * scale
    scorer = Scorer(b, info + ridge, crit, fallback) if crit in ("D", "A") else None
    available = np.ones(n_cand, dtype=bool)
    available[chosen] = False
    swaps = visits = unchanged = slot = 0
    with task("exchange", None) as step:
        while unchanged < chosen.size and visits < max_passes * chosen.size:
            step()
            out = chosen[slot]
            available[out] = True
            rest = info - b[out].T @ b[out]
            if scorer is not None:
                j = _argmax(scorer.scores_without(out), available)
            else:
                j, _ = best_by_eigenvalues(rest + ridge, b, available, crit)
            new_info = rest + b[j].T @ b[j]
            new_value = criterion_value(new_info + value_ridge, crit)
            unchanged += 1
            visits += 1
            if j != out and new_value > value + rtol * abs(value):
                chosen[slot], info, value = j, new_info, new_value
                swaps += 1
                unchanged = 0
                if crit != criterion and full_rank(b, chosen):
                    # the set now identifies everything: continue on the exact criterion
                    crit, ridge, value_ridge = setting(True)
                    value = criterion_value(info, crit)
                    scorer = Scorer(b, info + ridge, crit, fallback) if crit in ("D", "A") else None
                elif scorer is not None:
                    scorer.change(j, 1.0)  # add first: F stays well conditioned in between
                    scorer.change(out, -1.0)
            available[chosen[slot]] = False
            slot = (slot + 1) % chosen.size
    return chosen, swaps, -(-visits // chosen.size)


def select_poses(
    blocks: ArrayLike,
    n: int,
    criterion: str = "D",
    rng: np.random.Generator | int | None = None,
    exchange: bool = True,
    start: ArrayLike = (),
) -> SelectionResult:
    """Select ``n`` measurement poses from candidates: greedy, then exchange.

    Parameters
    ----------
    blocks : array_like, shape (N, 6, p)
        Per-candidate information blocks (:func:`information_blocks`).
    n : int
        Number of poses to select.
    criterion : {"D", "A", "E", "O4"}
        Optimality criterion of the information (:func:`criterion_value`).
    rng : Generator, int or None
        Breaks ties: the candidates are visited in a seeded random order, so that equally
        good candidates (the symmetric corners of a box, say) are chosen reproducibly.
        ``None`` keeps the given order.
    exchange : bool
        Improve the greedy set by exchange (:func:`exchange_selection`).
    start : array_like of int
        Candidates the greedy phase starts from (the exchange may replace them).

    Returns
    -------
    SelectionResult
        Indices refer to the candidates as given.

    Examples
    --------
    Three candidates of one row each for two parameters; the first and the third span the
    largest area (``det F = 16``):

    >>> blocks = np.array([[[2.0, 0.0]], [[0.0, 1.0]], [[1.0, 2.0]]])
    >>> result = select_poses(blocks, 2, "D", rng=0)
    >>> sorted(result.indices.tolist()), round(result.value, 4)
    ([0, 2], 1.3863)
    """
    check_criterion(criterion)
    b = np.asarray(blocks, dtype=float)
    if b.ndim != 3:
        raise ValueError(f"information blocks must have shape (N, rows, n), got {b.shape}")
    n = int(n)
    if n < 1:
        raise SelectionError(f"the number of poses must be at least 1, got {n}")
    if n > b.shape[0]:
        raise SelectionError(f"cannot select {n} poses from {b.shape[0]} feasible candidate(s)")
    order = np.arange(b.shape[0]) if rng is None else np.random.default_rng(rng).permutation(b.shape[0])
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.size)
    perm = b[order]
    start_perm = inverse[np.asarray(start, dtype=np.intp).reshape(-1)]
    greedy = greedy_selection(perm, n, criterion, start_perm)
    greedy_value = criterion_value(information_matrix(perm, greedy), criterion)
    chosen, swaps, passes = greedy, 0, 0
    if exchange:
        chosen, swaps, passes = exchange_selection(perm, greedy, criterion)
    value = criterion_value(information_matrix(perm, chosen), criterion)
    return SelectionResult(
        indices=order[chosen],
        criterion=criterion,
        value=float(value),
        greedy_indices=order[greedy],
        greedy_value=float(greedy_value),
        swaps=swaps,
        passes=passes,
    )


def random_subsets(
    n_candidates: int, n: int, count: int, rng: np.random.Generator | int | None = None
) -> NDArray[np.intp]:
    """``count`` random subsets of ``n`` of ``n_candidates`` (without repetition within a
    subset), shape (count, n): the seed paper's strategy is ``n=15`` of the 64 corners.

    >>> random_subsets(64, 15, 3, rng=0).shape
    (3, 15)
    """
    if n > n_candidates:
        raise SelectionError(f"cannot draw {n} of {n_candidates} candidates")
    gen = np.random.default_rng(rng)
    keys = gen.random((int(count), int(n_candidates)))
    return np.argsort(keys, axis=1)[:, : int(n)].astype(np.intp)
