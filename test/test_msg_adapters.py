"""msg_adapters conversions without a running node: exact round trips, vectorised speed, validation."""
import sys
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
pytestmark = pytest.mark.ros

from geometry_msgs.msg import PoseArray  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402

import contact_sim  # noqa: E402
from msg_adapters import conversions as cv  # noqa: E402

FLOAT_FIELDS = ("point", "normal", "depth", "impulse", "normal_impulse", "friction_impulse",
                "relative_normal_velocity")


def random_contacts(k, seed=0):
    rng = np.random.default_rng(seed)

    def nasty(shape):
        """Values whose every bit matters: random doubles, subnormals, -0.0, huge and tiny numbers."""
        x = rng.standard_normal(shape) * 10.0 ** rng.integers(-300, 300, shape)
        flat = x.reshape(-1)
        if flat.size >= 4:
            flat[:4] = [-0.0, 5e-324, np.nextafter(1.0, 2.0), -1.7976931348623157e308]
        return x

    n = rng.standard_normal((k, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return contact_sim.Contacts(
        body_a=rng.integers(0, 2**31, k), body_b=rng.integers(0, 2**31, k), point=nasty((k, 3)), normal=n,
        depth=nasty(k), impulse=nasty((k, 3)), normal_impulse=nasty(k), friction_impulse=nasty((k, 3)),
        relative_normal_velocity=nasty(k), feature=rng.integers(0, len(contact_sim.FEATURES), k),
    )


def assert_bits_equal(a, b):
    a, b = np.ascontiguousarray(a, np.float64), np.ascontiguousarray(b, np.float64)
    assert a.shape == b.shape
    np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64))


def assert_contacts_identical(c, d):
    for f in FLOAT_FIELDS:
        assert_bits_equal(getattr(c, f), getattr(d, f))
    for f in ("body_a", "body_b", "feature"):
        np.testing.assert_array_equal(getattr(c, f), getattr(d, f))
        assert getattr(d, f).dtype == np.int64


def header():
    return cv.make_header("world", 1_700_000_000_123_456_789)


@pytest.mark.parametrize("k", [0, 1, 7])
def test_contacts_pointcloud2_round_trip_is_bit_exact_through_the_wire(k):
    c = random_contacts(k, seed=k)
    msg = cv.contacts_to_pointcloud2(c, header())
    wire = deserialize_message(serialize_message(msg), PointCloud2)
    assert_contacts_identical(c, cv.pointcloud2_to_contacts(wire))
    assert wire.header.stamp.sec == 1_700_000_000 and wire.header.stamp.nanosec == 123_456_789


def test_pointcloud2_layout_is_documented_rviz_xyz_float32_and_the_rest_float64():
    """x y z float32 (RViz's PointCloud2 display takes nothing else), the exact point in point_x/y/z
    (was: x y z float64 in a 136-byte point; now a 152-byte point, every field naturally aligned)."""
    c = random_contacts(5)
    msg = cv.contacts_to_pointcloud2(c, header())
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 5, 152, 5 * 152)
    assert not msg.is_bigendian and msg.is_dense
    fields = {f.name: f for f in msg.fields}
    assert list(fields) == [n for n, _ in cv.CONTACT_FIELDS]
    for name in ("x", "y", "z"):
        assert fields[name].datatype == PointField.FLOAT32 and fields[name].count == 1
    assert [fields[n].offset for n in ("x", "y", "z")] == [0, 4, 8]
    for name in ("point_x", "point_y", "point_z", "normal_x", "depth", "impulse_z", "normal_impulse",
                 "friction_impulse_y", "relative_normal_velocity"):
        assert fields[name].datatype == PointField.FLOAT64 and fields[name].count == 1
        assert fields[name].offset % 8 == 0
    for name in ("body_a", "body_b", "feature"):
        assert fields[name].datatype == PointField.UINT32
    offsets = [f.offset for f in msg.fields]
    assert offsets == sorted(offsets) and offsets[-1] + 4 <= msg.point_step
    assert len(msg.data) == 5 * 152
    a = cv.pointcloud2_to_array(msg)
    with np.errstate(over="ignore"):
        np.testing.assert_array_equal(a["x"], c.point[:, 0].astype(np.float32))
    assert_bits_equal(a["point_z"], c.point[:, 2])


