"""The exact solve island by island (compiled, ``response.active_set``) against the sparse active
set over the whole system (``direct._active_set``), single contacts against LAPACK, and the
choice between the exact solve and Gauss–Seidel above 200 contacts."""
import numpy as np
import pytest

from contact_sim import constants
from contact_sim.response import active_set, direct, solver
from contact_sim.response.rows import body_mass


def _spheres_on_ground(k, spin, seed=5):
    rng = np.random.default_rng(seed)
    n = k + 1
    pos = np.zeros((n, 3))
    pos[1:, :2] = rng.uniform(-5, 5, (k, 2))
    pos[1:, 2] = 0.1
    inv_mass = np.r_[0.0, np.full(k, 2.0)]
    inertia_inv = np.zeros((n, 3, 3))
    inertia_inv[1:] = np.eye(3) / (0.4 * 0.5 * 0.01)
    vel = np.zeros((n, 3))
    vel[1:] = rng.normal(0, 0.5, (k, 3))
    vel[1:, :2] *= spin                                # slow tangential motion: every contact sticks
    omega = np.zeros((n, 3))
    omega[1:] = rng.normal(0, 2.0, (k, 3)) * spin
    a = np.arange(1, n)
    b = np.zeros(k, np.int64)
    normal = np.tile([0.0, 0.0, 1.0], (k, 1))
    point = pos[1:] - 0.1 * normal
    return solver.build_rows(a, b, point, normal, pos, inv_mass, inertia_inv, vel, omega), vel, omega


@pytest.mark.exact
@pytest.mark.parametrize("spin, converged", [(0.01, True), (1.0, False)])
def test_single_contacts_get_the_exact_3x3_answer_in_both_paths(spin, converged):
    """Spheres each touching only the ground (islands of one contact): the island kernel's answer is
    LAPACK's solve of the contact's 3×3 block where it sticks (``K λ = −v``), zero where it
    separates; a sliding one (outside the static cone) is left unsolved, for Gauss–Seidel. The
    Gauss–Seidel method peels the same singles off first and gets the same impulses."""
    k = 60
    rows, vel, omega = _spheres_on_ground(k, spin)
    mu = np.full(k, 0.5)
    target = np.zeros(k)
    v0 = solver.row_velocity(rows, vel, omega)
    lam, solved, _ = direct.solve_exact(rows, vel, omega, target_n=target, mu_s=mu, mu_d=mu)
    separating = v0[:, 0] >= 0
    ref = np.zeros((k, 3))
    approach = np.flatnonzero(~separating)
    ref[approach] = np.linalg.solve(rows.K[approach], -v0[approach][:, :, None])[:, :, 0]
    sticks = np.linalg.norm(ref[:, 1:], axis=1) <= 0.5 * ref[:, 0]
    assert separating.any() and np.all(lam[separating] == 0) and solved[separating].all()
    assert np.array_equal(solved, separating | sticks) and solved.all() == converged
    scale = np.abs(ref).max()
    assert np.allclose(lam[solved], ref[solved], rtol=0, atol=1e-13 * scale)
    v, w = vel.copy(), omega.copy()
    res = solver.solve_auto(rows, v, w, target_n=target, mu_s=mu, mu_d=mu, method="gs", iterations=200,
                            tolerance=1e-14)
    assert np.allclose(res.impulse[solved], ref[solved], rtol=0, atol=1e-13 * scale)
    if converged:   # every contact exact: no sweep needed, the velocities change only through λ
        assert res.iterations == 1
        rv = solver.row_velocity(rows, v, w)
        assert np.abs(rv[~separating]).max() < 1e-12
    else:           # the sliding ones: on their kinetic disc
        sl = ~solved
        t = np.linalg.norm(res.impulse[sl, 1:], axis=1)
        assert np.allclose(t, 0.5 * res.impulse[sl, 0], rtol=1e-9)


