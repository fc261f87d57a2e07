"""Observability indices, identifiability and predicted accuracy of a measurement pose set.

Builds on :mod:`hexcal.estimation.bounds` (errors-in-variables information and the
Cramér–Rao bound) with what a user needs before measuring:

- the SVD of the column-scaled identification Jacobian and the observability indices
  O1–O5 (:func:`observability_indices`);
- the numerical rank and, by name, the parameter combinations a pose set cannot
  identify (:func:`unidentifiable_combinations`);
- the covariance of the least-squares estimator that :func:`hexcal.estimation.identification.identify`
  actually uses (:func:`least_squares_covariance`), beside the Cramér–Rao bound;
- the first-order map from parameter errors to platform pose errors
  (:func:`pose_error_map`) and, through it, the predicted pose error after calibration
  at test poses (:func:`predicted_pose_errors`);
- all of it for one pose set (:func:`analyse_poses`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses, euler_axes
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import inverse_kinematics, pose_jacobian
from hexcal.core.linalg import RANK_RTOL
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import PARAMETER_NAMES, PARAMETER_SCALE, select_parameters
from hexcal.estimation.bounds import (
    cramer_rao_covariance,
    planned_measurements,
    residual_covariances,
    whitened_jacobian,
)
from hexcal.estimation.problem import identification_jacobian

SCALINGS = ("norm", "parameter", "none")

#: Factor from a standard deviation to the mean absolute value of a normal variable.
MEAN_ABS_FACTOR = float(np.sqrt(2.0 / np.pi))


# -- indices ------------------------------------------------------------------------------


@dataclass(frozen=True)
class ObservabilityIndices:
    """Singular values and observability indices of a (column-scaled) Jacobian.

    Attributes
    ----------
    singular_values : ndarray, shape (n,)
        Descending; zeros appended when the Jacobian has fewer rows than columns.
    O1, O2, O3, O4, O5 : float
        See :func:`observability_indices`.
    condition_number : float
        ``σ1 / σn`` (inf when ``σn = 0``).
    rank : int
        Numerical rank (judged on the column-normalised Jacobian, whatever the scaling).
    scaling : str
    """

    singular_values: NDArray[np.float64]
    O1: float
    O2: float
    O3: float
    O4: float
    O5: float
    condition_number: float
    rank: int
    scaling: str

    def as_dict(self) -> dict[str, float | int | str | list[float]]:
        """Plain-Python form (for JSON)."""
        return {
            "scaling": self.scaling,
            "rank": self.rank,
            "singular_values": self.singular_values.tolist(),
            "O1": self.O1,
            "O2": self.O2,
            "O3": self.O3,
            "O4": self.O4,
            "O5": self.O5,
            "condition_number": self.condition_number,
        }


def column_scales(
    jacobian: ArrayLike, scaling: str = "norm", parameter_scale: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Factors ``d`` (n,) by which the columns of a Jacobian are multiplied before its SVD.

    Parameters
    ----------
    jacobian : array_like, shape (r, n)
    scaling : {"norm", "parameter", "none"}
        ``norm``: ``d_k = 1 / ||J[:, k]||`` (every column of unit length: the indices no
        longer depend on parameter units or on any prior column scaling);
        ``parameter``: ``d_k`` the characteristic scale of parameter ``k`` (1 mm for joints
        and ``l0``, 1e-3 for gains; a column then reads "residual per characteristic
        parameter error", after Hollerbach & Wampler 1996);
        ``none``: ``d_k = 1`` (parameters in their own units).
    parameter_scale : array_like, shape (n,), optional
        Scales for ``parameter`` (default: :data:`hexcal.estimation.identification.PARAMETER_SCALE` of
        the 42 joints and ``l0``, which requires ``n == 42``).
    """
    jac = np.asarray(jacobian, dtype=float)
    if jac.ndim != 2:
        raise ValueError(f"jacobian must have shape (r, n), got {jac.shape}")
    n = jac.shape[1]
    if scaling == "norm":
        norms = np.linalg.norm(jac, axis=0)
        return 1.0 / np.where(norms > 0, norms, 1.0)
    if scaling == "parameter":
        scale = PARAMETER_SCALE[:42] if parameter_scale is None else np.asarray(parameter_scale, dtype=float)
        if scale.shape != (n,):
            raise ValueError(f"parameter_scale must have shape ({n},), got {scale.shape}")
        return scale
    if scaling == "none":
        return np.ones(n)
    raise ValueError(f"unknown scaling {scaling!r}; choose from {', '.join(SCALINGS)}")