def count_python_work(fn):
    """Lines of Python executed and calls (Python and C functions) made by ``fn()``: a loop over
    contacts in Python, or a call per contact, makes these grow with the number of contacts."""
    n = [0]

    def trace(frame, event, arg):
        n[0] += 1
        return trace

    def prof(frame, event, arg):
        if event == "c_call":
            n[0] += 1

    old_trace, old_profile = sys.gettrace(), sys.getprofile()  # e.g. coverage's tracer
    sys.settrace(trace)
    sys.setprofile(prof)
    try:
        fn()
    finally:
        sys.setprofile(old_profile)
        sys.settrace(old_trace)
    return n[0]


def test_ten_thousand_contacts_convert_with_numpy():
    big, small = random_contacts(10_000, seed=3), random_contacts(10, seed=4)

    def both_ways(c):
        return lambda: cv.pointcloud2_to_contacts(cv.contacts_to_pointcloud2(c, header()))

    both_ways(small)()  # warm up imports and caches
    # no per-contact Python work: exactly as many calls for 10,000 contacts as for 10
    assert count_python_work(both_ways(big)) == count_python_work(both_ways(small))
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        back = both_ways(big)()
        best = min(best, time.perf_counter() - t0)
    assert_contacts_identical(big, back)
    assert best < 0.25, f"10,000 contacts took {best * 1e3:.1f} ms both ways (numpy: ~6 ms)"


def test_pointcloud2_to_array_reads_foreign_clouds():
    dt = np.dtype({"names": ["x", "y", "z", "intensity"], "formats": ["<f4"] * 4, "offsets": [0, 4, 8, 16],
                   "itemsize": 20})
    a = np.zeros(4, dt)
    a["x"] = [1, 2, 3, 4]
    a["intensity"] = [0.5, 0.25, 0.125, 1.0]
    msg = cv.array_to_pointcloud2(a, header())
    back = cv.pointcloud2_to_array(deserialize_message(serialize_message(msg), PointCloud2))
    np.testing.assert_array_equal(back["x"], a["x"])
    np.testing.assert_array_equal(back["intensity"], a["intensity"])
    msg.data = bytes(msg.data)[:-1]
    with pytest.raises(ValueError, match="needs 80"):
        cv.pointcloud2_to_array(msg)


def random_poses(n, seed=0):
    rng = np.random.default_rng(seed)
    p = rng.standard_normal((n, 3)) * 10.0 ** rng.integers(-200, 200, (n, 3))
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return p, q


@pytest.mark.parametrize("n", [0, 1, 5])
def test_posearray_message_round_trip_is_bit_exact(n):
    p, q = random_poses(n, seed=n)
    msg = deserialize_message(serialize_message(cv.arrays_to_posearray(p, q, header())), PoseArray)
    p2, q2 = cv.posearray_to_arrays(msg)
    assert p2.shape == (n, 3) and q2.shape == (n, 4)
    assert_bits_equal(p, p2)
    assert_bits_equal(q, q2)


@pytest.mark.parametrize("frame_id", ["", "w", "ab", "abc", "world", "base_link", "frame_with_len_15"])
@pytest.mark.parametrize("n", [0, 1, 3])
def test_posearray_cdr_matches_rclpy_serialization_both_ways(frame_id, n):
    p, q = random_poses(n, seed=7)
    stamp = 1_700_000_001_000_000_007
    msg = cv.arrays_to_posearray(p, q, cv.make_header(frame_id, stamp))
    # ours -> rclpy
    back = deserialize_message(cv.posearray_cdr(p, q, frame_id, stamp), PoseArray)
    assert back.header.frame_id == frame_id
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (1_700_000_001, 7)
    p2, q2 = cv.posearray_to_arrays(back)
    assert_bits_equal(p, p2)
    assert_bits_equal(q, q2)
    # rclpy -> ours
    stamp_ns, fid, p3, q3 = cv.parse_posearray_cdr(serialize_message(msg))
    assert (stamp_ns, fid) == (stamp, frame_id)
    assert_bits_equal(p, p3)
    assert_bits_equal(q, q3)


def test_parse_posearray_cdr_refuses_malformed_bytes():
    good = cv.posearray_cdr(*random_poses(2), "world", 5)
    for bad, what in [(b"", "too short"), (b"\x07\x07\x00\x00" + good[4:], "encapsulation"),
                      (good[:10], "truncated"), (good[:-8], "need")]:
        with pytest.raises(cv.CdrError, match=what):
            cv.parse_posearray_cdr(bad)
    huge = bytearray(good)
    huge[4 + 12 + 8:4 + 12 + 8 + 4] = (10**9).to_bytes(4, "little")  # pose count far beyond the data
    with pytest.raises(cv.CdrError, match="poses need"):
        cv.parse_posearray_cdr(bytes(huge))