def _box_stack(layers, seed=0):
    """``layers`` unit-mass 0.2 m cubes stacked on a static ground (body 0), four corner contacts
    per face, slightly perturbed velocities: one island of ``4·layers`` coupled contacts."""
    rng = np.random.default_rng(seed)
    n = layers + 1
    h = 0.1
    pos = np.zeros((n, 3))
    pos[1:, 2] = h + 2 * h * np.arange(layers)
    inv_mass = np.r_[0.0, np.ones(layers)]
    inertia_inv = np.zeros((n, 3, 3))
    inertia_inv[1:] = np.eye(3) / (1.0 * (0.2 ** 2 + 0.2 ** 2) / 12)
    vel = rng.normal(0, 0.05, (n, 3))
    vel[0] = 0.0
    vel[:, :2] *= 0.2                      # slow sliding: every contact sticks under μ = 0.6
    vel[1:, 2] -= 0.3
    omega = rng.normal(0, 0.1, (n, 3))
    omega[0] = 0.0
    a, b, point = [], [], []
    for i in range(1, n):
        z = pos[i, 2] - h
        for sx in (-h, h):
            for sy in (-h, h):
                a.append(i)
                b.append(i - 1)
                point.append((sx, sy, z))
    k = len(a)
    normal = np.tile([0.0, 0.0, 1.0], (k, 1))
    rows = solver.build_rows(np.array(a), np.array(b), np.array(point), normal, pos, inv_mass, inertia_inv,
                             vel, omega)
    return rows, vel, omega


def _after(rows, vel, omega, *impulses):
    """The bodies' velocities ``(2N·3,)`` (linear, then angular) after each of ``impulses`` on
    ``rows``, from ``vel, omega``."""
    out = []
    for x in impulses:
        v, w = vel.copy(), omega.copy()
        solver.apply(rows, v, w, x)
        out.append(np.concatenate([v, w]).ravel())
    return out


@pytest.mark.exact
@pytest.mark.parametrize("shuffled", [False, True])
@pytest.mark.parametrize("mu", [0.0, 0.6])
def test_compiled_islands_equal_the_sparse_active_set(mu, shuffled):
    """Three separate stacks (three islands of 4–20 coupled contacts, four points on each face: a
    redundant set the regularisation splits by least norm) with friction: the compiled kernel and
    the sparse active set over the whole system give the same impulses to round-off. The islands
    above ``constants.DIRECT_BAND_MIN`` contacts are solved within each row's coupling range: in
    detection's order (each box's contacts together, a band) and with the contacts shuffled (each
    row's range then spans most of its island, and the ranges are widened to be monotone)."""
    parts = [_box_stack(n, seed=n) for n in (1, 3, 5)]
    # merge the three stacks into one system (bodies renumbered, one ground each)
    from contact_sim.response.rows import Rows

    offs = np.cumsum([0] + [len(p[1]) for p in parts])
    fields = ("a", "b", "n", "t1", "t2", "ra", "rb", "ang_a", "ang_b", "iang_a", "iang_b", "ima", "imb", "K", "dirs")
    cat = {f: np.concatenate([getattr(p[0], f) + (o if f in ("a", "b") else 0) for p, o in zip(parts, offs)])
           for f in fields}
    if shuffled:
        perm = np.random.default_rng(7).permutation(len(cat["a"]))
        cat = {f: v[perm] for f, v in cat.items()}
    rows = Rows(**cat, **{f: np.concatenate([getattr(p[0], f) for p in parts])
                          for f in ("movable", "inv_mass", "inv_inertia")})
    vel = np.concatenate([p[1] for p in parts])
    omega = np.concatenate([p[2] for p in parts])
    k = len(rows)
    mus = np.full(k, mu)
    target = np.zeros(k)
    lam, solved, residual = direct.solve_exact(rows, vel, omega, target_n=target, mu_s=mus, mu_d=mus)
    v0 = solver.row_velocity(rows, vel, omega)
    ref, ok, _ = direct._active_set(rows, v0, target, mus if mu else None, mus if mu else None, None)
    assert solved.all() and ok
    assert residual < 1e-9
    # four points on a face are redundant: the split among them is the regularisation's (least
    # norm, to the precision of its refinement), what they do is determined. Same velocities after,
    # and the same impulse per face
    after = []
    for x in (lam, ref):
        v, w = vel.copy(), omega.copy()
        solver.apply(rows, v, w, x)
        after.append((v, w, solver.row_velocity(rows, v, w)))
    assert np.allclose(after[0][0], after[1][0], rtol=0, atol=1e-12)
    assert np.allclose(after[0][1], after[1][1], rtol=0, atol=1e-12)
    back = np.argsort(perm) if shuffled else np.arange(k)   # a face's four contacts in a row again
    face = lambda x: np.add.reduceat(np.einsum("kd,kdi->ki", x[back], rows.dirs[back]), np.arange(0, k, 4))   # noqa: E731
    assert np.allclose(face(lam), face(ref), rtol=0, atol=1e-12 * np.abs(face(ref)).max())
    assert np.all(lam[:, 0] >= 0)
    # the answer: every pushing contact at rest after the impulses (the stacks stop)
    rv = after[0][2]
    pushing = lam[:, 0] > 0
    assert np.abs(rv[pushing, 0]).max() < 1e-12
    if mu:
        assert np.abs(rv[pushing, 1:]).max() < 1e-12


