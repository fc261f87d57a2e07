"""The ISO 230-4 circular test and the ISO 9283 pose figures on cases worked out by hand.

Every expected value below is computed in the comments from the definitions of
:mod:`hexcal.calibration.iso_tests` (its docstring states them: ISO 230-4 clause 3, ISO 9283
7.2.1 and 7.2.2), not by running the code.
"""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.calibration import circular_test, pose_statistics, repeated_visits
from hexcal.calibration.iso_poses import check_visits
from hexcal.calibration.iso_tests import circle_plane, lsc_circle, progression
from hexcal.errors import InputError

R = 100.0


def ring(degrees, radius=R):
    t = np.radians(np.asarray(degrees, dtype=float))
    return radius * np.column_stack([np.cos(t), np.sin(t)])


def test_a_centre_offset_alone_is_no_circular_deviation():
    # actual points (100.01, 0), (0, 100), (-99.99, 0), (0, -100): the circle of radius 100
    # about (0.01, 0) to second order (the points at 90° and 270° are 0.01²/(2·100) = 5e-7 mm
    # outside it). F = +-0.01 (about the commanded centre); G ~ 5e-7; the LSC centre is 0.01 mm
    # along u and its radius 100 (radius error ~ 0).
    c = circular_test(ring([0, 90, 180, 270]), [0.01, 0.0, -0.01, 0.0], direction=np.ones(4))
    run = c.runs["ccw"]
    assert set(c.runs) == {"ccw"} and c.hysteresis is None and c.bidirectional is None
    assert run.f_max == pytest.approx(0.01, abs=1e-12) and run.f_min == pytest.approx(-0.01, abs=1e-12)
    assert run.g == pytest.approx(0.0, abs=1e-6)
    assert run.centre_offset[0] == pytest.approx(0.01, abs=1e-6)
    assert run.centre_offset[1] == pytest.approx(0.0, abs=1e-9)
    assert run.radius_error == pytest.approx(0.0, abs=1e-6)
    assert c.radius == pytest.approx(R)


def test_an_oval_is_twice_its_amplitude():
    # d = a cos 2θ at 0°, 45°, ..., 315° (a = 0.004): radii R+a, R, R-a, R, ... The points are
    # symmetric under θ -> -θ and θ -> θ + 180°, so the LSC centre is the commanded centre and
    # its radius the mean R: G = (R + a) - (R - a) = 2a = 0.008.
    a = 0.004
    t = np.arange(0, 360, 45)
    c = circular_test(ring(t), a * np.cos(np.radians(2 * t)), direction=np.ones(8))
    run = c.runs["ccw"]
    assert run.g == pytest.approx(2 * a, abs=1e-12)
    assert run.f_max == pytest.approx(a) and run.f_min == pytest.approx(-a)
    assert np.allclose(run.centre_offset, 0, atol=1e-12) and abs(run.radius_error) < 1e-12


def test_hysteresis_is_the_gap_between_the_two_runs():
    # CCW at +0.002 mm, then CW back over the same angles at -0.003 mm: each run is a circle
    # (G = 0) of radius error +0.002 / -0.003; at every angle the runs differ by 0.005 = H;
    # together they span 0.005 about the common centre = G(b); F over both: +0.002, -0.003.
    t = np.arange(0, 360, 30.0)
    forth, back = ring(t), ring(t[::-1])
    dev = np.concatenate([np.full(12, 0.002), np.full(12, -0.003)])
    c = circular_test(np.vstack([forth, back]), dev, direction=np.r_[np.ones(12), -np.ones(12)])
    assert c.runs["ccw"].g == pytest.approx(0, abs=1e-12) and c.runs["cw"].g == pytest.approx(0, abs=1e-12)
    assert c.runs["ccw"].radius_error == pytest.approx(0.002)
    assert c.runs["cw"].radius_error == pytest.approx(-0.003)
    assert c.hysteresis == pytest.approx(0.005)
    assert c.bidirectional == pytest.approx(0.005)
    both = c.runs["both"]
    assert both.f_max == pytest.approx(0.002) and both.f_min == pytest.approx(-0.003) and both.points == 24


def test_hysteresis_only_where_both_runs_go():
    # CCW over 0..180° at 0, CW over the whole circle at -0.001 except -0.010 at 270°
    # (an angle the CCW run never reaches): H = 0.001, not 0.010.
    ccw = np.arange(0, 181, 10.0)
    cw = np.arange(360, 0, -10.0)
    dev_cw = np.where(np.isclose(cw, 270), -0.010, -0.001)
    q = np.vstack([ring(ccw), ring(cw)])
    sense = np.r_[np.ones(len(ccw)), -np.ones(len(cw))]
    c = circular_test(q, np.r_[np.zeros(len(ccw)), dev_cw], direction=sense, centre=[0, 0], radius=R)
    assert c.hysteresis == pytest.approx(0.001)


