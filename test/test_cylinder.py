"""The cylinder shape: exact mass properties, exact contacts with planes and spheres, the prism hull's
stated error bound for every other pair, scene files and the input contract."""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim.cylinder import hull_error

ID = np.array([0.0, 0.0, 0.0, 1.0])
R_, H_ = 0.1, 0.4          # radius, length
HH = 0.5 * H_


def qx(angle):
    """Rotation about x by ``angle`` (x, y, z, w)."""
    return np.array([np.sin(angle / 2), 0.0, 0.0, np.cos(angle / 2)])


def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def rot(q, v):
    x, y, z, w = q
    u = np.array([x, y, z])
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


@pytest.mark.exact
def test_mass_properties_are_the_formulas():
    c = cs.Cylinder(R_, H_)
    m, com, inertia = c.mass_properties(2700.0)
    mass = 2700.0 * np.pi * R_**2 * H_
    assert m == pytest.approx(mass, rel=1e-15)
    assert np.array_equal(com, np.zeros(3))
    assert np.allclose(inertia, np.diag([mass * (3 * R_**2 + H_**2) / 12] * 2 + [mass * R_**2 / 2]), rtol=1e-15,
                       atol=0)


@pytest.mark.exact
@pytest.mark.parametrize("tilt", [0.05, 0.3, 0.7, 1.2, np.pi / 2 - 0.01, 2.0, np.pi - 0.2])
def test_tilted_cylinder_on_a_plane_touches_at_its_deepest_rim_point(tilt):
    # axis tilted by `tilt` about x: the lowest point is on the lower cap's rim, at height
    # z_c - (h/2)|cos t| - r sin t, and is the only point within the margin
    zc = HH * abs(np.cos(tilt)) + R_ * np.sin(tilt) - 0.01   # 1 cm deep
    centre = np.array([0.3, -0.2, zc])
    c = cs.collide(cs.Cylinder(R_, H_), (centre, qx(tilt)), cs.Plane([0, 0, 1], 0.0), ([0, 0, 0], ID), margin=0.0)
    k = int(np.argmax(c.depth))
    assert c.depth[k] == pytest.approx(0.01, abs=1e-15)
    assert np.allclose(c.normal, [0, 0, 1], atol=0)
    s = 1.0 if np.cos(tilt) > 0 else -1.0          # which cap is lower
    lowest = centre + rot(qx(tilt), np.array([0.0, -R_, -HH * s]))
    assert lowest[2] == pytest.approx(-0.01, abs=1e-15)
    assert np.allclose(c.point[k], lowest + [0, 0, 0.005], atol=1e-15)   # half-way between the surfaces
    # any other point is a true rim point (of the lower cap at small tilts, of the upper one too when
    # the cylinder nearly lies), reported at its own depth
    for p, d in zip(c.point, c.depth):
        surface = p - [0, 0, 0.5 * d]
        local = rot(qx(-tilt), surface - centre)
        assert np.hypot(local[0], local[1]) == pytest.approx(R_, abs=1e-15)
        assert abs(local[2]) == pytest.approx(HH, abs=1e-15) and surface[2] == pytest.approx(-d, abs=1e-15)
    # the candidates: per cap the deepest rim point, its opposite and the two at 90°
    cand = [centre + rot(qx(tilt), np.array([x, y, z])) for z in (-HH, HH) for x, y in
            ((0, -R_), (0, R_), (R_, 0), (-R_, 0))]
    assert len(c.depth) == min(4, sum(p[2] <= 0 for p in cand))