@pytest.mark.exact
@pytest.mark.parametrize("layers", [1, 2, 6])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_island_solve_reads_only_what_it_wrote(seed, layers):
    """One island of a stack in a shuffled order, solved by ``active_set._island`` with every
    workspace filled with NaN (and the integer ones with nonsense): an entry read outside what the
    call wrote would show in the answer. The same impulses, to round-off, as the sparse active set
    over the system. 6 boxes (24 contacts, above ``constants.DIRECT_BAND_MIN``): each row's coupling
    range; 1 and 2 boxes (4 and 8 contacts): the island taken whole."""
    from contact_sim.constants import DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS, DIRECT_REGULARISATION
    rows, vel, omega = _box_stack(layers, seed=seed)
    k = len(rows)
    assert (k > constants.DIRECT_BAND_MIN) == (layers == 6)
    perm = np.random.default_rng(seed).permutation(k)
    rows = rows.select(perm)
    v0 = solver.row_velocity(rows, vel, omega)
    mus, target = np.full(k, 0.6), np.zeros(k)
    n = 3 * k
    A, sub, L = np.full((n, n), np.nan), np.full((n, n), np.nan), np.full((n, n), np.nan)
    vecs = np.full((5, n), np.nan)
    S, nz = np.full(n, -(10 ** 9), np.int64), np.full(n, -(10 ** 9), np.int64)
    act, band = np.zeros(k, bool), np.full((6, n + 1), 10 ** 9, np.int64)
    lam = np.full((k, 3), np.nan)
    status, residual = active_set._island(
        np.arange(k), rows.a.astype(np.int64), rows.b.astype(np.int64), rows.dirs, rows.ang_a, rows.ang_b,
        rows.iang_a, rows.iang_b, rows.ima, rows.imb, v0, target, np.zeros(k), mus, mus, True, np.zeros((k, 3)),
        False, DIRECT_REGULARISATION, DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS, lam, A, sub, L, vecs, S, nz, act, band)
    ref, ok, _ = direct._active_set(rows, v0, target, mus, mus, None)
    assert status == active_set.SOLVED and ok and residual < 1e-9
    after = _after(rows, vel, omega, lam, ref)
    assert np.allclose(after[0], after[1], rtol=0, atol=1e-12)


def _pressed(vel, layers):
    """``vel`` with each box of the stack moving down 0.1 m/s faster than the one below: every
    face approaches, so every contact is active from the first round."""
    vel = vel.copy()
    vel[1:, 2] = -0.1 * np.arange(1, layers + 1)
    return vel


def _dense_delassus(rows, n_bodies):
    """``A = J M⁻¹ Jᵀ`` of ``rows`` dense (3K × 3K), from each row's Jacobian and velocity change."""
    k = len(rows)
    J, B = np.zeros((3 * k, 6 * n_bodies)), np.zeros((3 * k, 6 * n_bodies))
    for c in range(k):
        for d in range(3):
            r, ia, ib = 3 * c + d, 6 * rows.a[c], 6 * rows.b[c]
            J[r, ia:ia + 3], J[r, ia + 3:ia + 6] = rows.dirs[c, d], rows.ang_a[c, d]
            J[r, ib:ib + 3] -= rows.dirs[c, d]
            J[r, ib + 3:ib + 6] -= rows.ang_b[c, d]
            B[r, ia:ia + 3], B[r, ia + 3:ia + 6] = rows.ima[c] * rows.dirs[c, d], rows.iang_a[c, d]
            B[r, ib:ib + 3] -= rows.imb[c] * rows.dirs[c, d]
            B[r, ib + 3:ib + 6] -= rows.iang_b[c, d]
    return J @ B.T


