import numpy as np

from contact_sim.vec import cross


def test_cross_matches_numpy_with_broadcasting():
    rng = np.random.default_rng(1)
    for sa, sb in [((7, 3), (7, 3)), ((4, 1, 3), (4, 5, 3)), ((3,), (6, 3)), ((2, 3, 3), (3,))]:
        a, b = rng.normal(size=sa), rng.normal(size=sb)
        assert np.array_equal(cross(a, b), np.cross(a, b))
    assert np.array_equal(cross([1, 0, 0], [0, 1, 0]), [0, 0, 1])


def test_dot_matches_row_wise_sum():
    from contact_sim.vec import dot

    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(5, 4, 3)), rng.normal(size=(5, 4, 3))
    assert np.allclose(dot(a, b), (a * b).sum(axis=-1), rtol=0, atol=1e-15)