@pytest.mark.exact
def test_cylinder_on_a_tilted_plane_in_any_frame():
    # the same geometry turned as a whole: depth unchanged, normal and point turned with it
    turn = np.array([0.2, -0.3, 0.4, 0.8])
    turn /= np.linalg.norm(turn)
    tilt, zc = 0.4, HH * np.cos(0.4) + R_ * np.sin(0.4) - 0.002
    plane = cs.Plane([0, 0, 1], 0.0)
    c = cs.collide(cs.Cylinder(R_, H_), (rot(turn, np.array([0, 0, zc])), qmul(turn, qx(tilt))), plane,
                   ([0, 0, 0], turn), margin=0.0)
    assert len(c.depth) == 1 and c.depth[0] == pytest.approx(0.002, abs=1e-15)
    assert np.allclose(c.normal[0], rot(turn, np.array([0.0, 0, 1])), atol=1e-15)
    lowest = np.array([0, 0, zc]) + rot(qx(tilt), np.array([0, -R_, -HH]))
    assert np.allclose(c.point[0], rot(turn, lowest + [0, 0, 0.001]), atol=1e-15)


@pytest.mark.exact
def test_flat_cap_gives_four_rim_points_and_a_lying_cylinder_two():
    cyl, plane = cs.Cylinder(R_, H_), cs.Plane([0, 0, 1], 0.0)
    c = cs.collide(cyl, ([1.0, 2.0, HH - 0.003], ID), plane, ([0, 0, 0], ID), margin=0.0)
    assert len(c.depth) == 4 and np.allclose(c.depth, 0.003, atol=1e-15)
    v = c.point[:, :2] - [1.0, 2.0]
    gram = np.sort((v @ v.T).ravel())           # on the rim, 90° apart: a square inscribed in it
    assert np.allclose(gram, [-R_**2] * 4 + [0] * 8 + [R_**2] * 4, atol=1e-15)
    assert np.allclose(np.linalg.norm(c.point[:, :2] - [1.0, 2.0], axis=1), R_, atol=1e-15)
    # on its side: one contact line, reported by its two ends (one per cap)
    c = cs.collide(cyl, ([0.0, 0.0, R_ - 0.004], qx(np.pi / 2)), plane, ([0, 0, 0], ID), margin=0.0)
    assert len(c.depth) == 2 and np.allclose(c.depth, 0.004, atol=1e-15)
    assert np.allclose(np.sort(c.point[:, 1]), [-HH, HH], atol=1e-15) and np.allclose(c.point[:, 0], 0, atol=1e-15)


@pytest.mark.exact
def test_cylinder_apart_from_a_plane_reports_nothing_beyond_the_margin():
    c = cs.collide(cs.Cylinder(R_, H_), ([0, 0, HH + 1e-3], ID), cs.Plane(), ([0, 0, 0], ID), margin=0.5e-3)
    assert len(c.depth) == 0
    c = cs.collide(cs.Cylinder(R_, H_), ([0, 0, HH + 1e-3], ID), cs.Plane(), ([0, 0, 0], ID), margin=2e-3)
    assert len(c.depth) == 4 and np.allclose(c.depth, -1e-3, atol=1e-15)


def _sphere_case(local_centre, rb, pose_q, pose_p):
    cyl, sph = cs.Cylinder(R_, H_), cs.Sphere(rb)
    centre = pose_p + rot(pose_q, np.asarray(local_centre, float))
    return cs.collide(cyl, (pose_p, pose_q), sph, (centre, ID), margin=0.0), centre


POSE_Q = np.array([0.1, 0.5, -0.3, 0.8]) / np.linalg.norm([0.1, 0.5, -0.3, 0.8])
POSE_P = np.array([0.5, -1.0, 2.0])


