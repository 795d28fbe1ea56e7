"""Broad phase: every method returns exactly the AABB-overlapping pairs (against an O(N²) reference
written independently here), whatever the layout and whichever method ``candidate_pairs`` picks."""
import numpy as np
import pytest

from contact_sim.collision import broadphase as bp


def reference(c, h, margin):
    """Pairs (i < j) whose boxes overlap within ``margin`` on all three axes, by a double loop."""
    out = set()
    for i in range(len(c)):
        for j in range(i + 1, len(c)):
            if all(abs(c[i, k] - c[j, k]) <= h[i, k] + h[j, k] + margin for k in range(3)):
                out.add((i, j))
    return out


def as_set(ij):
    i, j = ij
    assert np.all(i < j)
    pairs = set(zip(i.tolist(), j.tolist()))
    assert len(pairs) == len(i), "a pair is reported twice"
    return pairs


def layer(n, rng, spacing=0.21):   # spheres on a floor, some touching
    side = int(np.ceil(np.sqrt(n)))
    g = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1).reshape(-1, 2)[:n]
    c = np.column_stack([spacing * g + rng.uniform(-0.01, 0.01, (n, 2)), np.full(n, 0.1)])
    return c, np.full((n, 3), 0.1)


def lattice(n, rng):     # a 3-D lattice: every sweep axis is crowded, the grid's case
    side = int(np.ceil(n ** (1 / 3)))
    g = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    return g * 1.0 + rng.uniform(-0.3, 0.3, (n, 3)), rng.uniform(0.2, 0.6, (n, 3))


def clustered(n, rng):   # random boxes and one huge one (the grid's "big" path)
    c = rng.uniform(-2, 2, (n, 3))
    h = rng.uniform(0.05, 0.4, (n, 3))
    h[0] = [3.0, 0.1, 3.0]
    return c, h


@pytest.mark.parametrize("make", [layer, lattice, clustered])
@pytest.mark.parametrize("n", [2, 7, 32, 33, 150, 400])
def test_every_method_finds_exactly_the_overlapping_pairs(make, n):
    rng = np.random.default_rng(n)
    c, h = make(n, rng)
    ref = reference(c, h, 0.01)
    assert as_set(bp.candidate_pairs(c, h, 0.01)) == ref
    assert as_set(bp.all_pairs(c, h, 0.01)) == ref
    assert as_set(bp.grid_pairs(c, h, 0.01)) == ref
    assert as_set(bp.sweep_and_prune(c, h, 0.01)) == ref


def test_sap_gives_up_over_budget_and_the_grid_takes_over():
    rng = np.random.default_rng(3)
    c, h = lattice(400, rng)
    assert bp.sweep_and_prune(c, h, 0.0, budget=bp.SAP_BUDGET * 400 + 64) is None  # crowded sweep axis
    c2, h2 = layer(400, rng, spacing=0.3)        # a sparse floor: few boxes per sweep window
    assert bp.sweep_and_prune(c2, h2, 0.0, budget=bp.SAP_BUDGET * 400 + 64) is not None
    assert as_set(bp.candidate_pairs(c, h, 0.0)) == reference(c, h, 0.0)


def test_one_or_no_box_has_no_pairs():
    for n in (0, 1):
        i, j = bp.candidate_pairs(np.zeros((n, 3)), np.ones((n, 3)), 0.0)
        assert len(i) == len(j) == 0


