"""Optimal selection of measurement poses: greedy selection, then exchange.

The information of a pose set is additive over its poses: with ``B_j`` (6 × n) the
noise-whitened identification Jacobian of pose ``j`` (:func:`information_blocks`), the
Fisher information of a set ``S`` is ``F(S) = Σ_{j∈S} B_jᵀ B_j``
(:func:`hexcal.estimation.bounds.fisher_information`, errors in variables). Adding or
removing a pose is a rank-6 update, so the effect of every candidate on a criterion is
computed at once, vectorised over the candidates, through 6 × 6 matrices:

- D: ``log det(F + BᵀB) = log det F + log det(I + B F⁻¹ Bᵀ)``;
- A: ``tr (F + BᵀB)⁻¹ = tr F⁻¹ - tr[(I + B F⁻¹ Bᵀ)⁻¹ B F⁻² Bᵀ]`` (Woodbury);
- E and O4 (``λmin`` and ``λmin / √λmax``, no closed form): every candidate is screened
  by the Rayleigh–Ritz value of ``F + BᵀB`` on the weakest eigenvectors of ``F``, and the
  best few are evaluated exactly.

:func:`select_poses` first picks poses greedily, one at a time (a small ridge keeps the
information invertible until the set identifies every parameter; E and O4 pick by D
until then), then exchanges poses of the set for candidates while that improves the
criterion (Fedorov 1972; Cook & Nachtsheim 1980's modified Fedorov exchange: each
position of the set in turn is given the best replacement among all candidates). A swap
is kept only when the exact criterion improves, so the exchange never ends worse than
its greedy start.

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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import PARAMETER_SCALE, select_parameters
from hexcal.errors import SelectionError
from hexcal.estimation.bounds import whitened_jacobian

CRITERIA = ("D", "A", "E", "O4")

#: Ridge of the greedy phase, relative to the mean diagonal of one pose's information:
#: a weak prior that keeps ``F`` invertible while the set is still too small.
GREEDY_RIDGE = 1e-6
#: Ridge of the scoring formulas once the set is large enough (numerical safety only).
SCORING_RIDGE = 1e-10
#: An eigenvalue below this fraction of the largest counts as zero (rank deficiency).
EIG_RTOL = 1e-12
#: Weakest eigenvectors used to screen candidates for E and O4, and candidates then
#: evaluated exactly.
SCREEN_DIMENSIONS = 6
SCREEN_SHORTLIST = 32




def information_blocks(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Per-pose noise-whitened identification Jacobians ``B_j``, shape (m, 6, n).

    Columns are the selected parameters in units of their characteristic scale
    (:data:`hexcal.estimation.identification.PARAMETER_SCALE`: 1 mm for joints and ``l0``, 1e-3 for
    gains), so ``Σ_j B_jᵀ B_j`` is the Fisher information in those units and its inverse
    the Cramér–Rao bound (mm² for the length parameters).
    """
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    wa = whitened_jacobian(geometry, poses, noise, mask)
    return wa.reshape(poses.shape[0], 6, -1) * PARAMETER_SCALE[mask]


def information_matrix(blocks: ArrayLike, indices: ArrayLike | None = None) -> NDArray[np.float64]:
    """``Σ_j B_jᵀ B_j`` over ``indices`` (default all), shape (n, n)."""
    b = np.asarray(blocks, dtype=float)
    if indices is not None:
        b = b[np.asarray(indices, dtype=np.intp)]
    flat = b.reshape(-1, b.shape[-1])
    return flat.T @ flat