def test_direction_from_the_order_of_the_points():
    # 0, 10, ..., 350 then 350, 340, ..., 0: the first 36 go counterclockwise, the rest back
    t = np.r_[np.arange(0, 360, 10.0), np.arange(350, -1, -10.0)]
    sense = progression(np.radians(t))
    assert (sense[:36] == 1).all() and (sense[36:] == -1).all()
    c = circular_test(ring(t), np.zeros(len(t)))
    assert c.runs["ccw"].points == 36 and c.runs["cw"].points == 36


def test_a_circle_in_space_is_found_in_its_plane():
    # the circle of radius 50 about (10, 20, 30) in the x-z plane: normal +y (its closest base
    # axis, positive side), u = x, v = y × x = -z; a radial deviation of +0.003 everywhere
    # is a radius error of 0.003 and F_max = F_min = 0.003.
    t = np.radians(np.arange(0, 360, 20.0))
    q = np.column_stack([10 + 50 * np.cos(t), np.full(len(t), 20.0), 30 + 50 * np.sin(t)])
    _, axes = circle_plane(q)
    assert np.allclose(axes, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)
    c = circular_test(q, np.full(len(t), 0.003), direction=np.ones(len(t)))
    assert c.radius == pytest.approx(50) and np.allclose(c.centre, [10, 20, 30])
    assert c.runs["ccw"].radius_error == pytest.approx(0.003) and c.runs["ccw"].f_min == pytest.approx(0.003)


def test_lsc_of_a_shifted_circle():
    # points exactly on the circle of radius 3 about (1, -2): the LSC is that circle
    centre, radius = lsc_circle(ring(np.arange(0, 360, 60), 3.0) + [1.0, -2.0])
    assert np.allclose(centre, [1, -2], atol=1e-12) and radius == pytest.approx(3.0)


def test_bad_circles_are_one_line_errors():
    with pytest.raises(InputError, match="at least 3 points"):
        circular_test(ring([0, 90]), [0, 0])
    with pytest.raises(InputError, match="finite"):
        circular_test(ring([0, 90, 180]), [0, np.nan, 0])
    with pytest.raises(InputError, match="m deviations"):
        circular_test(ring([0, 90, 180]), [0, 0])
    # a square's mid-sides and corners (100 and 100√2 mm from its centre): off any circle by ~10 %
    square = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1]]) * 100.0
    with pytest.raises(InputError, match="no circle"):
        circular_test(square, np.zeros(8))
    # a circle tilted out of its plane by 5 mm at one point (5 % of the radius)
    lifted = np.column_stack([ring(np.arange(0, 360, 30)), np.zeros(12)])
    lifted[3, 2] = 5.0
    with pytest.raises(InputError, match="no circle"):
        circular_test(lifted, np.zeros(12))


def test_pose_accuracy_and_repeatability_by_hand():
    # pose P commanded at (0, 0, 0, 0, 0, π - 0.01), visited 3 times:
    #   positions (2, 0, 0), (0, 2, 0), (1, 1, 3): barycentre (1, 1, 1), AP_x = AP_y = AP_z = 1,
    #   AP_p = √3; l_j = |p_j - (1,1,1)| = √3, √3, 2; l̄ = (2√3 + 2)/3;
    #   l_j - l̄ = (√3 - 2)/3, (√3 - 2)/3, -2(√3 - 2)/3: Σ² = 6(2 - √3)²/9, S_l = (2 - √3)/√3,
    #   RP_l = l̄ + 3 S_l = (2√3 + 2)/3 + √3 (2 - √3) = 2.285468...;
    #   a = 0.01, 0.02, 0.03: AP_a = 0.02, S_a = sqrt((0.01² + 0 + 0.01²)/2) = 0.01, RP_a = 0.03;
    #   c = π - 0.02, -π + 0.01, π - 0.01: wrapped differences from c_c -0.01, +0.02, 0:
    #   AP_c = 0.01/3; deviations (-4, 5, -1)/300: S_c = 0.01 sqrt(7/3), RP_c = 0.01 √21.
    # pose Q at (100, 0, 0, 0, 0, 0), visited once at (100, 0, 0.5, 0, 0.001, 0):
    #   AP_p = 0.5, AP_b = 0.001, no repeatability (NaN).
    cp = [0, 0, 0, 0, 0, np.pi - 0.01]
    commanded = np.array([cp, [100, 0, 0, 0, 0, 0], cp, cp])
    attained = np.array(
        [
            [2, 0, 0, 0.01, 0, np.pi - 0.02],
            [100, 0, 0.5, 0, 0.001, 0],
            [0, 2, 0, 0.02, 0, -np.pi + 0.01],
            [1, 1, 3, 0.03, 0, np.pi - 0.01],
        ]
    )
    s = pose_statistics(commanded, attained, [7, 3, 7, 7], ids=("p1", "q1", "p2", "p3"))
    assert s.ids == ("p1", "q1") and s.visits.tolist() == [3, 1]
    p, q = 0, 1
    assert s.accuracy[p, :3] == pytest.approx([1, 1, 1])
    assert s.position_accuracy[p] == pytest.approx(np.sqrt(3))
    rp = (2 * np.sqrt(3) + 2) / 3 + np.sqrt(3) * (2 - np.sqrt(3))
    assert s.position_repeatability[p] == pytest.approx(rp) and rp == pytest.approx(2.285468, abs=1e-6)
    assert s.accuracy[p, 3:] == pytest.approx([0.02, 0, 0.01 / 3])
    assert s.orientation_repeatability[p] == pytest.approx([0.03, 0, 0.01 * np.sqrt(21)])
    assert s.commanded[p, 5] == pytest.approx(np.pi - 0.01)
    assert s.position_accuracy[q] == pytest.approx(0.5) and s.accuracy[q, 4] == pytest.approx(0.001)
    assert np.isnan(s.position_repeatability[q]) and np.isnan(s.orientation_repeatability[q]).all()
    record = s.to_dict()
    assert record["repeated"] == 1 and record["poses"][0]["id"] == "p1"