def numerical_rank(jacobian: ArrayLike, rtol: float = RANK_RTOL) -> int:
    """Rank of a Jacobian judged on its column-normalised form.

    Singular values of the column-normalised Jacobian below ``rtol`` times the largest
    count as zero; the same rule as :func:`hexcal.estimation.identification.identify`, and
    independent of parameter units.
    """
    jac = np.asarray(jacobian, dtype=float)
    sv = np.linalg.svd(jac * column_scales(jac, "norm"), compute_uv=False)
    return int(np.sum(sv > rtol * sv[0])) if sv.size and sv[0] > 0 else 0


def indices_from_singular_values(singular_values: ArrayLike) -> dict[str, float]:
    """O1–O5 and the condition number of singular values ``σ1 >= ... >= σn`` (see
    :func:`observability_indices`)."""
    sv = np.sort(np.asarray(singular_values, dtype=float))[::-1]
    smax, smin = float(sv[0]), float(sv[-1])
    positive = smin > 0
    with np.errstate(divide="ignore"):
        o1 = float(np.exp(np.mean(np.log(sv)))) if positive else 0.0
        o5 = float(1.0 / np.sum(1.0 / sv)) if positive else 0.0
    return {
        "O1": o1,
        "O2": smin / smax if smax > 0 else 0.0,
        "O3": smin,
        "O4": smin**2 / smax if smax > 0 else 0.0,
        "O5": o5,
        "condition_number": smax / smin if positive else float("inf"),
    }


def observability_indices(
    jacobian: ArrayLike,
    scaling: str = "norm",
    parameter_scale: ArrayLike | None = None,
) -> ObservabilityIndices:
    """Observability indices O1–O5 of an identification Jacobian.

    Parameters
    ----------
    jacobian : array_like, shape (r, n)
        Rows are measurement equations, columns parameters.
    scaling : {"norm", "parameter", "none"}
        Column scaling before the SVD (:func:`column_scales`).
    parameter_scale : array_like, shape (n,), optional
        For ``scaling="parameter"``.

    Returns
    -------
    ObservabilityIndices

    Notes
    -----
    With ``σ1 >= ... >= σn`` the singular values of ``J D`` (``D`` the column scaling;
    zeros are appended when ``r < n``):

    - ``O1 = (σ1 σ2 ... σn)^(1/n)``, the geometric mean of the singular values (the
      ``n``-th root of the product, i.e. ``det(Dᵀ JᵀJ D)^(1/2n)``): D-optimality, after
      Borm & Menq (1991), who also divide by ``√r``; hexcal does not, so that O1 of a pose
      set grows with the number of poses as the information does;
    - ``O2 = σn / σ1``, the inverse condition number (Driels & Pathre 1990);
    - ``O3 = σn``, the minimum singular value: E-optimality (Nahvi, Hollerbach & Hayward
      1994);
    - ``O4 = σn² / σ1``, the noise amplification index (Nahvi & Hollerbach 1996);
    - ``O5 = 1 / (1/σ1 + ... + 1/σn)``, related to A-optimality (Sun & Hollerbach 2008).

    Larger is better for all five. Under column scaling ``J -> J S`` (``S`` diagonal):
    with ``scaling="norm"`` every index is invariant; otherwise O1 is multiplied by
    ``|det S|^(1/n)`` (so O1 ranks pose sets the same under any units) while O2–O5
    change in general. Multiplying every row by ``c`` multiplies O1, O3, O4 and O5 by
    ``|c|`` and leaves O2 unchanged.

    References
    ----------
    .. [1] J. H. Borm and C. H. Menq, "Determination of optimal measurement
       configurations for robot calibration based on observability measure," Int. J.
       Robotics Research 10(1), 51-63, 1991. doi:10.1177/027836499101000104
    .. [2] M. R. Driels and U. S. Pathre, "Significance of observation strategy on the
       design of robot calibration experiments," J. Robotic Systems 7(2), 197-223, 1990.
       doi:10.1002/rob.4620070204
    .. [3] A. Nahvi, J. M. Hollerbach and V. Hayward, "Calibration of a parallel robot
       using multiple kinematic closed loops," IEEE ICRA 1994, 407-412.
       doi:10.1109/ROBOT.1994.351272
    .. [4] A. Nahvi and J. M. Hollerbach, "The noise amplification index for optimal
       pose selection in robot calibration," IEEE ICRA 1996, 647-654.
       doi:10.1109/ROBOT.1996.503848
    .. [5] Y. Sun and J. M. Hollerbach, "Observability index selection for robot
       calibration," IEEE ICRA 2008, 831-836. doi:10.1109/ROBOT.2008.4543242
    """
    jac = np.asarray(jacobian, dtype=float)
    scales = column_scales(jac, scaling, parameter_scale)
    sv = np.linalg.svd(jac * scales, compute_uv=False)
    sv = np.concatenate([sv, np.zeros(jac.shape[1] - sv.size)])
    values = indices_from_singular_values(sv)
    return ObservabilityIndices(singular_values=sv, rank=numerical_rank(jac), scaling=scaling, **values)


