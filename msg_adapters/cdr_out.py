"""The node's per-tick outputs written straight to CDR bytes (``Publisher.publish(bytes)``).

rclpy turns a message object into bytes field by field in Python-facing C: a ``MarkerArray`` of
a dozen markers with their points cost ~1.5 ms a tick and a ``PointCloud2`` ~0.2 ms, three times the
engine's step on a small scene. Written here with ``struct`` and numpy, they are the same bytes
(tests compare them with ``rclpy.serialization.serialize_message`` of the message objects that
``conversions`` builds) at a fraction of the cost, as ``conversions.posearray_cdr`` already does for
``body_states``.

The encoding is ROS 2's default: little-endian plain CDR (encapsulation ``00 01 00 00``), each
primitive aligned to its size counted from the start of the body (after those four bytes), a
string as ``uint32`` length (with its NUL) then the bytes and the NUL, a sequence as ``uint32``
count then the elements (aligned to the element's first primitive only when there is one).
"""
import struct

import numpy as np

_ENCAPSULATION = b"\x00\x01\x00\x00"


class CdrWriter:
    """Appends CDR primitives to a body (``bytes()`` then prepends the encapsulation)."""

    def __init__(self):
        self.out = bytearray()

    def align(self, n):
        pad = -len(self.out) % n
        if pad:
            self.out += b"\0" * pad

    def pack(self, align, fmt, *values):
        """Values of one alignment in a row (``fmt`` without the byte-order mark)."""
        self.align(align)
        self.out += struct.pack("<" + fmt, *values)

    def string(self, s):
        b = s.encode("utf-8") + b"\0" if isinstance(s, str) else s + b"\0"
        self.align(4)
        self.out += struct.pack("<I", len(b)) + b

    def doubles_seq(self, rows):
        """A sequence of structs of doubles (``rows (N, k)``: points, poses)."""
        self.pack(4, "I", len(rows))
        if len(rows):
            self.align(8)
            self.out += np.ascontiguousarray(rows, "<f8").tobytes()

    def octets(self, data):
        """A ``sequence<uint8>``."""
        self.pack(4, "I", len(data))
        self.out += data

    def header(self, frame_id, stamp_ns):
        """``std_msgs/Header``."""
        self.pack(4, "iI", int(stamp_ns // 1_000_000_000), int(stamp_ns % 1_000_000_000))
        self.string(frame_id)

    def bytes(self):
        return _ENCAPSULATION + bytes(self.out)


def pointcloud2_cdr(a, fields_cdr, frame_id, stamp_ns):
    """``sensor_msgs/PointCloud2`` of the structured array ``a (N,)`` (height 1, little-endian,
    dense), ``fields_cdr`` the ``sequence<PointField>`` of its layout (``point_fields_cdr``)."""
    a = np.ascontiguousarray(a)
    w = CdrWriter()
    w.header(frame_id, stamp_ns)
    w.pack(4, "II", 1, len(a))
    w.align(4)
    w.out += fields_cdr   # 4-aligned, and its own alignment does not depend on where it starts
    step = a.dtype.itemsize
    w.pack(1, "?", False)
    w.pack(4, "II", step, step * len(a))
    w.octets(a.tobytes())
    w.pack(1, "?", True)
    return w.bytes()


def point_fields_cdr(fields):
    """``sequence<sensor_msgs/PointField>`` of ``PointField`` messages (``conversions.point_fields``),
    to splice at a 4-aligned offset."""
    w = CdrWriter()
    w.pack(4, "I", len(fields))
    for f in fields:
        w.string(f.name)
        w.pack(4, "I", f.offset)
        w.pack(1, "B", f.datatype)
        w.pack(4, "I", f.count)
    return bytes(w.out)


def marker_array_cdr(markers, frame_id, stamp_ns):
    """``visualization_msgs/MarkerArray`` of marker specs ``(ns, id, type, action, scale (3,),
    color (4,), points (P, 3))`` (``conversions.contact_marker_specs``), each with the header
    ``frame_id``/``stamp_ns``, an identity pose, no lifetime, and every other field empty."""
    w = CdrWriter()
    w.pack(4, "I", len(markers))
    heads = {}   # header + ns: 4-aligned items only, the same bytes at any 4-aligned offset
    for ns, mid, mtype, action, scale, color, points in markers:
        head = heads.get(ns)
        if head is None:
            h = CdrWriter()
            h.header(frame_id, stamp_ns)
            h.string(ns)
            head = heads[ns] = bytes(h.out)
        w.align(4)
        w.out += head
        w.pack(4, "iii", mid, mtype, action)
        w.pack(8, "10d", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, *scale)
        w.pack(4, "4fiI", *color, 0, 0)     # colour, lifetime
        w.pack(1, "?", False)               # frame_locked
        w.doubles_seq(points)
        w.align(4)
        w.out += _MARKER_TAIL
    return w.bytes()


def _marker_tail():
    """A Marker's fields after ``points``, all empty: their alignments are 4 at most, so from any
    4-aligned offset they are these bytes."""
    w = CdrWriter()
    w.pack(4, "I", 0)                   # colors
    w.string("")                        # texture_resource
    w.header("", 0)                     # texture: CompressedImage (header, format, data)
    w.string("")
    w.pack(4, "I", 0)
    w.pack(4, "I", 0)                   # uv_coordinates
    w.string("")                        # text
    w.string("")                        # mesh_resource
    w.string("")                        # mesh_file: filename, data
    w.pack(4, "I", 0)
    w.pack(1, "?", False)               # mesh_use_embedded_materials
    return bytes(w.out)


_MARKER_TAIL = _marker_tail()