def criterion_value(information: ArrayLike, criterion: str = "D") -> NDArray[np.float64] | float:
    """Value of an optimality criterion (larger is better) of information matrices.

    Parameters
    ----------
    information : array_like, shape (..., n, n)
    criterion : {"D", "A", "E", "O4"}

    Returns
    -------
    float or ndarray, shape (...)
        With ``λ`` the eigenvalues of ``F``: D ``mean(log λ)`` (the log of ``det(F)^(1/n)``);
        A ``-Σ 1/λ`` (minus the trace of the covariance); E ``λmin``; O4
        ``λmin / √λmax`` (the noise amplification index of the whitened Jacobian, whose
        singular values are ``√λ``). D and A are ``-inf`` for a singular ``F``.
    """
    _check_criterion(criterion)
    f = np.asarray(information, dtype=float)
    lam = np.linalg.eigvalsh(f)
    lmin, lmax = lam[..., 0], lam[..., -1]
    singular = lmin <= EIG_RTOL * np.maximum(lmax, np.finfo(float).tiny)
    with np.errstate(divide="ignore", invalid="ignore"):
        if criterion == "D":
            out = np.where(singular, -np.inf, np.mean(np.log(np.abs(lam)), axis=-1))
        elif criterion == "A":
            out = np.where(singular, -np.inf, -np.sum(1.0 / np.abs(lam), axis=-1))
        elif criterion == "E":
            out = np.where(singular, 0.0, lmin)
        else:
            out = np.where(singular, 0.0, lmin / np.sqrt(lmax))
    return float(out) if np.ndim(out) == 0 else out


def describe_value(value: float, criterion: str) -> str:
    """The criterion value in readable form."""
    if criterion == "D":
        return f"det(F)^(1/n) = {np.exp(value):.4g}"
    if criterion == "A":
        return f"trace(F⁻¹) = {-value:.4g} mm²"
    if criterion == "E":
        return f"λmin(F) = {value:.4g}"
    return f"λmin/√λmax = {value:.4g}"


def _check_criterion(criterion: str) -> None:
    if criterion not in CRITERIA:
        raise SelectionError(f"unknown criterion {criterion!r}; choose from {', '.join(CRITERIA)}")


def _full_rank(info: NDArray[np.float64]) -> bool:
    lam = np.linalg.eigvalsh(info)
    return bool(lam[-1] > 0 and lam[0] > 1e-10 * lam[-1])


def _logdet_spd(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """``log det`` of symmetric positive definite matrices (..., k, k)."""
    try:
        chol = np.linalg.cholesky(m)
    except np.linalg.LinAlgError:  # rounding made some barely definite: slower but safe
        sign, logdet = np.linalg.slogdet(m)
        return np.where(sign > 0, logdet, -np.inf)
    return 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)


def _mean_diagonal(blocks: NDArray[np.float64]) -> float:
    n_cand, _, p = blocks.shape
    return float(np.einsum("mij,mij->", blocks, blocks)) / (n_cand * p)


