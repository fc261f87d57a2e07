"""Optimality criteria of the Fisher information, and how a candidate pose changes them.

The information of a pose set is additive over its poses: with ``B_j`` (6 × n) the
noise-whitened identification Jacobian of pose ``j`` (:func:`information_blocks`), the
Fisher information of a set ``S`` is ``F(S) = Σ_{j∈S} B_jᵀ B_j``
(:func:`hexcal.estimation.fisher_information`, errors in variables). Adding or removing a
pose is a rank-6 update, so the effect of every candidate on a criterion is computed at
once, vectorised over the candidates, through 6 × 6 matrices (:class:`Scorer`):

- D: ``log det(F + BᵀB) = log det F + log det(I + B F⁻¹ Bᵀ)``;
- A: ``tr (F + BᵀB)⁻¹ = tr F⁻¹ - tr[(I + B F⁻¹ Bᵀ)⁻¹ B F⁻² Bᵀ]`` (Woodbury);
- E and O4 (``λmin`` and ``λmin / √λmax``, no closed form): every candidate is screened
  by the Rayleigh–Ritz value of ``F + BᵀB`` on the weakest eigenvectors of ``F``, and the
  best few are evaluated exactly (:func:`best_by_eigenvalues`).

Whether a set identifies every parameter (:func:`full_rank`) is judged by the rank rule
of :mod:`hexcal.core.linalg`. Imports :mod:`hexcal.core` and :mod:`hexcal.estimation`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import PARAMETER_SCALE, Geometry, NoiseModel, scaled_svd, select_parameters
from hexcal.core import numerical_rank as rank_of_singular_values
from hexcal.errors import SelectionError
from hexcal.estimation import whitened_jacobian

CRITERIA = ("D", "A", "E", "O4")

#: Ridge of the greedy phase, relative to the mean diagonal of one pose's information:
#: a weak prior that keeps ``F`` invertible while the set is still too small.
GREEDY_RIDGE = 1e-6
#: Ridge of the scoring formulas once the set is large enough (numerical safety only).
SCORING_RIDGE = 1e-10
#: Convention of :func:`criterion_value`: an information whose smallest eigenvalue is
#: below this fraction of the largest has the value of a singular one (D and A ``-inf``,
#: E and O4 0). A guard of the value, not the identifiability judgement (:func:`full_rank`).
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
    instrument: Any = None,
    fix: Any = (),
    covariates: Any = None,
) -> NDArray[np.float64]:
    """Per-pose noise-whitened identification Jacobians ``B_j``, shape (m, 6, n); under the
    poses' ``covariates`` (a leg model that reads them).

    Columns are the selected parameters in units of their characteristic scale
    (:data:`hexcal.core.PARAMETER_SCALE`: 1 mm for joints and ``l0``, 1e-3 for
    gains), so ``Σ_j B_jᵀ B_j`` is the Fisher information in those units and its inverse
    the Cramér–Rao bound (mm² for the length parameters).

    >>> from hexcal.core import preset, workspace_corners
    >>> machine = preset("paper-hmt")
    >>> information_blocks(machine, workspace_corners(machine)).shape
    (64, 6, 42)
    """
    from hexcal.design.instrument_table import planned_instrument

    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    through_problem = planned_instrument(geometry, instrument)
    if through_problem is not None:
        return instrument_blocks(geometry, through_problem, poses, noise, mask, fix, covariates)
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    wa = whitened_jacobian(geometry, poses, noise, mask)
    return wa.reshape(poses.shape[0], 6, -1) * PARAMETER_SCALE[mask]


def instrument_blocks(
    geometry: Geometry,
    instrument: Any,
    poses: ArrayLike,
    noise: NoiseModel | None,
    mask: Any,
    fix: Any = (),
    covariates: Any = None,
) -> NDArray[np.float64]:
    """Per-candidate information rows ``B_j`` of an instrument that does not give the pose:
    the pose-eliminated, noise-whitened rows (:func:`hexcal.estimation.information_rows`) in
    the directions orthogonal to its gauge freedoms, ``(m, 6 + k, n - g)``, so that
    ``Σ B_jᵀ B_j`` is the information of the gauge-fixed parameters."""
    from hexcal.design.instrument_table import plan_problem
    from hexcal.estimation import complement_basis, gauge_freedoms, information_rows

    problem = plan_problem(geometry, instrument, poses, fix=fix, mask=mask, covariates=covariates)
    rows = information_rows(problem, NoiseModel() if noise is None else noise)[0]
    return rows @ complement_basis(gauge_freedoms(problem, problem.full0))


def information_matrix(blocks: ArrayLike, indices: ArrayLike | None = None) -> NDArray[np.float64]:
    """``Σ_j B_jᵀ B_j`` over ``indices`` (default all), shape (n, n).

    >>> information_matrix(np.ones((3, 1, 2)), [0, 2])
    array([[2., 2.],
           [2., 2.]])
    """
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

    Examples
    --------
    >>> info = np.diag([4.0, 1.0])
    >>> [round(criterion_value(info, c), 4) for c in CRITERIA]
    [0.6931, -1.25, 1.0, 0.5]
    >>> criterion_value(np.eye(3), "D"), criterion_value(np.zeros((2, 2)), "A")
    (0.0, -inf)
    """
    check_criterion(criterion)
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
    """The criterion value in readable form.

    >>> describe_value(-1.25, "A")
    'trace(F⁻¹) = 1.25 mm²'
    """
    if criterion == "D":
        return f"det(F)^(1/n) = {np.exp(value):.4g}"
    if criterion == "A":
        return f"trace(F⁻¹) = {-value:.4g} mm²"
    if criterion == "E":
        return f"λmin(F) = {value:.4g}"
    return f"λmin/√λmax = {value:.4g}"


