"""The split of the contact reactions' work (solver/energy.reaction_work): Coulomb's closed
form on a slipping link, and the same split for every reaction of a star's motion."""
import numpy as np
import pytest

from dolfrag.solver.energy import reaction_work


@pytest.mark.parametrize("gdim", [2, 3])
def test_a_link_slipping_on_the_cone_dissipates_friction_and_stores_cohesion(gdim):
    rng = np.random.default_rng(1)
    n = 5
    shift, cohesion_T, mu = rng.uniform(1e5, 4e5, n), rng.uniform(1e5, 4e5, n), 0.3
    pressed = rng.uniform(0.0, 1e6, n)  # r_N + shift (Pa)
    dg = rng.normal(0.0, 1e-9, (n, gdim))
    dg[:, 0] = 0.0  # closed links that slide
    slip = np.linalg.norm(dg[:, 1:], axis=1)
    radius = mu * pressed + cohesion_T
    r_T = -radius[:, None] * dg[:, 1:] / slip[:, None]  # on the cone, against the slip
    dissipated, stored = reaction_work(pressed - shift, r_T, dg, shift, cohesion_T)
    # Coulomb: friction mu r~_N |slip|; the cohesion's part of the radius stores the rest
    # (round-off of the products only)
    assert dissipated == pytest.approx(mu * pressed * slip, rel=1e-12)
    assert stored == pytest.approx(cohesion_T * slip, rel=1e-12)


def test_the_split_does_not_depend_on_a_self_stress_of_a_rigid_star():
    """A closed 2D star of six rigid links: adding the self-stress w_l R_l^T r_l = c (same
    on every link, which the star solve cannot tell from zero: it does no work on the
    star) changes every link's reactions but neither what each link stores nor what the
    star dissipates. The former split (the cohesive share of r_T.dg_T) failed this: 1 and 2
    ranks stored 1.09e-7 and 9.1e-9 J/m on a link of sound-bar (energy.reaction_work)."""
    rng = np.random.default_rng(2)
    n = 6
    angle = np.sort(rng.uniform(0, 2 * np.pi, n))  # facet rays around the vertex
    normal = np.stack([-np.sin(angle), np.cos(angle)], axis=1)
    frame = np.stack([normal, np.stack([-normal[:, 1], normal[:, 0]], axis=1)], axis=1)  # (n, 2, 2)
    weight = rng.uniform(1e-3, 2e-3, n)
    x = rng.normal(0.0, 1e-9, (n, 2))  # copy displacements over the two steps (m)
    dg = np.einsum("lij,lj->li", frame, np.roll(x, -1, axis=0) - x)  # link l joins copies l and l + 1
    shift = rng.uniform(3e5, 4e5, n)
    cohesion_T = shift
    r = np.stack([rng.uniform(-3e5, 3e5, n), rng.uniform(-3e5, 3e5, n)], axis=1)
    c = np.array([2e2, -1e2])  # N/m: the self-stress
    r_self = r + np.einsum("lij,j->li", frame, c) / weight[:, None]
    work = lambda r: -weight @ np.sum(r * dg, axis=1)  # noqa: E731
    assert work(r_self) == pytest.approx(work(r), rel=1e-9)  # no work on the star: a self-stress
    assert np.abs(r_self - r).max() > 1e4  # yet the reactions differ by ~5 % of the strength
    diss, stored = reaction_work(r[:, 0], r[:, 1:], dg, shift, cohesion_T)
    diss_self, stored_self = reaction_work(r_self[:, 0], r_self[:, 1:], dg, shift, cohesion_T)
    assert np.array_equal(stored_self, stored)  # read from the motion alone
    # the star's dissipation: its work less what it stores, the same to round-off of the sum
    assert weight @ diss_self == pytest.approx(weight @ diss, rel=1e-9)
    assert weight @ (diss + stored) == pytest.approx(work(r), rel=1e-12)


