"""Petrič & Žlajpah's velocity field (eqs. 4–19): the laws at hand-computed points, the readings
of eqs. 6, 11 and 12, the latch, the rate limiter and its QP level on every backend (profile
"tight"), and the properties of §II-A over 10⁴ random points and sequences — with the
counterexamples where a property does not hold as printed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import assert_kkt
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc
from wbc.papers.petric import VelocityField, rate_limit_interval, rate_limited_twist, smoothstep
from wbc.robots import tiago_base
from wbc.solvers import available_backends

BACKENDS = available_backends()
DEG = math.pi / 180.0


def random_points(rng, n, half_width=1.2):
    """``n`` points in a box around the robot: x, y in ±half_width, z in [−0.4, 1.2] m."""
    return np.column_stack([rng.uniform(-half_width, half_width, (n, 2)),
                            rng.uniform(-0.4, 1.2, n)])


# ----------------------------------------------------------------------------- parameters
def test_defaults_are_the_papers_section_iv_and_ours_documented():
    f = VelocityField()
    assert (f.l0, f.l1, f.l2) == (0.333, 0.328, 0.394)
    assert (f.k_f, f.k_r, f.k_omega, f.delta_f, f.delta_r) == (2.0, 2.0, 1.0, 0.15, 0.15)
    assert (f.phi_min, f.phi_max, f.phi_t) == pytest.approx((30 * DEG, 45 * DEG, 30 * DEG))
    assert (f.alpha, f.omega_max, f.dv_max, f.domega_max) == (0.25, 1.0, 1.0, 1.0)
    assert (f.b_d, f.epsilon, f.v_max) == (0.27, 0.05, 1.0)  # ours: the paper leaves them open
    assert f.r_f == pytest.approx(0.722)


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"l1": 0.0}, wbc.InvalidValueError, "l1"),
    ({"k_r": -1.0}, wbc.InvalidValueError, "k_r"),
    ({"phi_max": 20 * DEG}, wbc.InvalidValueError, "phi_max"),
    ({"phi_t": 4.0}, wbc.InvalidValueError, "phi_t"),
    ({"epsilon": 0.0}, wbc.InvalidValueError, "epsilon"),
    ({"alpha": 1.5}, wbc.InvalidValueError, "alpha"),
    ({"dv_max": 0.0}, wbc.InvalidValueError, "dv_max"),
    ({"v_max": float("nan")}, wbc.NonFiniteError, "v_max"),
    ({"b_d": "wide"}, wbc.InvalidValueError, "b_d"),
])
def test_bad_parameters_name_themselves(kwargs, error, match):
    with pytest.raises(error, match=match):
        VelocityField(**kwargs)


def test_bad_points_name_p():
    f = VelocityField()
    with pytest.raises(wbc.ShapeError, match="p"):
        f.raw([0.1, 0.2])
    with pytest.raises(wbc.NonFiniteError, match="p"):
        f.step([0.1, np.nan, 0.2])
    with pytest.raises(wbc.ShapeError, match="p"):
        f.step(np.zeros((2, 3)))
    with pytest.raises(wbc.InvalidValueError, match="phi_t"):
        f.raw([0.1, 0.2, 0.3], phi_t=4.0)
    with pytest.raises(wbc.ShapeError, match="command"):
        f.reset([0.0])


# ----------------------------------------------------------------------------- geometry and laws
def test_distances_by_hand():
    f = VelocityField()
    d_f, d_r, phi = f.distances([0.3, 0.4, 0.1])            # below the shoulder: planar d_r
    assert d_f == pytest.approx(0.722 - math.hypot(0.5, 0.233))
    assert d_r == pytest.approx(0.5 - 0.27)
    assert phi == pytest.approx(math.atan2(0.4, 0.3))
    _, d_r, _ = f.distances([0.3, 0.0, 0.733])               # above: distance to the shoulder
    assert d_r == pytest.approx(0.5 - 0.27)


def test_eq6_read_as_distance_outside_the_capsule_and_continuous_at_l0():
    """Eq. 6 as printed (``b_d − |·|``) would retreat from a distant point; the reading
    ``|·| − b_d`` retreats next to the base (the text and eq. 20's argument)."""
    f = VelocityField()
    assert f.raw([0.0, 0.05, 0.2])[0] < 0.0                  # next to the base: retreat
    assert f.raw([0.5, 0.0, 0.4])[0] == 0.0                  # comfortable: stand still
    assert f.raw([0.9, 0.0, 0.4])[0] > 0.0                   # near the reach sphere: forward
    rng = np.random.default_rng(1)
    xy = rng.uniform(-1, 1, (200, 2))
    below = f.distances(np.column_stack([xy, np.full(200, f.l0)]))[1]
    above = f.distances(np.column_stack([xy, np.full(200, f.l0 + 1e-12)]))[1]
    np.testing.assert_allclose(below, above, atol=1e-11)


def test_raw_laws_at_hand_computed_points():
    f = VelocityField()
    v, omega = f.raw([0.8, 0.0, 0.3])                        # eq. 7 forward branch, φ = 0
    assert v == pytest.approx(2.0 * (0.15 - (0.722 - math.hypot(0.8, 0.033))))
    assert omega == 0.0
    p = [0.5 * math.cos(40 * DEG), 0.5 * math.sin(40 * DEG), 0.3]
    s = (40 - 30) / 15
    assert f.raw(p)[1] == pytest.approx(3 * s**2 - 2 * s**3)  # eqs. 8-9 inside the band
    assert f.raw([0.0, -0.5, 0.3])[1] == -1.0                   # |φ| ≥ φ_max: full turn
    # retreat, deeper than ε: v = −K_r(Δ_r − d_r), ω = −sign(φ_t − φ)·ω_max with φ_t = −30°
    v, omega = f.raw([0.2, 0.1, 0.3])
    assert v == pytest.approx(-2.0 * (0.15 - (math.hypot(0.2, 0.1) - 0.27)))
    assert omega == 1.0
    assert f.raw([0.2, -0.1, 0.3])[1] == -1.0                   # φ < 0: φ_t = +30°
    assert f.raw([0.2, 0.1, 0.3], phi_t=40 * DEG)[1] == -1.0    # latched: towards φ_t


def test_raw_is_vectorised_like_pointwise():
    f = VelocityField()
    pts = random_points(np.random.default_rng(2), 50)
    v, omega = f.raw(pts)
    assert v.shape == omega.shape == (50,)
    for i in range(50):
        assert (v[i], omega[i]) == f.raw(pts[i])


def test_eta_reading_is_continuous_and_the_printed_one_jumps():
    """Eq. 12 with ``s = (Δ_r − d_r)/ε``: η = 0 at the boundary, 1 at depth ε, continuous. As
    printed, ``s = (d_r − (Δ_r − ε))/ε`` gives η → 1 just inside the boundary (the d_r ≥ Δ_r
    branch is 0) and η → 0 just above depth ε (that branch is 1): a jump at both ends."""
    f = VelocityField()
    eps, dr_bound = f.epsilon, f.delta_r
    printed = smoothstep((dr_bound - 1e-9 - (dr_bound - eps)) / eps)
    assert printed == pytest.approx(1.0)
    printed = smoothstep((dr_bound - eps + 1e-9 - (dr_bound - eps)) / eps)
    assert printed == pytest.approx(0.0, abs=1e-12)
    # ours: ω_r at a point straight ahead (latched φ_t = +30° → ω_r = −η) just inside / deep
    radius = f.b_d + f.delta_r
    just_inside = f.raw([radius - 1e-9, 0.0, 0.3], phi_t=30 * DEG)[1]
    at_depth = f.raw([radius - eps - 1e-9, 0.0, 0.3], phi_t=30 * DEG)[1]
    assert just_inside == pytest.approx(0.0, abs=1e-12) and at_depth == pytest.approx(-1.0)


# ----------------------------------------------------------------------------- the stateful tick
def test_step_latches_the_heading_on_entry_and_releases_it_on_exit():
    f = VelocityField()
    f.step([0.5, 0.0, 0.3])
    assert f.heading is None
    f.step([0.2, 0.05, 0.3])                                  # enters at φ > 0
    assert f.heading == pytest.approx(-30 * DEG)
    f.step([0.2, -0.05, 0.3])                                 # crosses φ = 0: stays latched
    assert f.heading == pytest.approx(-30 * DEG)
    assert f.raw([0.2, -0.05, 0.3], f.heading)[1] > 0.0      # still turning towards −30°
    assert f.raw([0.2, -0.05, 0.3])[1] < 0.0                 # unlatched it would turn back
    f.step([0.6, 0.0, 0.3])
    assert f.heading is None
    f.step([0.2, 0.0, 0.3])                                   # entry straight ahead: sign(0)=+1
    assert f.heading == pytest.approx(-30 * DEG)
    f.reset()
    assert f.heading is None and np.all(f.command == 0.0)


def test_step_is_eqs_14_to_17_on_the_raw_command():
    f = VelocityField(alpha=0.5, dv_max=0.1, domega_max=0.05)
    f.reset([0.3, -0.2])
    p = [0.2, 0.1, 0.3]
    raw = np.array(f.raw(p))
    smoothed = 0.5 * np.array([0.3, -0.2]) + 0.5 * raw
    expected = np.clip([0.3, -0.2] + np.clip(smoothed - [0.3, -0.2], [-0.1, -0.05], [0.1, 0.05]),
                       -1.0, 1.0)
    np.testing.assert_allclose(f.step(p), expected, atol=1e-15)
    np.testing.assert_allclose(f.command, expected, atol=1e-15)


# ----------------------------------------------------------------------------- eqs. 16-17
@settings(max_examples=200)
@given(st.integers(0, 2**32 - 1))
def test_two_stage_clip_is_the_projection_onto_the_clipped_rate_interval(seed):
    """docs/DESIGN.md, math note 5, including previous commands outside ``limit + rate`` (both
    give ±limit)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 4))
    limit, rate = rng.uniform(0.1, 2.0, n), rng.uniform(0.01, 1.0, n)
    previous = rng.uniform(-1.5, 1.5, n) * (limit + rate)
    target = rng.uniform(-3.0, 3.0, n)
    lower, upper = rate_limit_interval(previous, limit, rate)
    assert np.all(lower <= upper)
    np.testing.assert_allclose(rate_limited_twist(target, previous, limit, rate),
                               np.clip(target, lower, upper), atol=1e-15)


def test_rate_limiter_bad_input_names_the_argument():
    with pytest.raises(wbc.InvalidValueError, match="rate_limit"):
        rate_limited_twist([0.0, 0.0], [0.0, 0.0], 1.0, [0.1, 0.0])
    with pytest.raises(wbc.ShapeError, match="previous"):
        rate_limited_twist([0.0, 0.0], [0.0, 0.0, 0.0], 1.0, 0.1)
    with pytest.raises(wbc.NonFiniteError, match="target"):
        rate_limited_twist([0.0, np.inf], [0.0, 0.0], 1.0, 0.1)
    with pytest.raises(wbc.ShapeError, match="rate_limit_level"):
        VelocityField().rate_limit_level(wbc.Stack(wbc.Variables(qd=3)))


LIMITED = VelocityField(v_max=0.8, omega_max=0.6, dv_max=0.3, domega_max=0.2)
_WORKSPACES: dict = {}
PROXQP_WARM_START = ("proxqp, warm-started from the previous tick, reaches max_iter on the "
                     "min-norm level of the whole-body-shaped stack in ~4 % of random ticks "
                     "(11 of 300; 0 of 300 from a fresh workspace or without the arm block); "
                     "not this level's doing: LinearTask + Bounds with the same numbers fail "
                     "on the same ticks")


def _rate_limit_workspace(backend, arm: int):
    """The level over ``qd_base = (v, ω)`` at priority 0, alone (``arm = 0``) or beside an arm
    block it does not touch (the minimum-norm level pins that to 0). Built once per backend and
    reused from tick to tick, as in a control loop."""
    if (backend, arm) not in _WORKSPACES:
        blocks = {"qd_base": 2, "qd_arm": arm} if arm else {"qd_base": 2}
        stack = wbc.Stack(wbc.Variables(blocks))
        LIMITED.rate_limit_level(stack, priority=0, block="qd_base", name="rl")
        _WORKSPACES[backend, arm] = stack.workspace(backend, "tight")
    return _WORKSPACES[backend, arm]


def _check_level(backend, arm, target, previous):
    ws = _rate_limit_workspace(backend, arm)
    ws.set(**{"rl.target": target, "rl.previous": previous})
    sol = ws.solve()
    assert sol.ok, sol.message
    expected = rate_limited_twist(target, previous, LIMITED.limit, LIMITED.rate_limit)
    np.testing.assert_allclose(sol.x[:2], expected, atol=1e-7)
    np.testing.assert_allclose(sol.x[2:], 0.0, atol=1e-7)
    assert_kkt(ws)


def _random_instance(seed):
    rng = np.random.default_rng(seed)
    previous = rng.uniform(-1.0, 1.0, 2) * LIMITED.limit
    target = previous + rng.uniform(-2.0, 2.0, 2) * (LIMITED.limit + LIMITED.rate_limit)
    return target, previous


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("target", "previous"), [
    ([5.0, -5.0], [0.7, -0.5]),      # v: rate then saturation bind; ω: saturation binds
    ([0.75, 0.55], [0.6, 0.3]),      # both inside both intervals: û itself
    ([-3.0, 3.0], [0.2, 0.0]),       # rate limit binds on both
    ([3.0, 0.0], [2.0, 2.0]),        # previous beyond limit + rate: ±limit (clipped interval)
])
def test_qp_level_equals_the_two_stage_clip_on_hand_cases(backend, target, previous):
    _check_level(backend, 0, np.array(target), np.array(previous))


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=15)
@given(st.integers(0, 2**32 - 1))
def test_qp_level_equals_the_two_stage_clip(backend, seed):
    _check_level(backend, 0, *_random_instance(seed))


@pytest.mark.parametrize("backend", [
    pytest.param(b, marks=pytest.mark.xfail(reason=PROXQP_WARM_START, strict=False))
    if b == "proxqp" else b for b in BACKENDS])
def test_qp_level_beside_an_arm_block_equals_the_two_stage_clip(backend):
    for seed in range(40):
        _check_level(backend, 3, *_random_instance(seed))


# ----------------------------------------------------------------------------- §II-A: bounds
def _random_sequence(field, rng, ticks):
    """Apply ``field.step`` to a random TEE path: a random walk with occasional jumps anywhere
    in a box of ±3 m (so the raw commands run far beyond the limits); returns ``(ticks, 2)``."""
    p = random_points(rng, 1)[0]
    out = np.empty((ticks, 2))
    for k in range(ticks):
        if rng.random() < 0.05:
            p = random_points(rng, 1, half_width=3.0)[0]
        else:
            p = p + rng.normal(0.0, 0.03, 3)
        out[k] = field.step(p)
    return out


def _assert_bounded(field, commands):
    v, omega = commands[:, 0], commands[:, 1]
    assert np.abs(v).max() <= field.v_max and np.abs(omega).max() <= field.omega_max
    steps = np.abs(np.diff(np.vstack([[0.0, 0.0], commands]), axis=0))
    assert steps[:, 0].max() <= field.dv_max + 1e-15
    assert steps[:, 1].max() <= field.domega_max + 1e-15


def test_bounds_and_rate_limits_hold_over_ten_thousand_ticks():
    """Eq. 21 and the per-tick rate limits, 50 sequences × 200 ticks of the paper's field."""
    field, rng = VelocityField(), np.random.default_rng(3)
    commands = []
    for _ in range(50):
        field.reset()
        commands.append(_random_sequence(field, rng, 200))
    for c in commands:
        _assert_bounded(field, c)
    stacked = np.vstack(commands)
    assert np.isclose(np.abs(stacked[:, 0]).max(), field.v_max)  # the limits are reached


@settings(max_examples=25)
@given(st.integers(0, 2**32 - 1), st.floats(0.05, 1.0), st.floats(0.1, 2.0), st.floats(0.1, 2.0),
       st.floats(0.005, 0.5), st.floats(0.005, 0.5))
def test_bounds_and_rate_limits_hold_for_any_limits(seed, alpha, v_max, omega_max, dv, domega):
    field = VelocityField(alpha=alpha, v_max=v_max, omega_max=omega_max, dv_max=dv,
                          domega_max=domega, k_f=5.0, k_r=5.0, k_omega=3.0)
    _assert_bounded(field, _random_sequence(field, np.random.default_rng(seed), 150))


# ----------------------------------------------------------------------------- §II-A: continuity
def _angle_gap(phi, cut):
    return np.abs(np.angle(np.exp(1j * (phi - cut))))


@pytest.mark.parametrize("heading", [None, -30 * DEG, 30 * DEG])
def test_v_and_omega_are_lipschitz_within_each_mode_away_from_the_cuts(heading):
    """10⁴ random pairs ``p, p + δ`` (|δ| = 1e-6 m) in the same mode and on the same side of
    every cut listed in the module docstring: |Δv| ≤ K|δ| (d_f, d_r are 1-Lipschitz) and
    |Δω| ≤ (K_ω·1.5/(φ_max − φ_min)/|p_⊥| + ω_max·1.5/ε)|δ| (slopes of the smoothsteps)."""
    f, rng, h = VelocityField(), np.random.default_rng(4), 1e-6
    p = random_points(rng, 10_000)
    step = rng.normal(size=(10_000, 3))
    q = p + h * step / np.linalg.norm(step, axis=1, keepdims=True)
    _, dr_p, phi = f.distances(p)
    _, dr_q, _ = f.distances(q)
    planar = np.hypot(p[:, 0], p[:, 1])
    retreat = dr_p < f.delta_r
    same_mode = (retreat == (dr_q < f.delta_r)) & (np.abs(dr_p - f.delta_r) > 2 * h)
    cuts = [np.pi, np.where(retreat, 0.0 if heading is None else heading, np.pi)]
    clear = same_mode & (planar > 1e-3)
    for cut in cuts:
        clear &= _angle_gap(phi, cut) > 4 * h / planar
    assert clear.sum() > 9_000
    v_p, w_p = f.raw(p[clear], heading)
    v_q, w_q = f.raw(q[clear], heading)
    slope_v = max(f.k_f, f.k_r)
    slope_w = (f.k_omega * 1.5 / (f.phi_max - f.phi_min) / (planar[clear] - h)
               + f.omega_max * 1.5 / f.epsilon)
    assert np.all(np.abs(v_q - v_p) <= slope_v * h * (1 + 1e-6) + 1e-12)
    assert np.all(np.abs(w_q - w_p) <= slope_w * h * (1 + 1e-6) + 1e-12)


def test_continuity_counterexamples_as_printed():
    """Where the printed laws jump (module docstring); each jump is a full ±K_ω or ±ω_max."""
    f, t = VelocityField(), 1e-9
    jumps = {
        # nominal mode, behind the base: φ = ±π flips sign(φ)·γ(|φ|)
        "behind": (f.raw([-0.6, t, 0.3])[1], f.raw([-0.6, -t, 0.3])[1]),
        # nominal mode, on the vertical axis above the capsule: φ undefined
        "axis": (f.raw([t, 0.0, 0.85])[1], f.raw([0.0, t, 0.85])[1]),
        # retreat zone, latched φ_t = −30°: the bang-bang sign of eq. 10
        "at heading": (f.raw([0.2 * math.cos(-30 * DEG + t), 0.2 * math.sin(-30 * DEG + t), 0.3],
                             -30 * DEG)[1],
                       f.raw([0.2 * math.cos(-30 * DEG - t), 0.2 * math.sin(-30 * DEG - t), 0.3],
                             -30 * DEG)[1]),
        # retreat zone, unlatched: φ_t = −sign(φ)|φ_t| flips at φ = 0
        "ahead, unlatched": (f.raw([0.2, t, 0.3])[1], f.raw([0.2, -t, 0.3])[1]),
    }
    for name, (a, b) in jumps.items():
        assert abs(a - b) >= 1.0, name
    # the mode boundary where the forward zone meets the retreat zone (low z): v jumps
    radius, z = f.b_d + f.delta_r, -0.3
    outside, inside = f.raw([radius + t, 0.0, z])[0], f.raw([radius - t, 0.0, z])[0]
    assert outside == pytest.approx(f.k_f * (f.delta_f - (f.r_f - math.hypot(radius, z - f.l0))))
    assert outside > 0.1 and inside == pytest.approx(0.0, abs=1e-8)


def _unit(rng, n):
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def _on_switch_surfaces(f, rng, n):
    """``n`` random points on each surface where a law switches branch inside a mode: the
    forward activation ``d_f = Δ_f``, the heading band ends ``|φ| = φ_min, φ_max``, the end of
    the retreat ramp ``d_r = Δ_r − ε`` (below and above the shoulder) and eq. 6's ``z = l0``."""
    c = np.array([0.0, 0.0, f.l0])
    radius, angle = rng.uniform(0.3, 1.2, n), rng.choice([-1.0, 1.0], n)
    z = rng.uniform(-0.4, 1.2, n)
    ring = f.b_d + f.delta_r - f.epsilon
    around = rng.uniform(-np.pi, np.pi, n)
    upper = _unit(rng, n)
    upper[:, 2] = np.abs(upper[:, 2])
    return {
        "d_f = delta_f": c + (f.r_f - f.delta_f) * _unit(rng, n),
        "phi = phi_min": np.column_stack([radius * np.cos(angle * f.phi_min),
                                          radius * np.sin(angle * f.phi_min), z]),
        "phi = phi_max": np.column_stack([radius * np.cos(angle * f.phi_max),
                                          radius * np.sin(angle * f.phi_max), z]),
        "d_r = delta_r - eps (z <= l0)": np.column_stack([ring * np.cos(around),
                                                          ring * np.sin(around),
                                                          rng.uniform(-0.4, f.l0, n)]),
        "d_r = delta_r - eps (z > l0)": c + ring * upper,
        "z = l0": np.column_stack([rng.uniform(-1.2, 1.2, (n, 2)), np.full(n, f.l0)]),
    }


@pytest.mark.parametrize("heading", [None, -30 * DEG])
def test_v_and_omega_are_continuous_across_every_branch_switch_within_a_mode(heading):
    """The pairs ``s ± δ`` (|δ| = 1e-7 m) straddle a switch surface: the laws must not jump
    there (eq. 12 as printed would, at ``d_r = Δ_r − ε``). Pairs that change mode or straddle a
    cut of the module docstring are set aside; 10⁴ pairs in all."""
    f, rng, h = VelocityField(), np.random.default_rng(5), 1e-7
    checked = 0
    for name, s in _on_switch_surfaces(f, rng, 1_700).items():
        delta = h * _unit(rng, len(s))
        a, b = s - delta, s + delta
        (_, dr_a, phi), (_, dr_b, _) = f.distances(a), f.distances(b)
        planar = np.hypot(s[:, 0], s[:, 1])
        retreat = dr_a < f.delta_r
        keep = (retreat == (dr_b < f.delta_r)) & (np.abs(dr_a - f.delta_r) > 4 * h)
        keep &= planar > 1e-3
        for cut in (np.pi, np.where(retreat, 0.0 if heading is None else heading, np.pi)):
            keep &= _angle_gap(phi, cut) > 4 * h / planar
        assert keep.sum() > 500, name
        checked += keep.sum()
        (v_a, w_a), (v_b, w_b) = f.raw(a[keep], heading), f.raw(b[keep], heading)
        slope_w = (f.k_omega * 1.5 / (f.phi_max - f.phi_min) / (planar[keep] - h)
                   + f.omega_max * 1.5 / f.epsilon)
        assert np.all(np.abs(v_b - v_a) <= max(f.k_f, f.k_r) * 2 * h * (1 + 1e-6) + 1e-12), name
        assert np.all(np.abs(w_b - w_a) <= slope_w * 2 * h * (1 + 1e-6) + 1e-12), name
    assert checked > 7_000


# ----------------------------------------------------------------------------- §II-A: invariance
BASE = tiago_base()  # the kinematic model of eqs. 1–3 (integrate_pose: exact arcs)


def _in_base_frame(pose, p_world):
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = p_world[0] - pose[0], p_world[1] - pose[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, p_world[2]])