# -- identifiability ----------------------------------------------------------------------


def null_space(jacobian: ArrayLike, rtol: float = RANK_RTOL) -> NDArray[np.float64]:
    """Basis of the parameter changes a Jacobian does not see, shape (n - rank, n).

    Found on the column-normalised Jacobian (rank rule of :func:`numerical_rank`) and
    returned in parameter units, in reduced row-echelon form: each row is 1 at its own
    pivot parameter and 0 at the others' pivots, which names simple combinations (for
    example ``u1.x + s1.x``) whenever the lost directions are sparse.
    """
    import scipy.linalg  # deferred: only needed for degenerate pose sets

    jac = np.asarray(jacobian, dtype=float)
    scales = column_scales(jac, "norm")
    _, sv, vt = np.linalg.svd(jac * scales, full_matrices=True)
    sv = np.concatenate([sv, np.zeros(jac.shape[1] - sv.size)])
    rank = int(np.sum(sv > rtol * sv[0])) if sv[0] > 0 else 0
    basis = vt[rank:] * scales  # back to parameter units: theta = D y
    if basis.shape[0] == 0:
        return basis
    _, _, piv = scipy.linalg.qr(basis, pivoting=True, mode="economic")
    pivots = np.sort(piv[: basis.shape[0]])
    rref = np.linalg.solve(basis[:, pivots], basis)
    rref[np.abs(rref) < 1e-9 * np.max(np.abs(rref))] = 0.0
    first = np.argmax(rref != 0, axis=1)
    return rref[np.argsort(first, kind="stable")]


def format_combination(vector: ArrayLike, names: tuple[str, ...] | list[str], digits: int = 3) -> str:
    """A parameter combination as text, e.g. ``u1.x + s1.x`` or ``l0_1 - 0.5·g1``.

    The vector is scaled so that its largest entry has magnitude 1 and its first term
    (in parameter order) is positive; the direction and its negative are the same lost
    combination.
    """
    vec = np.asarray(vector, dtype=float)
    vec = vec / np.max(np.abs(vec))
    vec = -vec if vec[np.flatnonzero(np.abs(vec) > 10.0 ** (-digits - 1))[0]] < 0 else vec
    parts: list[str] = []
    for k in np.flatnonzero(np.abs(vec) > 10.0 ** (-digits - 1)):
        coef = vec[k]
        sign = "-" if coef < 0 else "+"
        mag = abs(coef)
        term = (
            names[k] if np.isclose(mag, 1.0, rtol=0, atol=10.0**-digits) else f"{mag:.{digits}g}·{names[k]}"
        )
        parts.append(f"{sign} {term}")
    return " ".join(parts)[2:]


def unidentifiable_combinations(
    jacobian: ArrayLike, names: tuple[str, ...] | list[str], rtol: float = RANK_RTOL
) -> list[str]:
    """The parameter combinations a Jacobian cannot identify, by name.

    Each string is a direction of parameter change that leaves every residual unchanged
    to first order (a row of :func:`null_space`); an empty list when the Jacobian has
    full column rank.
    """
    basis = null_space(jacobian, rtol)
    return [format_combination(row, names) for row in basis]


def _mask(mask: ArrayLike | None) -> NDArray[np.bool_]:
    return select_parameters() if mask is None else np.asarray(mask, dtype=bool)