class _Scorer:
    """D or A value of ``F + B_jᵀ B_j`` for every candidate ``j`` (working state, private).

    Holds ``F`` (positive definite), ``F⁻¹``, ``log det F`` and, for all candidates,
    ``M_j = B_j F⁻¹ B_jᵀ`` and (A only) ``G_j = B_j F⁻² B_jᵀ``, all small (6 × 6). A rank-6
    change ``F ± B_cᵀ B_c`` updates them by Woodbury with two thin products over the
    candidates; they are recomputed from scratch every ``REFRESH`` changes against drift.
    """

    REFRESH = 8

    def __init__(
        self,
        blocks: NDArray[np.float64],
        info: NDArray[np.float64],
        criterion: str,
        fallback_ridge: float = 0.0,
    ) -> None:
        self.blocks = blocks
        self.flat = blocks.reshape(-1, blocks.shape[-1])
        self.criterion = criterion
        self.fallback_ridge = fallback_ridge  # added when a removal leaves F nearly singular
        self.reset(info)

    def reset(self, info: NDArray[np.float64]) -> None:
        n_cand, rows, p = self.blocks.shape
        self.info = np.array(info)
        self.inv = np.linalg.inv(info)
        self.logdet = float(np.linalg.slogdet(info)[1])
        q = (self.flat @ self.inv).reshape(n_cand, rows, p)
        self.m = np.matmul(q, np.swapaxes(self.blocks, 1, 2))
        self.g = np.matmul(q, np.swapaxes(q, 1, 2)) if self.criterion == "A" else None
        self.changes = 0

    def _changed(self, c: int, sign: float) -> tuple | None:
        """``(F⁻¹, M, G, log det F)`` of ``F + sign B_cᵀ B_c``; None if ill-conditioned."""
        n_cand, rows, _ = self.blocks.shape
        eye = np.eye(rows)
        factor = eye + sign * self.m[c]  # I ± B_c F⁻¹ B_cᵀ: det(F') = det(F) det(factor)
        if np.linalg.eigvalsh(factor)[0] < 1e-6:
            return None
        h = self.blocks[c] @ self.inv  # B_c F⁻¹
        t_inv = np.linalg.inv(sign * eye + self.m[c])
        mo = (self.flat @ h.T).reshape(n_cand, rows, rows)  # B F⁻¹ B_cᵀ
        mo_t = mo @ t_inv
        m_new = self.m - np.matmul(mo_t, np.swapaxes(mo, 1, 2))
        k = t_inv @ h
        inv_new = self.inv - h.T @ k
        g_new = None
        if self.g is not None:
            qk = (self.flat @ (self.inv @ k.T)).reshape(n_cand, rows, rows)  # B F⁻¹ Kᵀ
            cross = np.matmul(qk, np.swapaxes(mo, 1, 2))
            g_new = (
                self.g - cross - np.swapaxes(cross, 1, 2) + np.matmul(mo @ (k @ k.T), np.swapaxes(mo, 1, 2))
            )
        return inv_new, m_new, g_new, self.logdet + float(np.linalg.slogdet(factor)[1])

    def _scores(self, inv: NDArray, m: NDArray, g: NDArray | None, logdet: float) -> NDArray[np.float64]:
        im = m + np.eye(m.shape[-1])
        if self.criterion == "D":
            return (logdet + _logdet_spd(im)) / inv.shape[0]
        return np.einsum("nij,nij->n", np.linalg.inv(im), g) - np.trace(inv)

    def scores(self) -> NDArray[np.float64]:
        """Criterion of ``F + B_jᵀ B_j`` for every candidate, shape (N,)."""
        return self._scores(self.inv, self.m, self.g, self.logdet)

    def scores_without(self, c: int) -> NDArray[np.float64]:
        """Criterion of ``F - B_cᵀ B_c + B_jᵀ B_j`` for every candidate ``j``."""
        changed = self._changed(c, -1.0)
        if changed is None:
            # removing c leaves F nearly singular (a set barely larger than the parameters):
            # rank the replacements on a ridged copy; the exchange accepts on exact values
            rest = self.info - self.blocks[c].T @ self.blocks[c]
            rest += self.fallback_ridge * np.eye(rest.shape[0])
            return _Scorer(self.blocks, rest, self.criterion).scores()
        return self._scores(*changed)

    def change(self, c: int, sign: float) -> None:
        """Commit ``F <- F + sign B_cᵀ B_c``."""
        info = self.info + sign * self.blocks[c].T @ self.blocks[c]
        changed = None if self.changes + 1 >= self.REFRESH else self._changed(c, sign)
        if changed is None:
            self.reset(info)
            return
        self.inv, self.m, self.g, self.logdet = changed
        self.info = info
        self.changes += 1


def _best_by_eigenvalues(
    info: NDArray[np.float64],
    blocks: NDArray[np.float64],
    available: NDArray[np.bool_],
    criterion: str,
) -> tuple[int, float]:
    """Best candidate to add to a positive definite ``info`` for E or O4, and its value.

    Every candidate is screened by the Rayleigh–Ritz value of ``F + BᵀB`` on the
    ``SCREEN_DIMENSIONS`` weakest eigenvectors of ``F`` (an upper bound of its ``λmin``);
    the ``SCREEN_SHORTLIST`` best are evaluated exactly. The Ritz values themselves are
    computed only for a pool of candidates, grown until the smallest diagonal entry of
    the Ritz matrix (an upper bound of its smallest eigenvalue) proves that no candidate
    outside the pool could enter the shortlist.
    """
    n_cand, rows, p = blocks.shape
    lam, vec = np.linalg.eigh(info)
    w = min(p, SCREEN_DIMENSIONS)
    k = (blocks.reshape(-1, p) @ vec[:, :w]).reshape(n_cand, rows, w)
    factor = 1.0 / np.sqrt(lam[-1]) if criterion == "O4" else 1.0
    bound = (lam[:w] + np.einsum("nrk,nrk->nk", k, k)).min(axis=1) * factor
    bound = np.where(available, bound, -np.inf)
    n_short = min(SCREEN_SHORTLIST, int(available.sum()))
    order = np.argsort(-bound, kind="stable")
    size = min(n_cand, 8 * n_short)
    while True:
        pool = order[:size]
        ritz = np.matmul(np.swapaxes(k[pool], 1, 2), k[pool])
        ritz[:, np.arange(w), np.arange(w)] += lam[:w]
        screen = np.where(available[pool], np.linalg.eigvalsh(ritz)[:, 0] * factor, -np.inf)
        best = np.argsort(-screen, kind="stable")[:n_short]
        if size >= n_cand or bound[order[size]] <= screen[best[-1]]:
            break
        size = min(n_cand, 4 * size)
    short = pool[best]
    trial = info + np.matmul(np.swapaxes(blocks[short], 1, 2), blocks[short])
    exact = np.asarray(criterion_value(trial, criterion), dtype=float).reshape(-1)
    j = int(np.argmax(exact))
    return int(short[j]), float(exact[j])


