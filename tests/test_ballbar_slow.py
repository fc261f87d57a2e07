"""Monte Carlo check of ballbar calibration against the Cramér–Rao bound (issue 21, slow).

For each machine (the seed paper's, presets paper-hmt / paper-hmt-true, and an irregular 6-6
one) 200 noisy campaigns of 24 circles at the pivots ``select_circles`` chose are identified;
the held-out circles' bar readings are predicted from their leg readings and compared with
their true values. The RMS prediction error over the trials must be the one the Cramér–Rao
bound at the truth predicts (propagated through the prediction's Jacobian), within four Monte
Carlo standard errors of the ratio (about ±6 % at 200 trials): a fit that is not efficient, a
bound that is wrong, or a prediction that misses by more than its uncertainty fails. About a
minute per machine (``benchmarks/ballbar.py`` prints the same figures).
"""

from __future__ import annotations

import pytest

from ballbar_cases import monte_carlo


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["paper", "general"])
def test_held_out_circles_are_predicted_as_the_bound_says(kind: str) -> None:
    out = monte_carlo(kind, 200)
    assert out["failed"] == 0 and len(out["ms"]) == 200
    assert out["ratio_se"] < 0.03  # the check has the power it claims
    assert abs(out["ratio"] - 1) < 4 * out["ratio_se"], out
