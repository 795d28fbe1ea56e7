"""Concave–concave pairs (issue 14, part 2): the lecture's vertex-inside (ray parity) and edge–face
tests over per-mesh AABB trees, in collide, detection and stepping."""
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation as Rot

import contact_sim as cs
from contact_sim.collision.mesh_mesh import build_bvh

I = (0.0, 0.0, 0.0, 1.0)


def mesh(t):
    return cs.TriMesh(t.vertices, t.faces)


def l_prism(arm=1.0, size=2.0, height=1.0):
    """An L-shaped prism (concave): [0, size]×[0, arm] ∪ [0, arm]×[0, size], z in [0, height]."""
    v2 = np.array([[0, 0], [size, 0], [size, arm], [arm, arm], [arm, size], [0, size]], float)
    f2 = np.array([[3, 4, 5], [3, 5, 0], [3, 0, 1], [3, 1, 2]])   # a fan from the concave corner
    return trimesh.creation.extrude_triangulation(v2, f2, height)


def coarse_torus():
    return trimesh.creation.torus(1.0, 0.2, major_sections=8, minor_sections=4)


def interlocked_pose():
    """B (the same octagonal torus) standing in the vertical plane through A's mid-edge direction,
    its tube crossing A's tube at right angles half-way along an edge of each: edges cross faces,
    no vertex of either is inside the other."""
    a = np.radians(22.5)
    rot = Rot.from_euler("z", a) * Rot.from_euler("x", 90, degrees=True) * Rot.from_euler("z", a)
    rc = np.cos(a)     # the octagonal centre line's radius at mid-edge
    p0 = rc * np.array([np.cos(a), np.sin(a), 0.0])
    # B's centre a little above rc, so that no edge of B lies in A's plane of corner edges (z = 0)
    return p0 + np.array([0, 0, rc + 0.03]), rot.as_quat()


@pytest.mark.exact
def test_bvh_covers_every_triangle_once():
    t = trimesh.creation.torus(1.0, 0.3)
    nodes, boxes, perm = build_bvh(t.vertices, t.faces)[:3]
    assert sorted(perm.tolist()) == list(range(len(t.faces)))
    leaves = nodes[nodes[:, 3] > 0]
    assert leaves[:, 3].sum() == len(t.faces) and leaves[:, 3].max() <= 4
    tv = t.vertices[t.faces]
    for k in np.flatnonzero(nodes[:, 3] > 0):   # each leaf box holds its triangles
        tri = tv[perm[nodes[k, 2]:nodes[k, 2] + nodes[k, 3]]].reshape(-1, 3)
        assert np.all(tri >= boxes[k, :3]) and np.all(tri <= boxes[k, 3:])
    for k in np.flatnonzero(nodes[:, 3] == 0):  # each inner box holds its children's
        for ch in nodes[k, :2]:
            assert np.all(boxes[ch, :3] >= boxes[k, :3]) and np.all(boxes[ch, 3:] <= boxes[k, 3:])


@pytest.mark.exact
def test_interlocked_tori_found_by_edge_face_alone():
    t = coarse_torus()
    A = mesh(t)
    pb, qb = interlocked_pose()
    # no vertex of either inside the other: the vertex test alone would say "apart"
    assert not cs.vertex_inside(A.vertices @ Rot.from_quat(qb).as_matrix().T + pb, A).any()
    assert not cs.vertex_inside(A.vertices, A, pose=(pb, qb)).any()
    assert _fcl_verdicts(t, t, [(pb, qb)])[0][0]      # and yet they intersect (python-fcl's BVH test)
    c, st = cs.collide(A, ((0, 0, 0), I), A, (pb, qb), stats=True)
    assert st.settled_by_vertex == 0 and st.needed_edge_face == 1 and st.edge_face_hits == 1
    assert 1 <= len(c) <= 4
    assert np.all(c.feature == cs.FEATURES.index("edge_face")) and np.all(c.depth > 0)
    assert np.allclose(np.linalg.norm(c.normal, axis=1), 1.0, atol=1e-12)
    # every point is where the two tubes cross: within both tori's tube radius (with the
    # square section's corner, 0.2·√2) of each centre line
    for p in c.point:
        for pos, rot in (((0, 0, 0), Rot.identity()), (pb, Rot.from_quat(qb))):
            x = rot.inv().apply(p - np.asarray(pos))
            assert abs(np.hypot(x[0], x[1]) - np.cos(np.radians(22.5))) <= 0.2 * np.sqrt(2) + 1e-9
            assert abs(x[2]) <= 0.2 * np.sqrt(2) + 1e-9
    # the same pair through the batch path, either order
    c2 = cs.collide(A, (pb, qb), A, ((0, 0, 0), I))
    assert len(c2) and np.all(c2.feature == c.feature[0]) and abs(c2.depth.max() - c.depth.max()) <= 1e-12