@pytest.mark.exact
@pytest.mark.parametrize("shuffled", [False, True])
@pytest.mark.parametrize("layers", [1, 3, 10])
def test_redundant_contacts_get_the_least_norm_split_to_rounding(layers, shuffled):
    """Four sticking points on each face of a stack: 12 rows per box on its 6 freedoms, so the
    impulses that stop the stack are not unique; the solve gives the least-norm ones, ``A⁺ r``
    (``A`` the Delassus matrix, ``r`` the rows' velocity change), to rounding: LAPACK's
    pseudo-inverse of the dense ``A`` agrees to 1e-11 of the largest impulse. (The rows'
    regularised solve, ``(A + εI)`` refined twice, was off by 4e-7 of it on one box and 1e-5 on
    ten.) Every pushing contact ends at rest."""
    rows, vel, omega = _box_stack(layers, seed=layers)
    vel = _pressed(vel, layers)
    k = len(rows)
    if shuffled:
        perm = np.random.default_rng(layers).permutation(k)
        rows = rows.select(perm)
    mus, target = np.full(k, 0.6), np.zeros(k)
    v0 = solver.row_velocity(rows, vel, omega)
    lam, solved, residual = direct.solve_exact(rows, vel, omega, target_n=target, mu_s=mus, mu_d=mus)
    assert solved.all() and np.all(lam[:, 0] > 0)
    A = _dense_delassus(rows, layers + 1)
    ref = (np.linalg.pinv(A, rcond=1e-12, hermitian=True) @ (-v0).ravel()).reshape(k, 3)
    scale = np.abs(ref).max()
    assert np.abs(lam - ref).max() <= 1e-11 * scale
    v, w = vel.copy(), omega.copy()
    solver.apply(rows, v, w, lam)
    assert np.abs(solver.row_velocity(rows, v, w)).max() < 1e-14
    assert residual < 1e-14


def _body_space_workspace(k, n_bodies):
    """``active_set._island_body``'s workspace for an island of ``k`` contacts, every float NaN and
    every index nonsense (but ``local``, which must come in −1 and is put back so)."""
    n = 3 * k
    junk = -(10 ** 9)
    return dict(G=np.full((n, n), np.nan), mb=np.full((2 * k + 1, 10), np.nan), vecs=np.full((5, n), np.nan),
                dofs=np.full((3, 4 * n), np.nan), S=np.full(n, junk, np.int64), nz=np.full(n, junk, np.int64),
                act=np.zeros(k, bool), band=np.full((6, n + 1), 10 ** 9, np.int64),
                local=np.full(n_bodies, -1, np.int64), listed=np.full(2 * k + 1, junk, np.int64),
                first=np.full(2 * k + 1, junk, np.int64), jv=np.full(12, np.nan), bv=np.full(12, np.nan),
                rhs_s=np.full(n, np.nan), every=np.arange(n))


def _island_body(rows, v0, target, mus, ws):
    """``active_set._island_body`` on the island ``rows`` (every contact), with friction where some
    ``mus`` is positive (as ``solver.solve_rows`` decides), no warm start, the workspace ``ws``:
    ``(status, residual, impulses (K,3))``."""
    from contact_sim.constants import DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS

    k = len(rows)
    lam = np.full((k, 3), np.nan)
    status, residual = active_set._island_body(
        np.arange(k), rows.a.astype(np.int64), rows.b.astype(np.int64), rows.dirs, rows.ang_a, rows.ang_b,
        rows.iang_a, rows.iang_b, rows.ima, rows.imb, v0, np.zeros(k), mus, mus, bool(mus.max() > 0),
        np.zeros((k, 3)), False,
        DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS, lam,
        tuple(ws[n] for n in ("G", "vecs", "dofs", "S", "nz", "act", "band", "local", "listed", "first", "jv", "bv",
                              "rhs_s", "every", "mb")),
        target, *body_mass(rows))
    return status, residual, lam