@pytest.mark.exact
@pytest.mark.parametrize("where, local, depth, outward", [
    ("side", [0.13 * np.cos(0.7), 0.13 * np.sin(0.7), 0.05], 0.05 + R_ - 0.13, [np.cos(0.7), np.sin(0.7), 0]),
    ("cap", [0.03, -0.04, HH + 0.02], 0.05 - 0.02, [0, 0, 1]),
    ("bottom cap", [0.0, 0.0, -HH - 0.049], 0.001, [0, 0, -1]),
    ("rim", [R_ + 0.03, 0.0, HH + 0.01], 0.05 - np.hypot(0.03, 0.01), [0.03 / np.hypot(0.03, 0.01), 0,
                                                                         0.01 / np.hypot(0.03, 0.01)]),
    ("inside, near the side", [0.09, 0.0, 0.0], 0.05 + 0.01, [1, 0, 0]),
    ("inside, near the cap", [0.0, 0.02, HH - 0.005], 0.05 + 0.005, [0, 0, 1]),
])
def test_cylinder_sphere_is_the_closest_point_of_the_solid(where, local, depth, outward):
    c, centre = _sphere_case(local, 0.05, POSE_Q, POSE_P)
    assert len(c.depth) == 1, where
    assert c.depth[0] == pytest.approx(depth, abs=1e-15), where
    n = rot(POSE_Q, np.asarray(outward, float))
    assert np.allclose(c.normal[0], -n, atol=1e-15), where      # B (sphere) → A (cylinder)
    assert np.allclose(c.point[0], centre - n * (0.05 - 0.5 * depth), atol=1e-15), where


@pytest.mark.exact
@pytest.mark.parametrize("local, outward", [
    ([0.066, 0.0, HH * (1 + 2e-16)], [0, 0, 1]),                       # on the cap, outside by round-off
    ([R_ * (1 + 2e-16) * np.cos(0.3), R_ * (1 + 2e-16) * np.sin(0.3), 0.02], [np.cos(0.3), np.sin(0.3), 0]),
])
def test_a_sphere_centred_on_the_cylinder_surface_gets_its_normal(local, outward):
    """A centre on the surface (outside it by round-off: a robot's finger sphere on its arm's cap)
    is as deep as the sphere's radius, along the surface's normal; the closest point was the centre
    itself and its direction 0/0 (NaN contacts, then NaN work in the step's statistics)."""
    c, centre = _sphere_case(local, 0.05, POSE_Q, POSE_P)
    n = rot(POSE_Q, np.asarray(outward, float))
    assert len(c) == 1 and np.isfinite(c.point).all()
    assert c.depth[0] == pytest.approx(0.05, abs=1e-15)
    assert np.allclose(c.normal[0], -n, atol=1e-15)


@pytest.mark.exact
def test_sphere_beside_the_cylinder_beyond_the_rim_does_not_touch():
    # 1 mm clear of the rim along the diagonal: the prism hull would differ, the exact kernel does not
    d = 0.05 + 1e-3
    local = [R_ + d / np.sqrt(2), 0.0, HH + d / np.sqrt(2)]
    c, _ = _sphere_case(local, 0.05, POSE_Q, POSE_P)
    assert len(c.depth) == 0


@pytest.mark.exact
def test_hull_error_bound_is_stated_and_attained():
    # other pairs use the circumscribed prism: a box face approaching square to a side face is exact,
    # one approaching a vertical prism edge sees the cylinder r(sec(pi/N) - 1) too wide, never more
    assert hull_error(1.0) == pytest.approx(1 / np.cos(np.pi / 32) - 1, rel=1e-15)
    assert 0.00482 < hull_error(1.0) < 0.00484                          # 0.48 % of r, as documented
    cyl, box = cs.Cylinder(R_, H_), cs.Box([0.2, 0.2, 0.2])
    worst = 0.0
    for ang in np.linspace(0.0, 2 * np.pi / 32, 9):
        u = np.array([np.cos(ang), np.sin(ang), 0.0])
        q = np.array([0.0, 0.0, np.sin(ang / 2), np.cos(ang / 2)])         # box face normal along -u
        c = cs.collide(cyl, ([0, 0, 0], ID), box, (u * (R_ + 0.1 - 0.01), q), margin=0.0)
        measured = c.depth.max() - 0.01                                      # true depth is 1 cm
        assert -1e-15 <= measured <= hull_error(R_) + 1e-15
        worst = max(worst, measured)
    assert worst == pytest.approx(hull_error(R_), abs=1e-15)                 # at ang = pi/32