@pytest.mark.parametrize("gdim", [2, 3])
def test_a_held_joints_elastic_work_is_stored_and_the_rest_split_as_for_a_rigid_link(gdim):
    """A rigid link's elastic joint (solver/active_set.COMPLIANCE) moves by dg_el: the work of
    its reactions on that part is stored (given back as it unloads), and the split of the
    rest is the rigid link's: a link slipping on its cone with an elastic part on top
    dissipates only its friction, whatever the elastic part (round-off of the products)."""
    from dolfrag.solver.energy import book_reaction_work
    rng = np.random.default_rng(4)
    n = 6
    shift, cohesion_T, mu = rng.uniform(1e5, 4e5, n), rng.uniform(1e5, 4e5, n), 0.3
    pressed = rng.uniform(0.0, 1e6, n)
    slide = rng.normal(0.0, 1e-9, (n, gdim))
    slide[:, 0] = 0.0
    slip = np.linalg.norm(slide[:, 1:], axis=1)
    r = np.column_stack([pressed - shift, -(mu * pressed + cohesion_T)[:, None] * slide[:, 1:] / slip[:, None]])
    elastic = rng.normal(0.0, 1e-10, (n, gdim))  # the joint's part of this step's and the last's increments
    weight, links, absorbed = np.ones(n), np.arange(n), np.zeros(n)
    # the window's increments, half this step's and half the last's, the joint's part on top
    this, before = 0.5 * (slide + elastic), 0.5 * (slide + elastic)
    dissipated = book_reaction_work(r, this, before, elastic, shift, cohesion_T, weight, links, absorbed)
    # the closed forms and the split are the same products summed in another order: round-off
    # of those sums only (terms of one sign, a handful of ulps), as in the first test above
    assert dissipated == pytest.approx(0.5 * np.sum(mu * pressed * slip), rel=1e-12)
    assert absorbed == pytest.approx(0.5 * (cohesion_T * slip - np.sum(r * elastic, axis=1)), rel=1e-12)


@pytest.mark.parametrize("gdim", [2, 3])
def test_a_jump_that_is_all_the_joints_elastic_part_is_no_opening_of_the_law(gdim):
    """active_set.joint_jumps: where a rigid cohesive link's jumps are its joint's elastic jump
    -c r (c = COMPLIANCE / rho) at both ends of the step, the law's opening is zero and the
    step's increment is all the joint's; on a broken (shift 0) or frozen link there is no
    joint, so the opening is the mid jump and the joint's increment is zero."""
    from dolfrag.solver.active_set import COMPLIANCE, joint_jumps
    rng = np.random.default_rng(7)
    n = 9
    rho = rng.uniform(1e12, 1e14, n)
    shift = np.where(np.arange(n) % 3 == 0, 0.0, rng.uniform(1e6, 3e6, n))  # every third link broken
    frozen = np.arange(n) % 4 == 1
    r_n, r = rng.normal(0.0, 1e6, (n, gdim)), rng.normal(0.0, 1e6, (n, gdim))
    c = COMPLIANCE / rho[:, None]
    g_n = -c * r_n
    slip = -c * (r - r_n)  # g_{n+1} = -c r
    g_mid, opening, joint = (np.empty((n, gdim)) for _ in range(3))
    joint_jumps(g_n, slip, r_n, r, shift, rho, frozen, g_mid, opening, joint)
    np.testing.assert_array_equal(g_mid, g_n + 0.5 * slip)
    held = (shift > 0) & ~frozen
    assert held.sum() >= 3 and (~held).sum() >= 3
    # round-off of the cancelling products only: terms of size c |r|, a few ulps of them (1e-14: ~50)
    scale = np.abs(c * np.maximum(np.abs(r), np.abs(r_n))).max()
    np.testing.assert_allclose(opening[held], 0.0, atol=1e-14 * scale)
    # the same product -c (r - r_n) as slip above, its c formed as COMPLIANCE / rho inside the
    # kernel: equal to an ulp or two
    np.testing.assert_allclose(joint[held], slip[held], rtol=1e-14)
    np.testing.assert_array_equal(opening[~held], g_mid[~held])
    np.testing.assert_array_equal(joint[~held], 0.0)
