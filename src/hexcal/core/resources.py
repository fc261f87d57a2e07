"""The one memory budget: sizes asked for by options are checked before anything is allocated.

Every size option (trials, grid points, candidate poses, ballbar pivots and points per circle,
...) is turned into the bytes its arrays would take by the function that allocates them, and
checked against :data:`MEMORY_BUDGET` by :func:`check_memory` first: a size that would not fit
is refused in one line naming the option, not discovered by the out-of-memory killer after
minutes. Standard library only (the command line checks options with it before loading numpy).
"""

from __future__ import annotations

from hexcal.errors import InputError

#: Bytes the arrays of one command (one library call) may take.
MEMORY_BUDGET = 2 * 1024**3


def check_memory(option: str, nbytes: float, what: str) -> None:
    """Refuse ``nbytes`` over :data:`MEMORY_BUDGET`, naming ``option`` and ``what`` needs it.

    Examples
    --------
    >>> check_memory("--points", 1024, "the circles")
    >>> check_memory("--points", 3 * 1024**3, "1,000 circles")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hexcal.errors.InputError: --points: 1,000 circles would need about 3.0 GiB, over hexcal's memory budget...
    """
    if nbytes > MEMORY_BUDGET:
        raise InputError(
            f"{option}: {what} would need about {nbytes / 1024**3:.1f} GiB, over hexcal's memory "
            f"budget of {MEMORY_BUDGET / 1024**3:.0f} GiB; choose a smaller value"
        )