@pytest.mark.exact
def test_linked_tori_apart_have_no_contact():
    # linked like two chain links but not touching: the bounding volumes overlap, the meshes do not
    A = mesh(trimesh.creation.torus(1.0, 0.25, major_sections=24, minor_sections=8))
    q = Rot.from_euler("x", 90, degrees=True).as_quat()
    c, st = cs.collide(A, ((0, 0, 0), I), A, ((1.0, 0, 0), q), stats=True)
    assert len(c) == 0 and st.rejected_by_bounding_volume == 0


@pytest.mark.exact
def test_nested_l_shapes():
    # A: arms 0.5 wide, 2 long, 1 high. B: a shorter, lower L (arms 1.5 long, 0.5 high) turned half
    # a turn about z with its corner at (s, s) in A's pocket: B = [s-1.5, s]×[s-0.5, s] ∪
    # [s-0.5, s]×[s-1.5, s], z in [0.25, 0.75]. The convex hulls overlap for s < 2.25; the L-shapes
    # only for s < 2, when B's arm ends poke into A's arms by 2 - s along x and along y
    A, B = mesh(l_prism(0.5, 2.0, 1.0)), mesh(l_prism(0.5, 1.5, 0.5))
    q = Rot.from_euler("z", 180, degrees=True).as_quat()
    apart = ((2.1, 2.1, 0.25), q)
    assert len(cs.collide(A, ((0, 0, 0), I), B, apart)) == 0
    ha, hb = cs.Convex(A.vertices), cs.Convex(B.vertices)
    assert len(cs.collide(ha, ((0, 0, 0), I), hb, apart)) > 0      # a convex test would say "hit"
    # within a margin of 0.15 the facing vertices are speculative contacts 0.1 apart (depth -0.1)
    c = cs.collide(A, ((0, 0, 0), I), B, apart, margin=0.15)
    assert len(c) and abs(c.depth.max() + 0.1) <= 1e-12
    # nested 0.05 deep: B's arm-end vertices are 0.05 inside A's arms
    c, st = cs.collide(A, ((0, 0, 0), I), B, ((1.95, 1.95, 0.25), q), stats=True)
    assert st.settled_by_vertex == 1
    assert len(c) and abs(c.depth.max() - 0.05) <= 1e-12
    assert np.all(c.feature == cs.FEATURES.index("vertex_face"))
    # normals from B to A: A (near the origin) is pushed towards -x or -y, never up or down
    assert np.all(c.normal[:, 0] + c.normal[:, 1] < 0) and np.allclose(c.normal[:, 2], 0, atol=1e-12)
    assert np.all(np.abs(np.linalg.norm(c.normal, axis=1) - 1) <= 1e-12)
    # the contact points lie in the overlap (x or y within [0.45, 0.5])
    assert np.all((np.abs(c.point[:, 0] - 0.475) <= 0.025 + 1e-12) | (np.abs(c.point[:, 1] - 0.475) <= 0.025 + 1e-12))


def _fcl_verdicts(ta, tb, poses):
    fcl = pytest.importorskip("fcl")

    def model(t):
        m = fcl.BVHModel()
        m.beginModel(len(t.vertices), len(t.faces))
        m.addSubModel(np.asarray(t.vertices, float), np.asarray(t.faces, np.int32))
        m.endModel()
        return m

    ma, mb = model(ta), model(tb)
    oa = fcl.CollisionObject(ma, fcl.Transform())
    hit, dist = [], []
    for p, q in poses:
        ob = fcl.CollisionObject(mb, fcl.Transform(Rot.from_quat(q).as_matrix(), p))
        hit.append(fcl.collide(oa, ob, fcl.CollisionRequest(), fcl.CollisionResult()) > 0)
        dist.append(fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult()))
    return np.array(hit), np.array(dist)


