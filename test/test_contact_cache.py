"""The contact cache's matching of contacts from step to step (``response.cache.match``)."""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim.response import cache


def _reference(ext, n, a0, b0, p0, a1, b1, p1):
    """Brute force: each new contact's nearest old contact of its pair within reach; claims by
    increasing distance (ties: the earlier new contact), an old contact claimed once."""
    reach = cache.MATCH_FRACTION * np.minimum(ext[a1], ext[b1])
    cand = []
    for i in range(len(a1)):
        same = np.flatnonzero((a0 == a1[i]) & (b0 == b1[i]))
        if same.size:
            d = np.linalg.norm(p0[same] - p1[i], axis=1)
            j = int(np.argmin(d))
            if d[j] <= reach[i]:
                cand.append((d[j], i, int(same[j])))
    out = np.full(len(a1), -1)
    taken = set()
    for _, i, o in sorted(cand):
        if o not in taken:
            taken.add(o)
            out[i] = o
    return out


@pytest.mark.exact
@pytest.mark.parametrize("seed", range(5))
def test_match_finds_the_nearest_unclaimed_point_of_the_same_pair(seed):
    rng = np.random.default_rng(seed)
    world = cs.World()
    for i in range(6):
        world.add_body(f"b{i}", cs.Sphere(0.5), position=(3.0 * i, 0, 0))
    k0, k1 = 40, 35
    a0, b0 = rng.integers(0, 3, k0), rng.integers(3, 6, k0)
    a1, b1 = rng.integers(0, 3, k1), rng.integers(3, 6, k1)
    p0 = rng.uniform(-0.2, 0.2, (k0, 3))
    p1 = p0[rng.integers(0, k0, k1)] + rng.normal(0, 0.03, (k1, 3))   # near old points, some of other pairs
    a1[:10], b1[:10] = a0[:10], b0[:10]
    p1[:10] = p0[:10] + rng.normal(0, 0.01, (10, 3))
    got = cache.match(world, a0, b0, p0, a1, b1, p1)
    from contact_sim.response import toi

    want = _reference(toi._extents(world), len(world), a0, b0, p0, a1, b1, p1)
    assert np.array_equal(got, want)
    assert (got >= 0).sum() >= 8                      # the ten moved-a-little contacts are found
    ok = got >= 0
    assert np.array_equal(a0[got[ok]], a1[ok]) and np.array_equal(b0[got[ok]], b1[ok])
    assert len(set(got[ok])) == ok.sum()


@pytest.mark.exact
@pytest.mark.parametrize("seed", range(3))
def test_match_across_many_pairs_finds_each_contacts_own_pair(seed):
    """Hundreds of pairs among 300 bodies, so that pairs share the hash's buckets (``_match``):
    every contact still matches only its own pair's points, as the brute force does; most new
    contacts have no rival for their old one, a few do (the nearest claims it)."""
    rng = np.random.default_rng(seed)
    world = cs.World()
    for i in range(300):
        world.add_body(f"b{i}", cs.Sphere(0.5), position=(3.0 * i, 0, 0))
    k0 = 600
    a0 = rng.integers(0, 150, k0)
    b0 = rng.integers(150, 300, k0)
    p0 = rng.uniform(-0.2, 0.2, (k0, 3))
    pick = rng.permutation(k0)[:500]
    pick[480:] = pick[100:120]           # twenty old contacts wanted by two new ones each
    a1, b1 = a0[pick], b0[pick]
    p1 = p0[pick] + rng.normal(0, 0.005, (500, 3))
    a1[:20] = (a1[:20] + 1) % 150        # twenty contacts of pairs that (almost surely) had none
    got = cache.match(world, a0, b0, p0, a1, b1, p1)
    from contact_sim.response import toi

    want = _reference(toi._extents(world), len(world), a0, b0, p0, a1, b1, p1)
    assert np.array_equal(got, want)
    assert (got[20:] >= 0).sum() == 460   # of each contested old contact, one claim
    ok = got >= 0
    assert np.array_equal(a0[got[ok]], a1[ok]) and np.array_equal(b0[got[ok]], b1[ok])
    assert len(set(got[ok])) == ok.sum()




@pytest.mark.exact
def test_the_warm_start_after_a_short_last_sub_step_is_no_larger_than_its_impulse():
    """A box sliding on the floor without friction reaches a wall at 3 cm/s (slower than a bounce:
    the resting stage stops it) at 0.999 of a fractional step, so the step's last sub-step lasts
    1e-3 of it. The cache keeps the resting impulses per unit of the step's time: the next step's
    warm start is the impulse that last solve gave, never more than the step applied. Divided by
    the short sub-step instead, the wall's stop read as a force of 1800 N on a 1 kg box; in a
    650-contact pile, where Gauss–Seidel alone solves, such warm starts (3800 N·s on a 0.8 kg
    sphere) kept the sweeps from converging (residual 333 m/s) and threw a body at 52 m/s."""
    g, dt, v, h = 9.81, 1 / 60, 0.03, 0.1
    gap = v * 0.999 * dt
    world = cs.load_scene({
        "gravity": [0, 0, -g], "settings": {"dt": dt, "toi": "fractional", "response": "impulse"},
        "materials": {"m": {"restitution": 0.0, "friction": 0.0}},
        "bodies": [{"name": "ground", "kind": "static", "shape": {"type": "plane"}, "material": "m"},
                   {"name": "wall", "kind": "static", "shape": {"type": "plane", "normal": [-1, 0, 0]},
                    "material": "m"},
                   {"name": "box", "shape": {"type": "box", "size": [h, h, h]}, "mass": 1.0,
                    "position": [-h / 2 - gap, 0.0, h / 2], "velocity": [v, 0.0, 0.0], "material": "m"}]})
    world.step()
    assert world.last_solve["impacts"] == 1
    assert world.body("box").velocity[0] == pytest.approx(0.0, abs=1e-12)   # stopped at the wall
    a0, b0, p0, values = world.contact_cache.warm
    c = world.contacts
    applied = np.array([c.normal_impulse[(c.body_a == a) & (c.body_b == b)].sum() for a, b in zip(a0, b0)])
    print("warm start", values[:, 0] * dt, "applied", applied)
    assert np.all(values[:, 0] * dt <= applied * (1 + 1e-12))