def _closed_loop_d_r(field, p_world, ticks, dt=0.01):
    """``d_r`` per tick while the field drives the base (eqs. 1–3) and the arm holds the TEE
    fixed in the world (``p_world`` [m]; the base starts at the origin, at rest)."""
    field.reset()
    pose, out = np.zeros(3), np.empty(ticks)
    for k in range(ticks):
        p = _in_base_frame(pose, p_world)
        out[k] = field.distances(p)[1]
        pose = BASE.integrate_pose(pose, field.step(p), dt)
    return out


def test_retreat_law_pushes_out_only_points_in_front_of_the_axle():
    """§II-A.2's argument in continuous time: with ``v < 0`` the rate of ``d_r`` for a TEE fixed
    in the world is ``−v·x/ρ`` (``ρ`` the distance eq. 6 measures; ω does not change it). Over
    10⁴ random retreat-zone points it is > 0 for ``x > 0`` — and < 0 for ``x < 0``: behind the
    axle the retreat drives the base onto the point, which the paper's argument overlooks."""
    f, rng, dt = VelocityField(), np.random.default_rng(6), 1e-6
    ring = rng.uniform(0.02, f.b_d + f.delta_r - 0.01, 10_000)
    angle = rng.uniform(-np.pi, np.pi, 10_000)
    p = np.column_stack([ring * np.cos(angle), ring * np.sin(angle),
                         rng.uniform(-0.4, f.l0, 10_000)])
    rates = np.empty(10_000)
    for i, point in enumerate(p):
        after = BASE.integrate_pose(np.zeros(3), f.raw(point), dt)
        rates[i] = (f.distances(_in_base_frame(after, point))[1] - f.distances(point)[1]) / dt
    front, behind = p[:, 0] > 1e-3, p[:, 0] < -1e-3
    assert np.all(rates[front] > 0.0) and np.all(rates[behind] < 0.0)
    v = f.raw(p)[0]
    np.testing.assert_allclose(rates, -v * p[:, 0] / np.hypot(p[:, 0], p[:, 1]), atol=1e-4)