def parameter_names(mask: ArrayLike | None = None) -> tuple[str, ...]:
    """Names of the parameters selected by a 48-mask (default joints and ``l0``)."""
    return tuple(n for n, keep in zip(PARAMETER_NAMES, _mask(mask), strict=True) if keep)


def planning_jacobian(
    geometry: Geometry, poses: ArrayLike, mask: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Identification Jacobian of the leg length residual at planned poses, shape (6 m, n).

    Leg readings are the geometry's own inverse kinematics (they matter only for gain
    columns); rows ``6 j + i`` are pose ``j``, leg ``i``.
    """
    poses = as_poses(poses).reshape(-1, 6)
    return identification_jacobian(geometry, planned_measurements(geometry, poses), "length", _mask(mask))


# -- predicted accuracy ---------------------------------------------------------------------


def _pinv_gram(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(AᵀA)⁺`` by the SVD of the column-normalised ``A`` (as curve_fit does)."""
    scales = column_scales(a, "norm")
    _, sv, vt = np.linalg.svd(a * scales, full_matrices=False)
    keep = sv > RANK_RTOL * sv[0]
    vs = vt[keep].T / sv[keep]
    return (vs @ vs.T) * np.outer(scales, scales)


def least_squares_covariance(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    method: str = "length",
) -> NDArray[np.float64]:
    """Covariance of the unweighted least-squares estimate of ``identify``.

    Parameters
    ----------
    geometry : Geometry
    poses : array_like, shape (m, 6)
    noise : NoiseModel, optional
        Default the seed paper's.
    mask : array_like of bool, shape (48,), optional
    method : {"length", "paper"}
        The residual minimised: leg length, or squared leg length (the paper's eq. 3).

    Returns
    -------
    ndarray, shape (n, n)
        Parameter units (mm² for joints and ``l0``).

    Notes
    -----
    The estimator minimises ``Σ |r_j|²`` without weights while the residual of pose
    ``j`` has covariance ``C_j = J_j Σ_pose J_jᵀ + σ_leg² I``
    (:func:`hexcal.estimation.bounds.residual_covariances`): its first-order covariance is
    the sandwich ``H⁻¹ (Σ_j A_jᵀ C_j A_j) H⁻¹`` with ``H = Σ_j A_jᵀ A_j``. For the paper's
    residual ``|v|² - l²`` every row of leg ``i`` is the leg-length row times ``2 l_ij``.
    The Cramér–Rao bound (:func:`hexcal.estimation.bounds.cramer_rao_covariance`) is what a
    noise-weighted estimator would reach; it is never larger.

    Evaluated at the poses the machine really reaches, it predicts the Monte Carlo error
    of :func:`~hexcal.estimation.identification.identify` within its standard error; at planning
    time only the commanded poses and the nominal geometry are known, and on the seed
    paper's machine (parameter errors up to 5 mm, reached poses up to 63 mm and 0.11 rad
    off) that prediction is 3-6 % high (``docs/observability.md``).
    """
    poses = as_poses(poses).reshape(-1, 6)
    m = poses.shape[0]
    a = planning_jacobian(geometry, poses, mask).reshape(m, 6, -1)
    cov = residual_covariances(geometry, poses, noise)
    if method == "paper":
        w = 2.0 * inverse_kinematics(geometry, poses)
        a = a * w[..., None]
        cov = cov * w[:, :, None] * w[:, None, :]
    elif method != "length":
        raise ValueError(f"unknown method {method!r}; choose from length, paper")
    h_inv = _pinv_gram(a.reshape(6 * m, -1))
    meat = np.einsum("mip,mij,mjq->pq", a, cov, a)
    return h_inv @ meat @ h_inv


def mean_abs_error(covariance: ArrayLike, mask: ArrayLike | None = None) -> float:
    """Predicted mean absolute error of the length parameters, mm.

    ``sqrt(2/π) · mean_k σ_k`` over the selected joints and ``l0`` (gains left out: they
    have no length unit), with ``σ_k`` from the covariance: the mean absolute error of a
    normally distributed unbiased estimate, comparable with the seed paper's Table I.
    """
    cov = np.asarray(covariance, dtype=float)
    names = parameter_names(mask)
    lengths = np.array([not n.startswith("g") for n in names])
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return MEAN_ABS_FACTOR * float(np.mean(sigma[lengths]))