@pytest.mark.exact
@pytest.mark.parametrize("layers", [1, 2, 6])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_body_space_solve_reads_only_what_it_wrote(seed, layers):
    """``_island_body`` on a stack in a shuffled order with its workspace filled with NaN and
    nonsense: the same velocities after, to round-off, as the sparse active set over the system,
    and the body numbering it borrowed (``local``) handed back all −1."""
    rows, vel, omega = _box_stack(layers, seed=seed)
    vel = _pressed(vel, layers)
    k = len(rows)
    perm = np.random.default_rng(seed).permutation(k)
    rows = rows.select(perm)
    v0 = solver.row_velocity(rows, vel, omega)
    mus, target = np.full(k, 0.6), np.zeros(k)
    ws = _body_space_workspace(k, layers + 1)
    status, residual, lam = _island_body(rows, v0, target, mus, ws)
    ref, ok, _ = direct._active_set(rows, v0, target, mus, mus, None)
    assert status == active_set.SOLVED and ok and residual < 1e-14
    assert np.all(ws["local"] == -1)
    after = _after(rows, vel, omega, lam, ref)
    assert np.allclose(after[0], after[1], rtol=0, atol=1e-12)


@pytest.mark.exact
def test_body_mass_is_the_inverse_of_the_rows_inverse_inertia():
    """``_body_mass``: each listed body's mass ``1/inv_mass`` and world inertia, the inverse of the
    inverse inertia the rows were built with (``inertia · inv_inertia = I`` to round-off of its
    condition); False for a body whose inverse inertia cannot be inverted (it does not rotate), and
    for rows made without their bodies (empty arrays)."""
    rng = np.random.default_rng(3)
    n = 4
    q = np.empty((n, 3, 3))
    for i in range(n):
        r, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q[i] = r @ np.diag(rng.uniform(0.1, 50.0, 3)) @ r.T   # a rotated inverse inertia, 1:500 at most
    inv_mass = rng.uniform(0.2, 5.0, n)
    listed = np.array([2, 0, 3])
    mb = np.full((3, 10), np.nan)
    assert active_set._body_mass(listed, 3, inv_mass, q, mb)
    for i, body in enumerate(listed):
        assert mb[i, 0] == 1.0 / inv_mass[body]
        inertia = mb[i, 1:].reshape(3, 3)
        cond = np.linalg.cond(q[body])
        assert np.abs(inertia @ q[body] - np.eye(3)).max() < 8 * cond * 2.2e-16
    q[0] = 0.0   # a body the models do not rotate
    assert not active_set._body_mass(listed, 3, inv_mass, q, mb)
    assert not active_set._body_mass(listed, 3, np.zeros(0), np.zeros((0, 3, 3)), mb)


@pytest.mark.exact
def test_rows_without_their_bodies_take_the_rows_method():
    """A stack's rows made without the bodies' mass (``Rows.inv_mass`` None, as rows assembled by
    hand): the body-space method declines (``_ROWS``) and ``solve_exact`` gives the same velocities
    after, to round-off, as with them (the rows' method on the same active set)."""
    from dataclasses import replace

    rows, vel, omega = _box_stack(3, seed=4)
    vel = _pressed(vel, 3)
    k = len(rows)
    bare = replace(rows, inv_mass=None, inv_inertia=None)
    mus, target = np.full(k, 0.6), np.zeros(k)
    v0 = solver.row_velocity(rows, vel, omega)
    assert _island_body(bare, v0, target, mus, _body_space_workspace(k, len(vel)))[0] == active_set._ROWS
    assert _island_body(rows, v0, target, mus, _body_space_workspace(k, len(vel)))[0] == active_set.SOLVED
    lam, solved, _ = direct.solve_exact(rows, vel, omega, target_n=target, mu_s=mus, mu_d=mus)
    lam_bare, solved_bare, _ = direct.solve_exact(bare, vel, omega, target_n=target, mu_s=mus, mu_d=mus)
    assert solved.all() and solved_bare.all()
    after = _after(rows, vel, omega, lam, lam_bare)
    assert np.allclose(after[0], after[1], rtol=0, atol=1e-12)