def _drift(stretch, margins=(0.0, 0.01, 0.05)):
    """Drifting, jittering and teleported boxes, with a margin that shrinks and grows: the cached
    pairs (fat boxes, stretched along each box's drift or not) filtered exactly must be the
    reference pairs at every step. Returns the cache."""
    rng = np.random.default_rng(7)
    n = 120
    c, h = clustered(n, rng)
    v = rng.normal(scale=0.003, size=(n, 3))   # m a step
    v[: n // 2] = 0.0                       # half of them at rest
    cache = bp.PairCache()
    for step in range(60):
        margin = margins[step % len(margins)]
        if step % 17 == 5:
            c[rng.integers(n)] = rng.uniform(-2, 2, 3)     # a teleport (set_pose)
        c = c + v + rng.normal(scale=1e-4, size=(n, 3)) * (v != 0)
        got = cache.pairs(c, h, margin, v if stretch else None, 4.0 if stretch else 0.0)
        assert as_set(got) == reference(c, h, margin), step
    assert cache.reuses > 0 and cache.rebuilds > 1
    return cache


def test_pair_cache_equals_a_fresh_search_every_step_of_a_random_motion():
    _drift(stretch=False)


def test_pair_cache_stretched_along_the_motion_gives_the_same_pairs_and_rebuilds_less():
    _drift(stretch=True)
    # at one margin only the motion rebuilds (11 times in 60 steps plain, 4 of them teleports; 8 stretched)
    plain, stretched = _drift(False, margins=(0.01,)), _drift(True, margins=(0.01,))
    assert stretched.rebuilds < plain.rebuilds, (stretched.rebuilds, plain.rebuilds)


def test_fat_boxes_cover_the_box_and_the_box_moved_by_its_stretch():
    # half sizes h + FAT_FRACTION·max(h) + |d|/2 about the centre moved by d/2, d = vel·horizon,
    # each component of d at most FAT_STRETCH_MAX·max(h) either way
    c = np.array([[1.0, -2.0, 0.5], [0.0, 0.0, 0.0], [3.0, 3.0, 3.0]])
    h = np.array([[0.1, 0.2, 0.05], [0.5, 0.5, 0.5], [0.0, 0.0, 0.0]])
    vel = np.array([[1.0, -0.5, 0.0], [100.0, -100.0, 0.2], [5.0, 0.0, 0.0]])
    fc, fh = np.empty((3, 3)), np.empty((3, 3))
    scale = bp.fat_boxes(c, h, vel, 0.1, fc, fh)
    hm = h.max(axis=1, keepdims=True)
    d = np.clip(vel * 0.1, -bp.FAT_STRETCH_MAX * hm, bp.FAT_STRETCH_MAX * hm)
    assert d[1, :2].tolist() == [2.0, -2.0] and d[2].tolist() == [0.0, 0.0, 0.0]   # capped; a point stays
    np.testing.assert_allclose(fc, c + d / 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(fh, h + bp.FAT_FRACTION * hm + np.abs(d) / 2, rtol=0, atol=1e-15)
    for box in (c, c + d):   # the box now and moved: inside, exactly as inside_fat tests it
        assert bp.inside_fat(box, h, fc, fh)
    assert scale == np.abs(fc).max() + fh.max()
    fc0, fh0 = np.empty((3, 3)), np.empty((3, 3))
    bp.fat_boxes(c, h, np.zeros((0, 3)), 0.1, fc0, fh0)   # no velocities: grown only
    assert fc0.tolist() == c.tolist()
    np.testing.assert_allclose(fh0, h + bp.FAT_FRACTION * hm, rtol=0, atol=1e-15)


def test_pair_cache_reused_at_rest_and_rebuilt_when_a_box_leaves_its_fat_box():
    rng = np.random.default_rng(1)
    c, h = layer(50, rng, spacing=0.3)
    cache = bp.PairCache()
    cache.pairs(c, h, 0.001)
    cache.pairs(c, h, 0.001)
    assert (cache.rebuilds, cache.reuses) == (1, 1)
    c2 = c.copy()
    c2[3, 0] += 0.5 * bp.FAT_FRACTION * 0.1        # inside the fat box: reused
    cache.pairs(c2, h, 0.001)
    assert (cache.rebuilds, cache.reuses) == (1, 2)
    c2[3, 0] += 2.0 * bp.FAT_FRACTION * 0.1        # out of it: rebuilt
    cache.pairs(c2, h, 0.001)
    assert cache.rebuilds == 2
    cache.pairs(c2, h, 1.0)                         # a margin larger than cached: rebuilt
    assert cache.rebuilds == 3


def _world_reference(world, margin):
    """The world's candidate pairs by double loops over bodies, written from the contract: world
    AABBs of the object boxes overlapping within ``margin``, a plane's half-space reaching a box,
    not both static, group/mask bits, no disabled pair."""
    import contact_sim.quat as Q
    from contact_sim.collision import _bodies_of

    bodies = _bodies_of(world)
    n = len(world)
    R = [Q.to_matrix(q) for q in world.s.quat]
    c = [world.s.pos[k] + R[k] @ bodies.aabb_c[k] for k in range(n)]
    h = [np.abs(R[k]) @ bodies.aabb_h[k] for k in range(n)]
    names = world.body_names
    off = {frozenset(p) for p in world.disabled_pairs}
    out = set()
    for i in range(n):
        for j in range(i + 1, n):
            pi, pj = bodies.is_plane[i], bodies.is_plane[j]
            if pi and pj:
                continue
            if pi or pj:
                p, f = (i, j) if pi else (j, i)
                nw = R[p] @ bodies.plane_n[p]
                touch = nw @ c[f] - np.abs(nw) @ h[f] <= bodies.plane_d[p] + nw @ world.s.pos[p] + margin
            else:
                touch = all(abs(c[i][k] - c[j][k]) <= h[i][k] + h[j][k] + margin for k in range(3))
            if (touch and (world.kind[i] != 0 or world.kind[j] != 0) and world.group[i] & world.mask[j]
                    and world.group[j] & world.mask[i] and frozenset((names[i], names[j])) not in off):
                out.add((i, j))
    return out


@pytest.mark.parametrize("horizon", [0.0, 0.5])
def test_world_pairs_compiled_pass_equals_the_reference_as_bodies_move(horizon):
    # the world's broad phase (pair cache, planes, filters in one compiled pass) against double
    # loops, over drifting and teleported bodies, a growing and shrinking margin, two planes (one
    # tilted), static and kinematic bodies, group/mask bits and disabled pairs; with a horizon
    # the cache's fat boxes are stretched along velocities (random: they need not be the motion's)
    import contact_sim as cs
    from contact_sim import quat as Q
    from contact_sim.collision import _bodies_of, _world_pairs
    from contact_sim.collision.vec3 import rotations

    rng = np.random.default_rng(11)
    w = cs.World()
    w.add_body("floor", cs.Plane((0.0, 0.0, 1.0), 0.0), kind="static")
    w.add_body("ramp", cs.Plane((0.3, 0.0, 1.0), 0.2), kind="static", position=(0.5, 0.0, 0.0),
               orientation=tuple(Q.from_rotvec((0.0, 0.1, 0.0))))
    n = 40
    for k in range(n):
        shape = cs.Sphere(rng.uniform(0.05, 0.15)) if k % 2 else cs.Box(tuple(rng.uniform(0.1, 0.3, 3)))
        kind = ("static", "kinematic", "dynamic", "dynamic")[k % 4]
        w.add_body(f"b{k}", shape, kind=kind, position=tuple(rng.uniform(-1, 1, 3) * (1, 1, 0.5) + (0, 0, 0.3)),
                   orientation=tuple(Q.normalize(rng.normal(size=4))), group=1 + (k % 3 == 0), mask=1 | 2 * (k % 5 != 0))
    near = sorted(_world_reference(w, 0.1))   # disable three pairs that touch (one with a plane)
    picks = [near[0], near[len(near) // 2], next(p for p in near if p[0] == 0)]
    w.disable_collisions([(w.body_names[i], w.body_names[j]) for i, j in picks])
    bodies = _bodies_of(w)
    for step in range(40):
        margin = [0.0, 0.02, 0.1][step % 3]
        moving = [f"b{k}" for k in range(n) if k % 4 >= 1]
        pos = w.s.pos[[w.index(m) for m in moving]] + rng.normal(scale=0.01, size=(len(moving), 3))
        if step % 13 == 4:
            pos[rng.integers(len(moving))] = rng.uniform(-1, 1, 3)     # a teleport
        w.set_states(moving, positions=pos, velocities=rng.normal(scale=0.05, size=(len(moving), 3)))
        R = np.empty((len(w), 3, 3))
        rotations(w.s.quat, R)
        ia, ib = _world_pairs(w, bodies, w.s.pos, R, margin, horizon)
        got = list(zip(ia.tolist(), ib.tolist()))
        assert got == sorted(set(got)), "pairs sorted by (i, j), each once"
        assert set(got) == _world_reference(w, margin), step
    assert bodies.pair_cache.reuses > 0 and bodies.pair_cache.rebuilds > 1


def test_a_step_stretches_the_pair_cache_along_the_motion_and_moves_the_bodies_the_same(monkeypatch):
    # ten balls falling past a static box: the stepper's cache covers FAT_STEPS steps of each
    # body's motion, so it is rebuilt less often than with boxes grown by their size only, and
    # the pairs, hence the trajectories, are the same to the bit
    import contact_sim as cs
    from contact_sim import stepper
    from contact_sim.collision import _bodies_of

    def run():
        w = cs.World(settings={"dt": 1 / 240})
        w.add_body("floor", cs.Plane((0.0, 0.0, 1.0), 0.0), kind="static")
        w.add_body("post", cs.Box((0.2, 0.2, 2.0)), kind="static", position=(0.0, 0.0, 1.0))
        for k in range(10):
            w.add_body(f"b{k}", cs.Sphere(0.05), mass=1.0, position=(0.2 + 0.11 * k, 0.1 * (k % 2), 1.0 + 0.1 * k))
        touched = 0
        for _ in range(200):
            w.step()
            touched += len(w.contacts)
        assert touched > 0   # they reach the floor
        return _bodies_of(w).pair_cache.rebuilds, w.s.pos.copy(), w.s.vel.copy()

    stretched = run()
    monkeypatch.setattr(stepper, "FAT_STEPS", 0)
    plain = run()
    assert stretched[0] < plain[0] / 2, (stretched[0], plain[0])   # 26 against 145
    assert np.array_equal(stretched[1], plain[1]) and np.array_equal(stretched[2], plain[2])
