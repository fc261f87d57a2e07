"""Identifiability of a pose set: numerical rank, null space and the lost combinations by name.

A pose set identifies the parameters when its identification Jacobian has full column
rank. The rank and the directions it cannot see follow the one rule of
:mod:`hexcal.core.linalg` (columns normalised to unit length, singular values below
``RANK_RTOL`` times the largest count as zero), so that the judgement here is the one
:func:`hexcal.estimation.identify` makes. Also the Jacobian of planned poses
(:func:`planning_jacobian`). Imports :mod:`hexcal.core` and :mod:`hexcal.estimation`.

>>> import numpy as np
>>> jac = np.array([[1.0, 1.0, 0.0], [2.0, 2.0, 1.0]])  # columns 1 and 2 always move together
>>> numerical_rank(jac)
2
>>> unidentifiable_combinations(jac, ["u1.x", "s1.x", "l0_1"])
['u1.x - s1.x']
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import (
    RANK_RTOL,
    Geometry,
    as_poses,
    scaled_svd,
    select_parameters,
)
from hexcal.core import (
    null_space as scaled_null_space,
)
from hexcal.core import (
    numerical_rank as rank_of_singular_values,
)
from hexcal.estimation import identification_jacobian, planned_measurements


def numerical_rank(jacobian: ArrayLike, rtol: float = RANK_RTOL) -> int:
    """Rank of a Jacobian (r, n) judged on its column-normalised form.

    Singular values of the column-normalised Jacobian below ``rtol`` times the largest
    count as zero (:mod:`hexcal.core.linalg`): the rule of
    :func:`hexcal.estimation.identify`, independent of parameter units.

    >>> numerical_rank([[1.0, 0.0], [0.0, 1e-3]])  # column scale does not matter
    2
    >>> numerical_rank([[1.0, 2.0], [2.0, 4.0]])
    1
    """
    return rank_of_singular_values(scaled_svd(jacobian).singular_values, rtol)


def null_space(jacobian: ArrayLike, rtol: float = RANK_RTOL) -> NDArray[np.float64]:
    """Basis of the parameter changes a Jacobian (r, n) does not see, shape (n - rank, n).

    Found on the column-normalised Jacobian (rank rule of :func:`numerical_rank`) and
    returned in parameter units, in reduced row-echelon form: each row is 1 at its own
    pivot parameter and 0 at the others' pivots, which names simple combinations (for
    example ``u1.x + s1.x``) whenever the lost directions are sparse.

    >>> null_space([[1.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
    array([[1., 1., 0.]])
    """
    import scipy.linalg  # deferred: only needed for degenerate pose sets

    normalised, norms = scaled_null_space(jacobian, rtol)
    basis = normalised / norms  # back to parameter units: theta = y / norms
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

    >>> format_combination([-2.0, 0.0, 1.0], ["l0_1", "l0_2", "g1"])
    'l0_1 - 0.5·g1'
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
    """The parameter combinations a Jacobian (r, n) cannot identify, by name.

    Each string is a direction of parameter change that leaves every residual unchanged
    to first order (a row of :func:`null_space`); an empty list when the Jacobian has
    full column rank.

    >>> unidentifiable_combinations([[1.0, 0.0], [0.0, 1.0]], ["l0_1", "l0_2"])
    []
    """
    basis = null_space(jacobian, rtol)
    return [format_combination(row, names) for row in basis]


def as_mask(mask: ArrayLike | None) -> NDArray[np.bool_]:
    """A 48-mask of machine parameters as a bool array; ``None`` selects joints and ``l0``.

    >>> int(as_mask(None).sum())
    42
    """
    return select_parameters() if mask is None else np.asarray(mask, dtype=bool)


def planning_jacobian(
    geometry: Geometry, poses: ArrayLike, mask: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Identification Jacobian of the leg length residual at planned poses, shape (6 m, n).

    Leg readings are the geometry's own inverse kinematics (they matter only for gain
    columns); rows ``6 j + i`` are pose ``j``, leg ``i``.

    >>> from hexcal.core import preset, workspace_corners
    >>> machine = preset("paper-hmt")
    >>> jac = planning_jacobian(machine, workspace_corners(machine)[:10])
    >>> jac.shape, numerical_rank(jac)
    ((60, 42), 42)
    """
    poses = as_poses(poses).reshape(-1, 6)
    return identification_jacobian(geometry, planned_measurements(geometry, poses), "length", as_mask(mask))