def pose_error_map(
    geometry: Geometry, poses: ArrayLike, mask: ArrayLike | None = None
) -> NDArray[np.float64]:
    """First-order map from parameter errors to platform pose errors, shape (..., 6, n).

    Parameters
    ----------
    geometry : Geometry
        The controller's (nominal) geometry.
    poses : array_like, shape (..., 6)
        Commanded poses.
    mask : array_like of bool, shape (48,), optional
        Parameters with errors (default joints and ``l0``).

    Returns
    -------
    ndarray, shape (..., 6, n)
        ``E`` with ``δpose = E δθ`` (mm and rad per parameter unit).

    Notes
    -----
    The controller commands the nominal leg readings of a pose; a machine whose
    parameters differ by ``δθ`` reaches the pose where its leg equations
    ``r = |o + R s_i - u_i| - (l0_i + g_i dl_i) = 0`` hold. To first order
    ``J δpose + A δθ = 0``, so ``E = -J⁻¹ A`` with ``J`` the pose Jacobian and ``A`` the
    identification Jacobian of the leg length residual.
    """
    poses = as_poses(poses)
    batch = poses.shape[:-1]
    flat = poses.reshape(-1, 6)
    a = planning_jacobian(geometry, flat, mask).reshape(flat.shape[0], 6, -1)
    jac_inv = np.linalg.inv(pose_jacobian(geometry, flat))
    out = -np.matmul(jac_inv, a)
    return out.reshape(batch + out.shape[-2:])


def rotation_vector_map(geometry: Geometry, poses: ArrayLike) -> NDArray[np.float64]:
    """Matrices ``W`` (..., 3, 3) with ``ω = W δ(a, b, c)``: small angle changes to the
    rotation vector of the orientation error, rad per rad (columns are the Euler axes)."""
    poses = as_poses(poses)
    return np.swapaxes(euler_axes(poses[..., 3:], geometry.euler), -1, -2)