def check_criterion(criterion: str) -> None:
    """:class:`~hexcal.errors.SelectionError` unless ``criterion`` is one of :data:`CRITERIA`.

    >>> check_criterion("A")
    """
    if criterion not in CRITERIA:
        raise SelectionError(f"unknown criterion {criterion!r}; choose from {', '.join(CRITERIA)}")


def full_rank(blocks: ArrayLike, indices: ArrayLike) -> bool:
    """Whether the poses ``indices`` of ``blocks`` (N, rows, p) identify all ``p`` parameters.

    The rank rule of :mod:`hexcal.core.linalg` on their stacked Jacobian.

    >>> blocks = np.eye(2)[:, None, :]  # two candidates, one row each
    >>> full_rank(blocks, [0]), full_rank(blocks, [0, 1])
    (False, True)
    """
    b = np.asarray(blocks, dtype=float)
    chosen = b[np.asarray(indices, dtype=np.intp)].reshape(-1, b.shape[-1])
    if chosen.shape[0] < chosen.shape[1]:
        return False
    return rank_of_singular_values(scaled_svd(chosen).singular_values) == chosen.shape[1]


def _logdet_spd(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """``log det`` of symmetric positive definite matrices (..., k, k)."""
    try:
        chol = np.linalg.cholesky(m)
    except np.linalg.LinAlgError:  # rounding made some barely definite: slower but safe
        sign, logdet = np.linalg.slogdet(m)
        return np.where(sign > 0, logdet, -np.inf)
    return 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)


class Scorer:
    """D or A value of ``F + B_jᵀ B_j`` for every candidate ``j`` (working state, private).

    Holds ``F`` (positive definite), ``F⁻¹``, ``log det F`` and, for all candidates,
    ``M_j = B_j F⁻¹ B_jᵀ`` and (A only) ``G_j = B_j F⁻² B_jᵀ``, all small (6 × 6). A rank-6
    change ``F ± B_cᵀ B_c`` updates them by Woodbury with two thin products over the
    candidates; they are recomputed from scratch every ``REFRESH`` changes against drift.

    >>> blocks = np.array([[[2.0, 0.0]], [[0.0, 1.0]], [[1.0, 2.0]]])
    >>> scorer = Scorer(blocks, np.eye(2), "D")
    >>> np.round(scorer.scores(), 4).tolist()  # mean log eigenvalue of I + B_jᵀ B_j
    [0.8047, 0.3466, 0.8959]
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
            return Scorer(self.blocks, rest, self.criterion).scores()
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


def best_by_eigenvalues(
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

    >>> blocks = np.array([[[2.0, 0.0]], [[0.0, 1.0]], [[1.0, 2.0]]])
    >>> best_by_eigenvalues(np.diag([1.0, 4.0]), blocks, np.ones(3, dtype=bool), "E")
    (0, 4.0)
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