def test_validate_poses_refuses_each_kind_of_bad_input_by_name():
    p, q = random_poses(3)
    ok_p, ok_q = cv.validate_poses(p, q * (1 + 5e-4), expected=3, tolerance=1e-3)
    assert_bits_equal(ok_p, p)
    np.testing.assert_allclose(np.linalg.norm(ok_q, axis=1), 1.0, rtol=0, atol=1e-15)
    cases = [
        (p[:2], q[:2], "length"),
        (np.vstack([p, p[:1]]), np.vstack([q, q[:1]]), "length"),
        (p, q[:, :3], "length"),
        (np.where(np.arange(9).reshape(3, 3) == 4, np.nan, p), q, "nonfinite"),
        (p, np.where(np.arange(12).reshape(3, 4) == 0, np.inf, q), "nonfinite"),
        (p, np.vstack([q[:2], np.zeros(4)]), "zero_quaternion"),
        (p, np.vstack([q[:2], [0.0, 0.0, 0.0, 1.1]]), "non_unit_quaternion"),
    ]
    for pp, qq, reason in cases:
        with pytest.raises(cv.PoseError) as info:
            cv.validate_poses(pp, qq, expected=3, tolerance=1e-3, what="body_poses")
        assert info.value.reason == reason
        assert "body_poses" in str(info.value)


def test_markers_show_points_and_the_largest_impulses():
    c = random_contacts(20, seed=1)
    c.impulse = np.random.default_rng(2).standard_normal((20, 3))
    c.point = np.random.default_rng(3).standard_normal((20, 3))
    m = cv.contact_markers(c, header(), impulse_scale=0.5, max_arrows=5)
    assert m.markers[0].action == Marker.DELETEALL
    assert m.markers[1].type == Marker.SPHERE_LIST and len(m.markers[1].points) == 20
    lines = m.markers[2]
    assert lines.type == Marker.LINE_LIST and len(lines.points) == 40  # every impulse as a segment
    seg = np.array([[p.x, p.y, p.z] for p in lines.points]).reshape(20, 2, 3)
    order = np.argsort(-np.linalg.norm(c.impulse, axis=1), kind="stable")
    np.testing.assert_allclose(seg[:, 0], c.point[order])
    np.testing.assert_allclose(seg[:, 1] - seg[:, 0], 0.5 * c.impulse[order], atol=1e-12)
    arrows = m.markers[3:]
    assert len(arrows) == 5 and all(a.type == Marker.ARROW for a in arrows)
    biggest = np.argmax(np.linalg.norm(c.impulse, axis=1))
    a0 = arrows[0].points
    np.testing.assert_allclose([a0[0].x, a0[0].y, a0[0].z], c.point[biggest])
    np.testing.assert_allclose([a0[1].x - a0[0].x, a0[1].y - a0[0].y, a0[1].z - a0[0].z],
                               0.5 * c.impulse[biggest], atol=1e-12)
    empty = cv.contact_markers(contact_sim.Contacts.empty(), header())
    assert len(empty.markers) == 2 and not empty.markers[1].points


def test_diagnostics_round_trip():
    msg = cv.diagnostic_array(header(), "contact_sim: world", "/contact_sim",
                              {"contacts": 3, "energy_J": 1.25, "paused": False, "scene": "x.yaml"})
    d = cv.diagnostics_to_dict(msg, "contact_sim: world")
    assert d == {"contacts": "3", "energy_J": "1.25", "paused": "false", "scene": "x.yaml"}
    assert cv.diagnostics_to_dict(msg, "other") is None


@pytest.mark.parametrize("frame, names", [("", []), ("w", ["a"]), ("world", ["ground", "paddle", "ball"]),
                                          ("abc", ["xxxxx", "yy", "z"])])