def _argmax(scores: NDArray[np.float64], available: NDArray[np.bool_]) -> int:
    return int(np.argmax(np.where(available, scores, -np.inf)))


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

    Notes
    -----
    While the set does not yet identify every parameter the information carries a ridge,
    ``GREEDY_RIDGE`` times the mean diagonal of one candidate's information, and E and O4
    pick by D (both are 0 for every candidate until the rank is full).
    """
    _check_criterion(criterion)
    b = np.asarray(blocks, dtype=float)
    n_cand, _, p = b.shape
    chosen = [int(i) for i in np.asarray(start, dtype=np.intp).reshape(-1)]
    if n > n_cand:
        raise SelectionError(f"cannot select {n} poses from {n_cand} candidates")
    available = np.ones(n_cand, dtype=bool)
    available[chosen] = False
    info = information_matrix(b, chosen) if chosen else np.zeros((p, p))
    scale = _mean_diagonal(b)
    full = _full_rank(info)
    scorer: _Scorer | None = None
    for _ in range(n - len(chosen)):
        ridge = (SCORING_RIDGE if full else GREEDY_RIDGE) * scale * np.eye(p)
        crit = criterion if full or criterion in ("D", "A") else "D"
        if crit in ("D", "A"):
            if scorer is None or scorer.criterion != crit:
                scorer = _Scorer(b, info + ridge, crit)
            j = _argmax(scorer.scores(), available)
        else:
            j, _ = _best_by_eigenvalues(info + ridge, b, available, crit)
        chosen.append(j)
        available[j] = False
        info = info + b[j].T @ b[j]
        if not full and _full_rank(info):
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

    Notes
    -----
    A set that does not identify every parameter is first improved on the D criterion of
    its ridged information (as in the greedy phase), then on ``criterion``.
    """
    _check_criterion(criterion)
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

    crit, ridge, value_ridge = setting(_full_rank(info))
    value = criterion_value(info + value_ridge, crit)
    fallback = GREEDY_RIDGE * scale
    scorer = _Scorer(b, info + ridge, crit, fallback) if crit in ("D", "A") else None
    available = np.ones(n_cand, dtype=bool)
    available[chosen] = False
    swaps = visits = unchanged = slot = 0
    while unchanged < chosen.size and visits < max_passes * chosen.size:
        out = chosen[slot]
        available[out] = True
        rest = info - b[out].T @ b[out]
        if scorer is not None:
            j = _argmax(scorer.scores_without(out), available)
        else:
            j, _ = _best_by_eigenvalues(rest + ridge, b, available, crit)
        new_info = rest + b[j].T @ b[j]
        new_value = criterion_value(new_info + value_ridge, crit)
        unchanged += 1
        visits += 1
        if j != out and new_value > value + rtol * abs(value):
            chosen[slot], info, value = j, new_info, new_value
            swaps += 1
            unchanged = 0
            if crit != criterion and _full_rank(info):
                # the set now identifies everything: continue on the exact criterion
                crit, ridge, value_ridge = setting(True)
                value = criterion_value(info, crit)
                scorer = _Scorer(b, info + ridge, crit, fallback) if crit in ("D", "A") else None
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
    """
    _check_criterion(criterion)
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
    subset), shape (count, n): the seed paper's strategy is ``n=15`` of the 64 corners."""
    if n > n_candidates:
        raise SelectionError(f"cannot draw {n} of {n_candidates} candidates")
    gen = np.random.default_rng(rng)
    keys = gen.random((int(count), int(n_candidates)))
    return np.argsort(keys, axis=1)[:, : int(n)].astype(np.intp)