def test_safe_region_stays_safe_where_the_forward_zone_does_not_reach_it():
    """Closed loop, TEE held fixed in the world (with the arm's joints frozen instead, ``p`` is
    constant in the base frame and the property is vacuous), base from rest, 10 ms ticks: for
    ``z ≥ 0`` the forward zone (``d_f < Δ_f``) lies ≥ 4.5 cm outside the retreat zone, and
    ``d_r ≥ Δ_r`` at the start stays so — 60 random placements × 150 ticks."""
    f, rng = VelocityField(), np.random.default_rng(7)
    runs = 0
    while runs < 60:
        p_world = np.array([*rng.uniform(-1.0, 1.0, 2), rng.uniform(0.0, 1.1)])
        if f.distances(p_world)[1] < f.delta_r:
            continue
        runs += 1
        assert _closed_loop_d_r(f, p_world, 150).min() >= f.delta_r, p_world


def test_safe_region_is_entered_where_the_forward_zone_touches_it():
    """Counterexample to §II-A.2 as stated: below ``z ≈ −0.055`` m the forward zone reaches the
    retreat boundary, so the base drives forward into it (``v = K_f(Δ_f − d_f) > 0`` on the
    boundary) and the smoothing lag carries it further: 1.4 cm deep here, starting outside; the
    base then settles on the boundary from inside, where the two laws push against each other."""
    f = VelocityField()
    d_r = _closed_loop_d_r(f, np.array([0.7936, 0.1666, -0.3397]), 400)
    assert d_r[0] >= f.delta_r
    assert f.delta_r - d_r.min() > 0.01
    assert 0.0 < f.delta_r - d_r[-1] < 1e-4