def test_multidof_cdr_round_trip_through_rclpy(frame, names):
    """The MultiDOFJointState written as bytes (alignment after every string) reads back exactly."""
    from sensor_msgs.msg import MultiDOFJointState

    rng = np.random.default_rng(len(names))
    n = len(names)
    p, q, v, w, f, t = (rng.standard_normal((n, k)) for k in (3, 4, 3, 3, 3, 3))
    data = cv.multidof_cdr(cv.names_cdr(names), p, q, v, w, f, t, frame, 1_700_000_000_123_456_789)
    msg = deserialize_message(data, MultiDOFJointState)
    assert msg.header.frame_id == frame and cv.stamp_to_ns(msg.header.stamp) == 1_700_000_000_123_456_789
    assert len(serialize_message(msg)) == len(data)
    got_names, p2, q2, v2, w2 = cv.multidof_to_arrays(msg)
    assert got_names == names
    if n:
        for a, b in ((p, p2), (q, q2), (v, v2), (w, w2)):
            assert_bits_equal(a, b)
        wrench = np.array([(x.force.x, x.force.y, x.force.z, x.torque.x, x.torque.y, x.torque.z) for x in msg.wrench])
        assert_bits_equal(wrench, np.hstack([f, t]))
    else:
        assert p2 is None and v2 is None
    msg.twist = msg.twist[:1] if n > 1 else msg.twist
    if n > 1:
        with pytest.raises(cv.PoseError, match="1 twist for"):
            cv.multidof_to_arrays(msg)


def test_contact_wrenches_sum_impulses_per_body():
    c = random_contacts(300, seed=5)
    c.body_a, c.body_b = c.body_a % 7, c.body_b % 7
    c.point, c.impulse = np.random.default_rng(1).standard_normal((2, 300, 3))
    origins = np.random.default_rng(2).standard_normal((9, 3))
    force, torque = cv.contact_wrenches(c, origins, 0.01)
    f_ref, t_ref = np.zeros((9, 3)), np.zeros((9, 3))
    j = c.impulse / 0.01
    np.add.at(f_ref, c.body_a, j)
    np.add.at(f_ref, c.body_b, -j)
    np.add.at(t_ref, c.body_a, np.cross(c.point - origins[c.body_a], j))
    np.add.at(t_ref, c.body_b, -np.cross(c.point - origins[c.body_b], j))
    np.testing.assert_allclose(force, f_ref, atol=1e-9)
    np.testing.assert_allclose(torque, t_ref, atol=1e-9)
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-9)      # action and reaction
    assert not force[7:].any() and not torque[7:].any()


@pytest.mark.parametrize("frame_id", ["", "w", "world", "base_link_7"])
@pytest.mark.parametrize("k", [0, 1, 7, 60])
def test_tick_outputs_as_cdr_bytes_equal_rclpy_serialization(frame_id, k):
    """The node publishes ``contacts`` and ``contact_markers`` as bytes (``cdr_out``): the same
    length as rclpy's serialization of the message objects of ``conversions``, and the same message
    read back (rclpy leaves padding bytes unset, so the bytes themselves are not compared), for
    frame ids of every length modulo 4 (the alignment of what follows), no contacts, zero
    impulses and more impulses than arrows."""
    from msg_adapters import cdr_out
    from visualization_msgs.msg import MarkerArray

    c = random_contacts(k, seed=k)
    c.point = np.random.default_rng(k).normal(size=(k, 3))          # finite points for the markers
    c.impulse = np.random.default_rng(k + 1).normal(size=(k, 3))
    if k > 2:
        c.impulse[1] = 0.0                                            # no segment, no arrow
    stamp = 1_700_000_000_123_456_789
    h = cv.make_header(frame_id, stamp)
    fields = cdr_out.point_fields_cdr(cv.point_fields(cv.CONTACT_DTYPE))
    ours = cdr_out.pointcloud2_cdr(cv.contacts_to_array(c), fields, frame_id, stamp)
    ref = serialize_message(cv.contacts_to_pointcloud2(c, h))
    assert len(ours) == len(ref)
    assert deserialize_message(ours, PointCloud2) == deserialize_message(ref, PointCloud2)
    for arrows in (0, 3, 10):
        ours = cdr_out.marker_array_cdr(cv.contact_marker_specs(c, 0.5, arrows), frame_id, stamp)
        ref = serialize_message(cv.contact_markers(c, h, 0.5, arrows))
        assert len(ours) == len(ref)
        got, want = deserialize_message(ours, MarkerArray), deserialize_message(ref, MarkerArray)
        nonzero = k - 1 if k > 2 else k
        # DELETEALL and the points; with impulses to draw, their segments and the arrows
        assert len(got.markers) == len(want.markers) == (3 + min(arrows, nonzero) if k and arrows else 2)
        assert got == want