def predicted_pose_errors(
    geometry: Geometry,
    test_poses: ArrayLike,
    covariance: ArrayLike,
    mask: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """RMS position and orientation error after calibration at test poses.

    Parameters
    ----------
    geometry : Geometry
    test_poses : array_like, shape (t, 6)
    covariance : array_like, shape (n, n)
        Covariance of the identified parameters (parameter units).
    mask : array_like of bool, shape (48,), optional

    Returns
    -------
    position : ndarray, shape (t,), mm
        ``sqrt(E[|δp|²])``.
    orientation : ndarray, shape (t,), rad
        ``sqrt(E[|ω|²])``, ``ω`` the rotation vector of the orientation error.

    Notes
    -----
    A controller with the identified parameters misses a target by
    ``δpose = E (θ̂ - θ)`` (:func:`pose_error_map`), whose covariance is ``E Σθ Eᵀ``.
    """
    tp = as_poses(test_poses).reshape(-1, 6)
    cov = np.asarray(covariance, dtype=float)
    e = pose_error_map(geometry, tp, mask)
    w = rotation_vector_map(geometry, tp)
    e_pos = e[:, :3]
    e_rot = np.einsum("tij,tjk->tik", w, e[:, 3:])
    pos = np.einsum("tip,pq,tiq->t", e_pos, cov, e_pos)
    rot = np.einsum("tip,pq,tiq->t", e_rot, cov, e_rot)
    return np.sqrt(np.clip(pos, 0, None)), np.sqrt(np.clip(rot, 0, None))


# -- one pose set, everything -------------------------------------------------------------


@dataclass(frozen=True)
class PoseSetAnalysis:
    """Observability and predicted accuracy of one measurement pose set.

    Attributes
    ----------
    names : tuple of str
        Parameters considered (n).
    n_poses : int
    indices : ObservabilityIndices
    unidentifiable : list of str
        Lost parameter combinations by name (empty when the rank is full).
    not_identifiable : ndarray of bool, shape (n,)
        Parameters that take part in a lost combination.
    std_bound, std_estimator : ndarray, shape (n,)
        Predicted standard deviation of every parameter: Cramér–Rao bound and the
        unweighted least-squares estimator of :func:`~hexcal.estimation.identification.identify`
        (``method``); inf where not identifiable.
    mean_error_bound, mean_error_estimator : float
        :func:`mean_abs_error` of the two, mm (inf when any length parameter is lost).
    test_position_rms, test_orientation_rms : ndarray, shape (t,)
        Predicted RMS pose error after calibration (estimator covariance) at the test
        poses, mm and rad; inf where a lost combination moves the platform.
    method : str
    noise : NoiseModel
    weighted : bool
        Whether the indices are of the noise-whitened Jacobian.
    """

    names: tuple[str, ...]
    n_poses: int
    indices: ObservabilityIndices
    unidentifiable: list[str]
    not_identifiable: NDArray[np.bool_]
    std_bound: NDArray[np.float64]
    std_estimator: NDArray[np.float64]
    mean_error_bound: float
    mean_error_estimator: float
    test_position_rms: NDArray[np.float64]
    test_orientation_rms: NDArray[np.float64]
    method: str
    noise: NoiseModel
    weighted: bool

    @property
    def rank(self) -> int:
        return self.indices.rank


def analyse_poses(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    test_poses: ArrayLike | None = None,
    scaling: str = "norm",
    method: str = "length",
    weighted: bool = False,
) -> PoseSetAnalysis:
    """Observability indices, identifiability and predicted accuracy of a pose set.

    Parameters
    ----------
    geometry : Geometry
        Nominal geometry (the Jacobians are evaluated on it).
    poses : array_like, shape (m, 6)
        Planned measurement poses.
    noise : NoiseModel, optional
        Default the seed paper's.
    mask : array_like of bool, shape (48,), optional
        Parameters to identify (default joints and ``l0``).
    test_poses : array_like, shape (t, 6), optional
        Where to predict the pose error after calibration (default none).
    scaling : {"norm", "parameter", "none"}
        Column scaling of the indices (:func:`column_scales`).
    method : {"length", "paper"}
        Residual of the estimator whose covariance is predicted.
    weighted : bool
        Compute the indices on the noise-whitened Jacobian instead of the plain one.

    Returns
    -------
    PoseSetAnalysis
    """
    noise = NoiseModel() if noise is None else noise
    mask = _mask(mask)
    poses = as_poses(poses).reshape(-1, 6)
    names = parameter_names(mask)
    scale = PARAMETER_SCALE[mask]
    jac = (
        whitened_jacobian(geometry, poses, noise, mask)
        if weighted
        else planning_jacobian(geometry, poses, mask)
    )
    indices = observability_indices(jac, scaling, scale)
    lost = null_space(jac)
    not_identifiable = np.any(np.abs(lost) > 0, axis=0) if lost.size else np.zeros(len(names), dtype=bool)
    std_bound = np.sqrt(np.clip(np.diag(cramer_rao_covariance(geometry, poses, noise, mask)), 0, None))
    cov_est = least_squares_covariance(geometry, poses, noise, mask, method)
    std_est = np.sqrt(np.clip(np.diag(cov_est), 0, None))
    std_bound[not_identifiable] = np.inf
    std_est[not_identifiable] = np.inf
    lengths = np.array([not n.startswith("g") for n in names])
    mean_bound = MEAN_ABS_FACTOR * float(np.mean(std_bound[lengths]))
    mean_est = MEAN_ABS_FACTOR * float(np.mean(std_est[lengths]))
    if test_poses is None:
        pos_rms = rot_rms = np.empty(0)
    else:
        tp = as_poses(test_poses, "test poses").reshape(-1, 6)
        pos_rms, rot_rms = predicted_pose_errors(geometry, tp, cov_est, mask)
        if lost.size:
            # a lost combination that moves the platform at a test pose makes its error unbounded
            e = pose_error_map(geometry, tp, mask)
            moved = np.einsum("tip,kp->tik", e, lost / np.linalg.norm(lost, axis=1, keepdims=True))
            unbounded = np.max(np.abs(moved), axis=(1, 2)) > 1e-6
            pos_rms = np.where(unbounded, np.inf, pos_rms)
            rot_rms = np.where(unbounded, np.inf, rot_rms)
    return PoseSetAnalysis(
        names=names,
        n_poses=int(poses.shape[0]),
        indices=indices,
        unidentifiable=[format_combination(row, names) for row in lost],
        not_identifiable=not_identifiable,
        std_bound=std_bound,
        std_estimator=std_est,
        mean_error_bound=mean_bound,
        mean_error_estimator=mean_est,
        test_position_rms=pos_rms,
        test_orientation_rms=rot_rms,
        method=method,
        noise=noise,
        weighted=weighted,
    )
