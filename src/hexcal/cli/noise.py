"""The noise options of the commands: ``--noise``, ``--noise-dist`` and ``--pose-covariance``."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from hexcal.cli.common import CommandError

if TYPE_CHECKING:
    from hexcal.core import NoiseModel

#: Help of the planning commands' ``--noise``.
NOISE_HELP = "noise half-widths (uniform) or sigmas (normal), e.g. leg=0.01,pos=0.025,ang=0.001"


def parse_noise(text: str | None, distribution: str = "uniform", elsewhere: Sequence[str] = ()) -> NoiseModel:
    """Parse ``leg=0.01,pos=0.025,ang=0.001`` (any subset; others keep the paper's values,
    said in a warning line naming them: a partial ``--noise`` never fills the rest silently;
    the groups in ``elsewhere`` are given otherwise, by a pose covariance, and not named).

    >>> parse_noise("leg=0.02").leg
    0.02
    """
    from hexcal.core import NoiseModel

    keys = {"leg": "leg", "pos": "position", "ang": "orientation"}
    values: dict[str, float] = {}
    for item in (text or "").split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in keys:
            raise CommandError(f"--noise: cannot read {item!r}; write e.g. leg=0.01,pos=0.025,ang=0.001")
        if keys[key] in values:
            raise CommandError(f"--noise: {key} is given twice; give each of leg, pos and ang once")
        try:
            number = float(value)
        except ValueError:
            raise CommandError(f"--noise: {key}={value!r} is not a number") from None
        if not math.isfinite(number) or number < 0:
            raise CommandError(f"--noise: {key} must be a finite value >= 0, got {value}")
        values[keys[key]] = number
    try:
        model = NoiseModel(distribution=distribution, **values)
    except ValueError as exc:
        raise CommandError(f"--noise: {exc}") from None
    if values and any(name not in values and name not in elsewhere for name in keys.values()):
        import warnings

        from hexcal.errors import HexcalWarning

        short = {v: k for k, v in keys.items()}
        rest = [
            f"{short[name]}={getattr(model, name):g}"
            for name in keys.values()
            if name not in values and name not in elsewhere
        ]
        warnings.warn(
            f"--noise gives only {', '.join(short[n] for n in values)}: {', '.join(rest)} "
            "(the seed paper's values) for the rest",
            HexcalWarning,
            stacklevel=2,
        )
    return model


def noise_options(p: argparse.ArgumentParser) -> None:
    """Add ``--noise``, ``--noise-dist`` and ``--pose-covariance`` to a subcommand."""
    p.add_argument(
        "--noise",
        help="measurement noise: leg=MM,pos=MM,ang=RAD (default the seed paper's "
        "leg=0.01,pos=0.025,ang=0.001)",
    )
    p.add_argument(
        "--noise-dist",
        choices=("uniform", "normal"),
        default="uniform",
        help="uniform: the values are half-widths a (σ = a/√3); normal: they are σ",
    )
    p.add_argument(
        "--pose-covariance",
        metavar="FILE",
        help="full 6x6 pose covariance (mm², mm·rad, rad²; 6 rows of 6 numbers), replacing pos and ang",
    )


def noise_from_args(args: argparse.Namespace, instruments: Sequence[Any] = ()) -> NoiseModel:
    """The noise model of ``--noise``, ``--noise-dist`` and ``--pose-covariance``; a pose
    covariance is refused for an instrument of ``instruments`` that measures no pose (it would
    not act)."""
    path = getattr(args, "pose_covariance", None)
    noise = parse_noise(args.noise, args.noise_dist, ("position", "orientation") if path else ())
    if path:
        for instrument in instruments:
            if not instrument.uses_pose_covariance():
                raise CommandError(
                    f"--pose-covariance: {instrument.describe()}: no pose is measured, so a pose "
                    "covariance cannot describe the noise; give --noise pos=MM (the σ of each coordinate)"
                )
        from hexcal.core import NoiseModel
        from hexcal.io import read_matrix

        try:
            noise = NoiseModel(
                leg=noise.leg, distribution=noise.distribution, pose_covariance=read_matrix(path, (6, 6))
            )
        except ValueError as exc:
            raise CommandError(f"{path}: {exc}") from None
    return noise


def refuse_zero_noise(noise: NoiseModel, what: str) -> NoiseModel:
    """``noise``, unless it is zero in every group (the library's rule,
    :func:`hexcal.core.noise.require_noise`, said before any file is read)."""
    from hexcal.core.noise import require_noise

    return require_noise(noise, what)