@pytest.mark.exact
def test_islands_group_contacts_through_movable_bodies():
    """Contacts join an island through a movable body, never through a static one; a contact of
    two immovable bodies is its own island; islands come in the order of their first contact."""
    movable = np.array([False, True, True, True, False, True])
    a = np.array([1, 3, 2, 5, 4, 1])
    b = np.array([0, 0, 1, 0, 0, 2])
    order, start = active_set.islands(a, b, movable, len(movable))
    groups = [list(order[start[i]:start[i + 1]]) for i in range(len(start) - 1)]
    assert groups == [[0, 2, 5], [1], [3], [4]]


@pytest.mark.exact
def test_many_small_islands_above_200_contacts_take_the_exact_solve():
    """60 boxes resting apart on the ground: 240 contacts, above the 200 where one large island
    would go to Gauss–Seidel first, but 60 islands of 4, which the compiled active set solves
    exactly (one round each: iterations 1) and the boxes stay put to round-off."""
    import contact_sim as cs

    w = cs.World()
    w.add_body("ground", cs.Plane(), kind="static")
    for i in range(60):
        w.add_body(f"box{i}", cs.Box((0.2, 0.2, 0.2)), mass=1.0, position=(0.5 * (i % 10), 0.5 * (i // 10), 0.1))
    z0 = w.s.pos[1:, 2].copy()
    for _ in range(20):
        w.step(0.01)
    assert w.last_solve.contacts == 240 and w.last_solve.iterations == 1
    assert np.abs(w.s.pos[1:, 2] - z0).max() < 1e-12 and np.abs(w.s.vel).max() < 1e-12


def test_rows_apply_kernel_equals_the_numpy_form_bit_for_bit():
    """``rows.apply`` (a compiled pass) against its numpy form with ``np.add.at`` on random rows
    whose bodies repeat on both sides: the same sums, rounded the same."""
    from contact_sim.response import rows as R

    rng = np.random.default_rng(0)
    for _ in range(100):
        n, k = int(rng.integers(2, 8)), int(rng.integers(1, 30))
        a = rng.integers(0, n, k)
        b = (a + rng.integers(1, n, k)) % n
        rows = R.Rows(a, b, *(rng.normal(size=(k, 3)) for _ in range(5)), *(rng.normal(size=(k, 3, 3)) for _ in range(4)),
                      rng.uniform(0, 2, k), rng.uniform(0, 2, k), rng.normal(size=(k, 3, 3)), rng.normal(size=(k, 3, 3)),
                      np.ones(n, bool))
        lam, vel, omega = rng.normal(size=(k, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
        v1, w1 = vel.copy(), omega.copy()
        imp = np.einsum("kd,kdi->ki", lam, rows.dirs)
        np.add.at(v1, a, rows.ima[:, None] * imp)
        np.add.at(v1, b, -rows.imb[:, None] * imp)
        np.add.at(w1, a, np.einsum("kd,kdi->ki", lam, rows.iang_a))
        np.add.at(w1, b, -np.einsum("kd,kdi->ki", lam, rows.iang_b))
        R.apply(rows, vel, omega, lam)
        assert np.array_equal(vel, v1) and np.array_equal(omega, w1)


def _random_chain(seed, bodies, square=False):
    """A chain of ``bodies`` rigid bodies on a static ground (body 0), each touching the one below
    (or the ground) through a random, tilted normal, with random masses (0.1–10 kg) and random full
    inertia tensors, each faster down than the one below: in no axis-aligned or symmetric
    arrangement. The contacts are 3–5 random points (some then leave the set) or, ``square``, the
    corners of a randomly turned square centred under the body (every face stays pressed)."""
    rng = np.random.default_rng(seed)
    n = bodies + 1
    pos = np.zeros((n, 3))
    pos[1:, 2] = 0.3 * np.arange(1, n)
    inv_mass = np.r_[0.0, 1.0 / rng.uniform(0.1, 10.0, bodies)]
    inv_inertia = np.zeros((n, 3, 3))
    for i in range(1, n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        inv_inertia[i] = q @ np.diag(1.0 / rng.uniform(0.01, 1.0, 3)) @ q.T
    vel = rng.normal(0, 0.05, (n, 3))
    vel[0] = 0.0
    vel[1:, 2] = -0.2 * np.arange(1, n)
    omega = rng.normal(0, 0.05, (n, 3))
    omega[0] = 0.0
    if square:
        vel[1:, :2] = 0.0
        omega[:] = 0.0
    a, b, point, normal = [], [], [], []
    for i in range(1, n):
        nrm = np.array([*rng.normal(0, 0.2, 2), 1.0])
        nrm /= np.linalg.norm(nrm)
        if square:
            u = np.cross(nrm, [1.0, 0.0, 0.0])
            u /= np.linalg.norm(u)
            v = np.cross(nrm, u)
            turn = rng.uniform(0, np.pi)
            u, v = np.cos(turn) * u + np.sin(turn) * v, -np.sin(turn) * u + np.cos(turn) * v
            offsets = [0.1 * (su * u + sv * v) - 0.15 * nrm for su in (-1, 1) for sv in (-1, 1)]
        else:
            offsets = [np.array([*rng.uniform(-0.15, 0.15, 2), -0.15]) for _ in range(rng.integers(3, 6))]
        for off in offsets:
            a.append(i)
            b.append(i - 1)
            point.append(pos[i] + off)
            normal.append(nrm)
    return (solver.build_rows(np.array(a), np.array(b), np.array(point), np.array(normal), pos, inv_mass,
                              inv_inertia, vel, omega), vel, omega)


def _both_methods(rows, vel, omega, mu):
    """The island ``rows`` (one island) solved by ``solve_islands`` (the body-space method where it
    takes it) and by the rows' method alone (``_island``), with friction ``mu``: ``(body-space
    status, solve_islands' (status, impulses), _island's (status, impulses), v0)``."""
    from contact_sim.constants import DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS, DIRECT_REGULARISATION

    k = len(rows)
    a, b = rows.a.astype(np.int64), rows.b.astype(np.int64)
    v0 = solver.row_velocity(rows, vel, omega)
    mus, target = np.full(k, mu), np.zeros(k)
    order, start = active_set.islands(a, b, rows.movable, len(vel))
    assert len(start) == 2
    lam, status = np.zeros((k, 3)), np.empty(k, np.int64)
    active_set.solve_islands(a, b, order, start, rows.dirs, rows.ang_a, rows.ang_b, rows.iang_a, rows.iang_b, rows.ima,
                             rows.imb, target, np.zeros(k), mus, mus, mu > 0, np.zeros((k, 3)), False,
                             constants.DIRECT_ISLAND_MAX, DIRECT_REGULARISATION, DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS,
                             vel.copy(), omega.copy(), False, lam, status, *body_mass(rows))
    n = 3 * k
    mats, vecs = np.empty((3, n, n)), np.empty((5, n))
    lam_rows = np.zeros((k, 3))
    st_rows, _ = active_set._island(
        np.arange(k), a, b, rows.dirs, rows.ang_a, rows.ang_b, rows.iang_a, rows.iang_b, rows.ima, rows.imb, v0,
        target, np.zeros(k), mus, mus, mu > 0, np.zeros((k, 3)), False, DIRECT_REGULARISATION, DIRECT_CONSISTENCY,
        DIRECT_MAX_ROUNDS, lam_rows, mats[0], mats[1], mats[2], vecs, np.empty(n, np.int64), np.empty(n, np.int64),
        np.empty(k, bool), np.empty((6, n + 1), np.int64))
    ws = _body_space_workspace(k, len(vel))
    st_body, _, _ = _island_body(rows, v0, target, mus, ws)
    assert np.all(ws["local"] == -1)
    return st_body, (status[0], lam), (st_rows, lam_rows), v0


def _check_body_answer(rows, vel, omega, mu, least_norm=1e-10):
    """``_both_methods``' answers agree: the same status, and where it is solved the same
    velocities after to round-off (where the body-space method declined, ``solve_islands`` runs the
    rows' method itself, on the rows' velocities it computes: the same but for their last bits);
    where the body-space method solved, zero impulse on the contacts that do not push and the
    least-norm impulses on those that do, to ``least_norm`` of the largest (LAPACK's
    pseudo-inverse of their dense Delassus block). Returns the body-space status."""
    st_body, (status, lam), (st_rows, lam_rows), v0 = _both_methods(rows, vel, omega, mu)
    assert status == st_rows and st_body in (status, active_set._ROWS)
    if status != active_set.SOLVED:
        return st_body
    after = _after(rows, vel, omega, lam, lam_rows)
    speed = np.abs(after[1]).max() + np.abs(np.concatenate([vel, omega])).max()
    assert np.abs(after[0] - after[1]).max() <= 1e-12 * speed
    if st_body == active_set._ROWS:
        return st_body
    push = lam[:, 0] > 0
    assert push.any() and np.all(lam[~push] == 0)
    S = np.flatnonzero(np.repeat(push, 3) & np.tile([True, mu > 0, mu > 0], len(rows)))
    A = _dense_delassus(rows, len(vel))[np.ix_(S, S)]
    ref = np.linalg.pinv(A, rcond=1e-12, hermitian=True) @ (-v0).ravel()[S]
    assert np.abs(lam.ravel()[S] - ref).max() <= least_norm * np.abs(ref).max()
    return st_body


@pytest.mark.exact
def test_fewer_rows_than_freedoms_is_the_rows_method():
    """A frictionless box on its face (4 normal rows on 6 freedoms): the rows' system is the
    smaller, the body-space method declines at once, and ``solve_islands`` gives the rows'
    impulses."""
    rows, vel, omega = _box_stack(1, seed=4)
    assert _check_body_answer(rows, vel, omega, 0.0) == active_set._ROWS


@pytest.mark.exact
def test_a_free_freedom_is_the_rows_method():
    """A box pressed on one edge (two sticking contacts: 6 rows on 6 freedoms, but it turns about
    the edge freely) and a 4-box stack whose second face separates (the three boxes above it float:
    their common motion is fixed by no row): ``G = JᵀJ`` is singular (a pivot below
    ``DIRECT_PIVOT_FRACTION`` of its diagonal), the body impulse is not unique, and the
    body-space method declines; ``solve_islands`` gives the rows' answer."""
    rows, vel, omega = _box_stack(1, seed=4)
    vel = _pressed(vel, 1)
    edge = np.flatnonzero(rows.ra[:, 0] < 0)   # the two contacts of the edge x = −h
    edge_rows = rows.select(edge)
    assert _check_body_answer(edge_rows, vel, omega, 0.6) == active_set._ROWS
    chain, chain_vel, chain_omega = _box_stack(4, seed=4)
    chain_vel = _pressed(chain_vel, 4)
    chain_vel[2, 2] = chain_vel[1, 2] + 0.05   # the second box leaves the first
    assert _check_body_answer(chain, chain_vel, chain_omega, 0.6) == active_set._ROWS


@pytest.mark.exact
@pytest.mark.parametrize("square", [False, True])
@pytest.mark.parametrize("seed", range(12))
def test_body_space_answer_on_random_chains(seed, square):
    """Random chains (1–6 bodies, tilted faces, masses 100× apart, full inertia tensors), with
    friction that holds and without: where the body-space method takes one, its answer is the rows'
    method's to round-off and the least-norm one to 1e-10; where it declines (a body left on two
    contacts turns about them), ``solve_islands`` gives the rows' answer (``_check_body_answer``).
    It takes every chain of pressed square faces with friction (solved, or unfinished where the
    sticking impulses leave the cone, as the rows' method finds too)."""
    rows, vel, omega = _random_chain(seed, 1 + seed % 6, square)
    taken = _check_body_answer(rows, vel, omega, 1.5)
    _check_body_answer(rows, vel, omega, 0.0)
    if square:
        assert taken != active_set._ROWS