def test_repeated_visits_chain_within_the_tolerance():
    # rows 0 and 2 differ by 0.008 on one leg (within 0.01), rows 2 and 3 by 0.008 more
    # (0.016 from row 0: chained); row 1 is elsewhere; row 4 is 0.02 from row 1 (apart)
    r = np.zeros((5, 6))
    r[1] = 5.0
    r[2, 0], r[3, 0] = 0.008, 0.016
    r[4] = 5.0
    r[4, 3] = 5.02
    assert repeated_visits(r, 0.01).tolist() == [0, 1, 0, 0, 2]
    assert repeated_visits(r, 0.0).tolist() == [0, 1, 2, 3, 4]
    with pytest.raises(InputError, match="tolerance"):
        repeated_visits(r, -1)


def test_repeated_visits_with_one_leg_always_alike():
    # leg 1 reads the same everywhere (100 rows within the tolerance of each other in it: the
    # k-d tree path); legs 2-6 pair rows 2k and 2k + 1 (0.004 apart), the pairs 1 mm apart
    r = np.zeros((100, 6))
    r[:, 1:] = (np.arange(100) // 2)[:, None] * 1.0
    r[1::2, 2] += 0.004
    groups = repeated_visits(r, 0.005)
    assert groups.tolist() == (np.arange(100) // 2).tolist()


def test_points_commanded_on_the_circle():
    # positions 0.5 mm outside the circle at 0° and 180° (an oval of commanded positions, the
    # actual path of another machine): with on_circle the actual radius is R0 + d, so zero
    # deviations are a perfect circle, G = 0 and F = 0, whatever the positions' own shape
    t = np.arange(0, 360, 30.0)
    q = ring(t) * (1 + 0.005 * np.cos(np.radians(2 * t)))[:, None]
    off = circular_test(q, np.zeros(12), direction=np.ones(12))
    on = circular_test(q, np.zeros(12), direction=np.ones(12), on_circle=True)
    assert off.runs["ccw"].g == pytest.approx(1.0, abs=1e-9)  # 100.5 - 99.5
    assert on.runs["ccw"].g == pytest.approx(0, abs=1e-12)
    assert on.runs["ccw"].f_max == pytest.approx(0, abs=1e-12)
    # 5 mm out of round (5 % of the radius): no commanded circle (1 %), but positions that only
    # locate the points (a machine's path) may be that far off (10 %)
    oval = ring(t) * (1 + 0.05 * np.cos(np.radians(2 * t)))[:, None]
    with pytest.raises(InputError, match="commanded positions are no circle"):
        circular_test(oval, np.zeros(12), direction=np.ones(12))
    assert circular_test(oval, np.zeros(12), direction=np.ones(12), on_circle=True).runs["ccw"].g < 1e-12


def test_a_tolerance_that_chains_distinct_poses_is_refused():
    # rows 0, 1, 2 chain at 0.01 (0.008 apart in turn) but rows 0 and 2 read 0.016 apart: no
    # visits of one pose; a tolerance beyond 0.1 mm joins distinct poses whatever the data
    r = np.zeros((4, 6))
    r[1, 0], r[2, 0], r[3] = 0.008, 0.016, 5.0
    visits = repeated_visits(r, 0.01)
    assert visits.tolist() == [0, 0, 0, 1]
    with pytest.raises(InputError, match=r"pose a read legs up to 0\.016 mm apart"):
        check_visits(r, visits, 0.01, ("a", "b", "c", "d"))
    check_visits(r, repeated_visits(r, 0.02), 0.02)  # within 0.02 of each other: one pose
    with pytest.raises(InputError, match=r"between 0 and 0\.1 mm, got 1e\+09"):
        repeated_visits(r, 1e9)