def test_cylinder_stands_on_the_floor_and_lies_on_its_side(tmp_path):
    scene = {
        "settings": {"dt": 1 / 240},
        "bodies": [
            {"name": "floor", "kind": "static", "shape": {"type": "plane"}},
            {"name": "can", "shape": {"type": "cylinder", "radius": R_, "length": H_}, "mass": 1.0,
             "position": [0, 0, HH + 0.02]},
            {"name": "log", "shape": {"type": "cylinder", "radius": R_, "length": H_}, "mass": 1.0,
             "position": [1, 0, R_ + 0.02], "orientation": qx(np.pi / 2).tolist()},
        ],
    }
    w = cs.load_scene(scene)
    for _ in range(240):
        w.step()
    can, log = w.body("can"), w.body("log")
    assert can.position[2] == pytest.approx(HH, abs=1e-6) and np.linalg.norm(can.velocity) < 1e-6
    assert log.position[2] == pytest.approx(R_, abs=1e-6) and np.linalg.norm(log.velocity) < 1e-6
    assert "cylinder" in w.describe()


@pytest.mark.exact
@pytest.mark.parametrize("shape, message", [
    ({"type": "cylinder", "radius": -0.1, "length": 1.0}, "bodies[0].shape.radius"),
    ({"type": "cylinder", "radius": 0.1, "length": 0.0}, "bodies[0].shape.length"),
    ({"type": "cylinder", "radius": 0.1}, "bodies[0].shape.length: required"),
    ({"type": "cylinder", "radius": float("nan"), "length": 1.0}, "bodies[0].shape.radius"),
    ({"type": "cylinder", "radius": 0.1, "length": 1.0, "size": 3}, "bodies[0].shape"),
    ({"type": "cylinder", "radius": 2e4, "length": 1.0}, "bodies[0].shape.radius"),   # beyond max_size
])
def test_bad_cylinders_are_refused_by_name(shape, message):
    with pytest.raises(cs.ContactSimError) as err:
        cs.load_scene({"bodies": [{"name": "c", "shape": shape}]})
    assert message in str(err.value)


@pytest.mark.exact
def test_bad_cylinder_in_code_names_the_argument():
    with pytest.raises(cs.ContactSimError, match=r"cylinder\.length"):
        cs.Cylinder(0.1, -1)
    with pytest.raises(cs.ContactSimError, match=r"cylinder\.radius"):
        cs.Cylinder("a", 1)


def test_cylinder_kernels_are_there_whatever_kernel_module_was_imported_first(repo):
    # the dispatch table loads all kernel modules on first use, even when one was imported before
    import subprocess
    import sys

    code = ("import contact_sim as cs\nfrom contact_sim.collision import primitives\n"
            "I = [0, 0, 0, 1]\n"
            "c = cs.collide(cs.Cylinder(0.1, 0.4), ([0, 0, 0.19], I), cs.Plane(), ([0, 0, 0], I))\n"
            "print(len(c.depth))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=repo, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-1] == "4"


@pytest.mark.exact
@pytest.mark.parametrize("offset", [1.79e-162, 1e-200, 5e-324])
def test_sphere_centre_off_the_axis_below_the_square_roots_range_leaves_by_the_side_along_the_offset(offset):
    """A sphere's centre inside a long cylinder, ``offset`` (m) off its axis: ``x² + y²``
    underflows (1.79e-162 squares below the smallest double), and the radial direction was
    ``x / sqrt(x²)`` = 0.806 long. It is the unit offset direction, and the depth the side's."""
    for axis in range(2):
        p = np.zeros(3)
        p[axis] = offset
        c = cs.collide(cs.Cylinder(0.1, 2.0), (np.zeros(3), (0.0, 0.0, 0.0, 1.0)), cs.Sphere(0.02),
                       (p, (0.0, 0.0, 0.0, 1.0)))
        assert len(c) == 1
        np.testing.assert_array_equal(c.normal[0], -np.eye(3)[axis])   # B → A: into the cylinder
        np.testing.assert_allclose(c.depth[0], 0.1 + 0.02, rtol=1e-15)