@settings(max_examples=20)
@given(st.integers(0, 2**32 - 1), st.floats(0.5, 3.0), st.floats(0.5, 3.0), st.floats(0.0, 0.3),
       st.floats(0.0, 0.3), st.floats(0.01, 0.2))
def test_zones_decide_the_sign_of_v_and_the_source_of_omega(seed, k_f, k_r, delta_f, delta_r,
                                                           epsilon):
    """Eqs. 7 and 13 over random parameters, 500 points per example (10⁴ in all): the base
    retreats exactly in the retreat zone, advances exactly in the forward zone outside it, and
    stands still elsewhere; ω is ``±ω_max·η`` in the retreat zone and ``±K_ω·γ`` outside."""
    f = VelocityField(k_f=k_f, k_r=k_r, delta_f=delta_f, delta_r=delta_r, epsilon=epsilon)
    p = random_points(np.random.default_rng(seed), 500)
    d_f, d_r, phi = f.distances(p)
    v, omega = f.raw(p)
    retreat, forward = d_r < delta_r, (d_f < delta_f) & (d_r >= delta_r)
    assert np.all(v[retreat] < 0.0) and np.all(v[forward] > 0.0)
    assert np.all(v[~retreat & ~forward] == 0.0)
    eta = smoothstep((delta_r - d_r) / epsilon)
    gamma = smoothstep((np.abs(phi) - f.phi_min) / (f.phi_max - f.phi_min))
    np.testing.assert_allclose(np.abs(omega[retreat]), f.omega_max * eta[retreat], atol=1e-15)
    np.testing.assert_allclose(np.abs(omega[~retreat]), f.k_omega * gamma[~retreat], atol=1e-15)
    assert np.all(omega[~retreat & (np.abs(phi) <= f.phi_min)] == 0.0)      # dead band