def test_verdicts_against_fcl_on_random_poses():
    ta = trimesh.creation.torus(1.0, 0.3, major_sections=16, minor_sections=8)
    tb = l_prism(0.4, 1.2, 0.5)
    A, B = mesh(ta), mesh(tb)
    rng = np.random.default_rng(14)
    n = 2000
    pos = rng.uniform([-1.8, -1.8, -0.9], [1.8, 1.8, 0.9], size=(n, 3))
    quats = Rot.random(n, random_state=rng).as_quat()
    poses = list(zip(pos, quats))
    hit, dist = _fcl_verdicts(ta, tb, poses)
    ours = np.array([len(cs.collide(A, ((0, 0, 0), I), B, (p, q))) > 0 for p, q in poses])
    assert 0.2 < hit.mean() < 0.8          # the poses exercise both answers
    bad = np.flatnonzero(ours != hit)
    # a disagreement is allowed only where the two are within 1e-9 of touching
    assert np.all(np.abs(dist[bad]) <= 1e-9), (bad[:10], dist[bad[:10]], hit[bad[:10]])


def trough():
    """A U-shaped trough (closed, concave): floor top at z = 0.2, inner walls at x = ±0.8 up to
    z = 1, 1 m long along y (centred)."""
    v2 = np.array([[-1, 0], [1, 0], [1, 1], [0.8, 1], [0.8, 0.2], [-0.8, 0.2], [-0.8, 1], [-1, 1]], float)
    f2 = np.array([[1, 2, 3], [1, 3, 4], [0, 1, 4], [0, 4, 5], [0, 5, 6], [0, 6, 7]])
    t = trimesh.creation.extrude_triangulation(v2, f2, 1.0)
    x, y, z = t.vertices.T
    return trimesh.Trimesh(np.column_stack([x, 0.5 - z, y]), t.faces, process=False)   # a rotation: y up → z up


@pytest.mark.parametrize("toi", ["auto", "next_step"])
def test_concave_body_rests_in_a_concave_trough(toi):
    w = cs.World(gravity=(0, 0, -9.81), settings={"toi": toi})
    w.add_body("trough", mesh(trough()), kind="static")
    w.add_body("L", mesh(l_prism(0.15, 0.4, 0.2)), mass=1.0, position=(-0.2, -0.2, 0.25))
    for _ in range(int(0.5 / w.settings.dt)):       # falls 5 cm, lands, settles
        w.step()
    p0 = w.body("L").position.copy()
    assert w.contacts is not None and len(w.contacts) >= 3
    assert set(w.contacts.body_a) | set(w.contacts.body_b) == {0, 1}
    assert np.allclose(w.contacts.normal, [0, 0, -1], atol=1e-6)     # B (the L) to A (the trough): up is +z on the L
    for _ in range(int(3.0 / w.settings.dt)):       # then at rest for 3 s
        w.step()
    b = w.body("L")
    assert np.linalg.norm(b.velocity) < 1e-3 and np.linalg.norm(b.angular_velocity) < 1e-2
    assert np.linalg.norm(b.position - p0) < 1e-3               # drift under a millimetre over 3 s
    assert abs(b.position[2] - 0.2) < 1e-3                      # on the floor (its origin is its bottom)
    assert w.last_solve["max_penetration"] < 1e-3


def test_concave_body_rests_on_an_open_terrain_mesh():
    # an open mesh is one-sided: everything behind it is inside, however deep (no box cut-off)
    g = np.linspace(-1, 1, 9)
    x, y = np.meshgrid(g, g, indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(81)])
    F = [[a, a + 9, a + 10] for a in (i * 9 + j for i in range(8) for j in range(8))]
    F += [[a, a + 10, a + 1] for a in (i * 9 + j for i in range(8) for j in range(8))]
    terrain = cs.TriMesh(V, np.array(F))
    assert not terrain.watertight
    w = cs.World(gravity=(0, 0, -9.81))
    w.add_body("terrain", terrain, kind="static")
    w.add_body("L", mesh(l_prism(0.15, 0.4, 0.2)), mass=1.0, position=(-0.13, -0.17, 0.05))
    for _ in range(int(2.0 / w.settings.dt)):
        w.step()
    b = w.body("L")
    assert abs(b.position[2]) < 1e-3 and np.linalg.norm(b.velocity) < 1e-3
    assert abs(b.orientation[3]) > 1 - 1e-4        # flat on it, not tipped over
