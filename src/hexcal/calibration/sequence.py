"""Structure in acquisition order: a step (a bumped instrument) or a drift (warming legs).

The rows of a session are in the order they were measured (a ``time`` column says when). A
calibration model describes each pose on its own; what changes *during* a session is not in
it: a laser tracker bumped half-way, a tool or a frame that slipped (a **step**), legs that grow
as they warm, a frame that creeps (a **drift**). With the noise learned from the data such an
error is absorbed into a larger noise and the fit looks consistent; here it is looked for.

At the maximum-likelihood solution, the whitened residuals ``e`` of every observation are
tested against regressors of the quantities that could have moved, one *family* at a time: each
group of the instrument's own setup (its frame, tool, targets, a ballbar's pivot, ball and
length: fixed or free) and the legs' initial lengths. For a family with whitened derivatives
``Z_j`` (observation ``j``, in the parameters' own units),

- a step after the ``k``-th observation is the regressor ``Z_j 1[j ≥ k]``,
- a drift the regressor ``Z_j (τ_j - τ̄)``, ``τ`` the time (or the row number),

each taken orthogonal to what the fit already explains (every observation's own pose, the fitted
parameters, and a constant change of the family: a setup quantity held fixed may simply be
wrong, which is not a change in time). The Lagrange-multiplier statistic ``LM = sᵀ M⁺ s`` of the
linearised model (``s = Zᵀ e``, ``M = Zᵀ Z`` after the projections, computed for every ``k`` at
once from cumulative sums) is turned into the scale-free ``F = (LM / q) / ((RSS - LM) / (dof -
q))``, so that a noise learned too large does not hide it. A step's ``p`` is its smallest over the
split points times their number (Bonferroni: the max of correlated statistics, conservative) and
times the number of families; a split leaves at least :data:`MIN_SEGMENT` observations on each
side (a single bad pose is an outlier, found by the outlier screen). A finding is reported
below :data:`ALPHA`: the candidate (step or drift, of any family, at any split point) of the
smallest ``p``, and where ``p`` is beyond floating point (a gross step, at several split points
around it) the one that explains the most. Its
size (the family's change, in mm and degrees) is the linearised estimate ``-M⁺ s``. It is a
``fail`` when it explains so much of the residuals that the learned noise is
:data:`~hexcal.calibration.limits.FAIL_INFLATION` times what it would be without it, a
``warn`` when it explains at least :data:`~hexcal.calibration.limits.WARN_SHARE` of them, else
an ``info`` (found, but a small part of what the fit leaves: beside a model error that follows
the poses, a test in acquisition order cannot tell order from pose).

The remedies: a step splits the session there into two sessions (each with its own instrument
quantities: :func:`hexcal.calibration.splitting.split_sessions`); a drift wants the cause in
the model (the legs' temperatures with a thermal leg model) or shorter sessions.

>>> F_TESTS  # the statistics' names in reports
('step', 'drift')
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.limits import FAIL_INFLATION, MIN_SEGMENT, WARN_SHARE
from hexcal.calibration.limits import SEQUENCE_ALPHA as ALPHA
from hexcal.calibration.reasons import Reason
from hexcal.errors import HexcalError, UsageError

F_TESTS = ("step", "drift")


@dataclass(frozen=True)
class SequenceFinding:
    """A step or a drift in one session's acquisition order.

    Attributes
    ----------
    session : str
        The session's label.
    kind : str
        ``step`` or ``drift``.
    family : str
        What moved: an instrument group (``frame``, ``tool``, ``targets``, ``pivot``, ...) or
        ``legs``.
    index : int
        For a step, the first observation after it (0-based, in the session); else -1.
    before, after : str
        For a step, the ids of the observations between which it happened.
    statistic, p_value : float
        ``F`` and its ``p`` (corrected for the split points and families).
    explained : float
        The share of the residual sum of squares it explains.
    size : dict
        Its size: ``translation_mm`` and ``rotation_deg`` (a frame or tool), ``max_mm`` (targets,
        a pivot, a ball, a length), ``legs_mm`` (each leg's change), over the step or the whole
        session for a drift.
    """

    session: str
    kind: str
    family: str
    index: int
    before: str
    after: str
    statistic: float
    p_value: float
    explained: float
    size: dict[str, Any]

    @property
    def inflation(self) -> float:
        """How many times larger the learned noise is for it (``sqrt(RSS / (RSS - LM))``)."""
        return float(1.0 / np.sqrt(max(1.0 - self.explained, 1e-12)))

    @property
    def severity(self) -> str:
        if self.inflation >= FAIL_INFLATION:
            return "fail"
        return "warn" if self.explained >= WARN_SHARE else "info"

    def describe_size(self) -> str:
        size = self.size
        if "legs_mm" in size:
            legs = np.asarray(size["legs_mm"])
            return f"the legs changed by {legs.min():+.3g} to {legs.max():+.3g} mm"
        if "rotation_deg" in size:
            return f"{size['translation_mm']:.3g} mm and {size['rotation_deg']:.3g}°"
        return f"{size['max_mm']:.3g} mm"

    def to_dict(self) -> dict[str, Any]:
        return {
            "session": self.session,
            "kind": self.kind,
            "family": self.family,
            "index": self.index,
            "before": self.before,
            "after": self.after,
            "statistic": self.statistic,
            "p_value": self.p_value,
            "explained": self.explained,
            "inflation": self.inflation,
            "size": {
                k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in self.size.items()
            },
        }


def _orthonormal(matrix: NDArray[np.float64], rtol: float = 1e-9, scale: float | None = None) -> NDArray:
    """An orthonormal basis of the column space: the directions whose singular values exceed
    ``rtol`` times ``scale`` (default the largest; give the size of what ``matrix`` was before
    a projection, so that the round-off a projection leaves is not taken for a direction)."""
    if matrix.shape[1] == 0:
        return matrix
    u, sv, _ = np.linalg.svd(matrix, full_matrices=False)
    top = float(sv[0]) if scale is None else scale
    return u[:, sv > rtol * max(top, 1e-300)]


def _lm(s: NDArray[np.float64], m: NDArray[np.float64], rtol: float = 1e-9) -> tuple[NDArray, NDArray]:
    """``sᵀ M⁺ s`` and the rank of ``M`` for stacks ``s (..., q)``, ``M (..., q, q)``."""
    vals, vecs = np.linalg.eigh(0.5 * (m + np.swapaxes(m, -1, -2)))
    top = np.max(vals, axis=-1, keepdims=True)
    keep = vals > rtol * np.maximum(top, 1e-300)
    proj = np.einsum("...qi,...q->...i", vecs, s)
    inv = np.where(keep, 1.0 / np.where(keep, vals, 1.0), 0.0)
    return np.sum(proj**2 * inv, axis=-1), keep.sum(axis=-1)


def _solve(s: NDArray[np.float64], m: NDArray[np.float64], rtol: float = 1e-9) -> NDArray[np.float64]:
    """``M⁺ s`` (one system)."""
    vals, vecs = np.linalg.eigh(0.5 * (m + m.T))
    keep = vals > rtol * max(float(vals.max(initial=0.0)), 1e-300)
    inv = np.where(keep, 1.0 / np.where(keep, vals, 1.0), 0.0)
    return vecs @ (inv * (vecs.T @ s))


def _families(
    problem: Any, part: Any, full: NDArray, poses: NDArray, whitener: NDArray, sigma: float
) -> dict:
    """Each family's whitened derivatives ``(m, 6 + k, q)`` (parameter units) and its names."""
    instrument = part.instrument
    m, k = len(part), instrument.size
    out: dict[str, tuple[NDArray, tuple[str, ...]]] = {}
    params = instrument.parameters()
    if len(params.names):
        setup = full[part.block]
        dsetup = np.matmul(whitener, instrument.setup_jacobian(setup, poses, problem.euler))
        dsetup = np.where(part.present[..., None], dsetup, 0.0)
        for group, names in params.groups.items():
            cols = [params.names.index(n) for n in names]
            z = np.zeros((m, 6 + k, len(cols)))
            z[:, 6:] = dsetup[:, :, cols]
            out[group] = (z, tuple(names))
    block = full[problem.leg_block]
    dl0 = problem.legs.jacobian(block, part.readings, part.inputs)[..., :6]  # (m, 6 legs, 6 l0)
    z = np.zeros((m, 6 + k, 6))
    z[:, :6] = -dl0 / sigma
    out["legs"] = (z, tuple(f"l0_{i}" for i in range(1, 7)))
    return out


def session_times(part: Any) -> NDArray[np.float64]:
    """When each observation of a session was measured: its ``time`` column, else the row order."""
    time = part.instrument.covariates(part.data).time
    if time is not None:
        return np.asarray(time, dtype=float)
    return np.arange(len(part), dtype=float)


def _size(
    family: str, names: tuple[str, ...], delta: NDArray[np.float64], euler: str, values: NDArray
) -> dict:
    """A family's change ``delta`` (its parameters' units) in mm and degrees."""
    if family == "legs":
        return {"legs_mm": delta}
    if family in ("frame", "tool") and len(delta) == 6:
        from scipy.spatial.transform import Rotation

        before = Rotation.from_euler(euler, values[3:6])
        after = Rotation.from_euler(euler, values[3:6] + delta[3:6])
        angle = float(np.rad2deg((after * before.inv()).magnitude()))
        return {"translation_mm": float(np.linalg.norm(delta[:3])), "rotation_deg": angle}
    points = delta.reshape(-1, 3) if len(delta) % 3 == 0 else delta.reshape(-1, 1)
    return {"max_mm": float(np.max(np.linalg.norm(points, axis=1)))}


def sequence_findings(
    problem: Any,
    result: Any,
    noise: Any,
    exclude: Sequence[int] = (),
    alpha: float = ALPHA,
) -> list[SequenceFinding]:
    """Steps and drifts in each session's acquisition order (module docstring).

    Parameters
    ----------
    problem : Problem
        The data fitted.
    result : IdentificationResult
        A fit of ``problem`` (its values are used; best the ``ml`` fit).
    noise : NoiseModel or one per session
        The noise the residuals are whitened with (the learned or the given one).
    exclude : sequence of int
        Observations (rows of the problem) left out of the test: the outliers the screen found.
    alpha : float
        Level of each session's test.

    Returns
    -------
    list of SequenceFinding
        At most one per session, most significant first.
    """
    from scipy.stats import f as f_dist

    from hexcal.estimation.likelihood import Projection

    if len(problem) != result.n_poses:
        raise UsageError("the fit and the problem have different observations")
    inner = Projection(problem, noise)
    x = (np.asarray(result.values) - problem.full0[problem.mask]) / problem.scale
    full = problem.unpack(x)
    evaluated = inner.evaluate(x)
    basis = _orthonormal(inner.jacobian(x))
    sizes = [e.size for _, e, _ in evaluated]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    e_all = np.concatenate([e.ravel() for _, e, _ in evaluated])
    dropped = np.zeros(len(problem), dtype=bool)
    dropped[np.asarray(exclude, dtype=np.intp)] = True
    out = []
    for s, (part, (poses, e, b), pp) in enumerate(zip(problem.parts, evaluated, inner.parts, strict=True)):
        m, r = e.shape
        if m < 2 * MIN_SEGMENT:
            continue
        keep = ~dropped[part.rows]
        q_pose, _ = np.linalg.qr(b)
        families = _families(problem, part, full, poses, pp.whitener, pp.sigma)
        tau = session_times(part)
        tau = (tau - tau[0]) / max(float(np.ptp(tau)), 1e-300)  # any origin, any size of time
        tau -= tau.mean()
        candidates: list[dict[str, Any]] = []
        rows = slice(offsets[s], offsets[s + 1])
        for family, (z, names) in families.items():
            z = z - np.matmul(q_pose, np.matmul(q_pose.transpose(0, 2, 1), z))  # own poses out
            z = np.where(keep[:, None, None], z, 0.0)
            q = z.shape[2]
            # the null: the fit's basis and a constant change of the family
            constant = np.zeros((len(e_all), q))
            constant[rows] = z.reshape(m * r, q)
            size = float(np.linalg.norm(constant, 2))
            constant -= basis @ (basis.T @ constant)
            null = np.hstack([basis, _orthonormal(constant, 1e-7, size)])
            e0 = e_all - null @ (null.T @ e_all)
            e0[rows] = np.where(keep[:, None], e0[rows].reshape(m, r), 0.0).ravel()
            own = e0[rows].reshape(m, r)
            rss = float(e0 @ e0)
            dof = max(int(result.dof) - (null.shape[1] - basis.shape[1]), q + 1)
            nrows = null[rows].reshape(m, r, -1)
            gram = np.einsum("mri,mrj->mij", z, z)  # (m, q, q)
            cross = np.einsum("mrn,mrq->mnq", nrows, z)  # (m, n_null, q)
            score = np.einsum("mrq,mr->mq", z, own)  # (m, q)
            found = {"family": family, "names": names, "rss": rss}
            # steps: sums over the observations from k on, every k at once
            split = np.arange(MIN_SEGMENT, m - MIN_SEGMENT + 1)
            if split.size:
                s_k = np.cumsum(score[::-1], axis=0)[::-1][split]
                c_k = np.cumsum(cross[::-1], axis=0)[::-1][split]
                m_k = np.cumsum(gram[::-1], axis=0)[::-1][split] - np.einsum("knq,knp->kqp", c_k, c_k)
                lm, rank = _lm(s_k, m_k)
                f_k = np.where(rank > 0, (lm / np.maximum(rank, 1)) / ((rss - lm) / (dof - rank)), 0.0)
                # log p (a gross step's p underflows), Bonferroni over the split points
                logp = f_dist.logsf(f_k, np.maximum(rank, 1), np.maximum(dof - rank, 1)) + np.log(split.size)
                # the smallest p; where it is beyond floating point (-inf, several split points
                # around a gross step) the largest share explained, not the first such point
                j = int(np.lexsort((-lm, logp))[0])
                candidates.append(
                    found
                    | {
                        "kind": "step",
                        "logp": float(logp[j]),
                        "lm": float(lm[j]),
                        "f": float(f_k[j]),
                        "index": int(split[j]),
                        "s": s_k[j],
                        "m": m_k[j],
                    }
                )
            # the drift: one regressor, τ-weighted sums; where the time jumps once (a pause), a
            # drift in time is the step at the jump, and the step says where to split
            if split.size and _step_like(tau, int(split[j])):
                continue
            sd = np.einsum("m,mq->q", tau, score)
            cd = np.einsum("m,mnq->nq", tau, cross)
            md = np.einsum("m,mqp->qp", tau**2, gram) - cd.T @ cd
            lm_d, rank_d = _lm(sd, md)
            if rank_d > 0:
                f_d = float((lm_d / rank_d) / ((rss - lm_d) / (dof - rank_d)))
                logp_d = float(f_dist.logsf(f_d, rank_d, max(dof - rank_d, 1)))
                candidates.append(
                    found
                    | {
                        "kind": "drift",
                        "logp": logp_d,
                        "lm": float(lm_d),
                        "f": f_d,
                        "index": -1,
                        "s": sd,
                        "m": md,
                    }
                )
        # every family's step and drift: the smallest p, corrected for the families tested
        tests = np.log(2 * len(families))
        if not candidates or min(c["logp"] for c in candidates) + tests >= np.log(alpha):
            continue
        chosen = min(candidates, key=lambda c: (c["logp"], -c["lm"] / max(c["rss"], 1e-300)))
        # the change of the family that takes the residuals away (e + Z δ ≈ 0); a drift's from
        # the first observation to the last (τ spans 1)
        delta = -_solve(chosen["s"], chosen["m"])
        family, names = chosen["family"], chosen["names"]
        params = part.instrument.parameters()
        values = (
            np.array([full[part.block][params.names.index(n)] for n in names]) if family != "legs" else delta
        )
        ids, index = part.session.ids, chosen["index"]
        out.append(
            SequenceFinding(
                session=part.label,
                kind=chosen["kind"],
                family=family,
                index=index,
                before=ids[index - 1] if index > 0 else "",
                after=ids[index] if index > 0 else "",
                statistic=chosen["f"],
                p_value=float(min(1.0, np.exp(chosen["logp"] + tests))),
                explained=float(chosen["lm"] / max(chosen["rss"], 1e-300)),
                size=_size(family, names, delta, problem.euler, values),
            )
        )
    return sorted(out, key=lambda f: f.p_value)


#: The correlation of the times with a step beyond which a drift is that step (the time
#: jumps once, as over a pause, and is nearly constant on either side).
STEP_LIKE = 0.99


def _step_like(tau: NDArray[np.float64], k: int) -> bool:
    """Whether the (centred) times ``tau`` follow a step at observation ``k``."""
    step = (np.arange(len(tau)) >= k).astype(float)
    step -= step.mean()
    norm = float(np.linalg.norm(step) * np.linalg.norm(tau))
    return norm > 0 and abs(float(step @ tau)) / norm > STEP_LIKE


#: What moved, by family, as the verdict says it.
_WHAT = {
    "frame": "the instrument frame",
    "tool": "the tool",
    "targets": "the targets",
    "pivot": "the ballbar's pivot",
    "ball": "the ballbar's ball",
    "length": "the bar's length",
    "legs": "the legs",
}


def _p(p: float) -> str:
    return "p < 1e-300" if p <= 0 else f"p {p:.2g}"


def finding_reason(finding: SequenceFinding) -> Reason:
    """The verdict's line of a step or a drift, with its remedy."""
    f = finding
    what = _WHAT.get(f.family, f"the setup's {f.family}")
    stats = f"F {f.statistic:.3g}, {_p(f.p_value)}; it explains {f.explained:.0%} of the residuals"
    if f.kind == "step":
        size = f.describe_size() if f.family == "legs" else f"{what} moved {f.describe_size()}"
        cause = (
            "a leg lost its position or its reading jumped (re-home and measure again), "
            "or the instrument moved"
            if f.family == "legs"
            else "the instrument was bumped, or a frame, a tool or a target slipped"
        )
        text = (
            f"{f.session}: a step between poses {f.before} and {f.after}: {size} ({stats}); {cause}: "
            f"split the session there (--split {f.session}:{f.after}, or --split auto)"
        )
    else:
        size = f.describe_size() if f.family == "legs" else f"{what} moved {f.describe_size()}"
        text = (
            f"{f.session}: a drift in acquisition order: {size} from the first pose to the last ({stats}); "
            "legs that warm up, or a creeping instrument: give each leg's temperature (temp1 ... temp6, or "
            "temp) with a thermal leg model, or measure shorter sessions"
        )
    return Reason(f.kind, f.severity, text, f.to_dict())


def sequence_reasons(
    problem: Any, result: Any, noise: Any, exclude: Sequence[int] = (), alpha: float = ALPHA
) -> list[Reason]:
    """The verdict's reasons for the steps and drifts of :func:`sequence_findings` (none when
    the test cannot run on these data: it is advisory)."""
    try:
        found = sequence_findings(problem, result, noise, exclude, alpha)
    except (HexcalError, ValueError, np.linalg.LinAlgError):
        return []
    return [finding_reason(f) for f in found]


__all__ = [
    "ALPHA",
    "FAIL_INFLATION",
    "MIN_SEGMENT",
    "SequenceFinding",
    "finding_reason",
    "sequence_findings",
    "sequence_reasons",
    "session_times",
]
