"""The cylinder shape: exact where a closed form exists, a circumscribed prism elsewhere.

A ``Cylinder(radius, length)`` is centred on its body origin with its axis along local z (as URDF
and SDF). Its mass properties are exact, and so are its contacts with planes and spheres (compiled
kernels in ``collision/cylinders.py``). Against every other shape it collides as its convex hull,
an ``N``-gon prism (``N = Cylinder.SIDES`` = 32) *circumscribed* about the true cylinder: the prism
contains the cylinder, so bounding volumes and contacts are conservative (a contact is never
missed), and its surface lies at most

    r · (1 / cos(π / N) − 1)        (0.483 % of r for N = 32, at the prism's vertical edges)

outside the cylinder, touching it along the middle of every side face. That is the radial error
bound of every cylinder contact except cylinder–plane and cylinder–sphere; the caps are exact.
"""
import numpy as np

from .shapes import Convex
from .validate import LENGTH


def hull_error(radius, sides=None):
    """The largest distance ``(m)`` between the prism hull of a cylinder of ``radius`` and the
    cylinder itself: ``r (sec(π/N) − 1)``."""
    n = Cylinder.SIDES if sides is None else sides
    return radius * (1.0 / np.cos(np.pi / n) - 1.0)


class Cylinder(Convex):
    """Solid cylinder of ``radius`` and ``length`` (full length along local z, centred on the origin).

    Collision geometry for pairs without an exact kernel is the circumscribed ``SIDES``-gon prism
    (module docstring: radial error at most ``r (sec(π/N) − 1)``, 0.48 % of r for N = 32). Its side
    faces face ±x and ±y (N divisible by 4), so the object-space box is the cylinder's own.
    """

    type = "cylinder"
    size_field = "radius"
    SIDES = 32

    def __init__(self, radius, length, *, name="cylinder"):
        r = LENGTH.check(radius, f"{name}.radius")
        h = LENGTH.check(length, f"{name}.length")
        self.radius, self.length = r, h
        n = self.SIDES
        # vertices at half-step angles: the side faces' normals are at k·2π/N (±x, ±y among them),
        # each face at distance r from the axis
        ang = (np.arange(n) + 0.5) * (2.0 * np.pi / n)
        rc = r / np.cos(np.pi / n)
        ring = np.column_stack([rc * np.cos(ang), rc * np.sin(ang)])
        pts = np.vstack([np.column_stack([ring, np.full(n, -0.5 * h)]), np.column_stack([ring, np.full(n, 0.5 * h)])])
        super().__init__(pts, name=name)

    def mass_properties(self, density):
        """Exact: ``m = ρ π r² h``, ``I_zz = m r² / 2``, ``I_xx = I_yy = m (3 r² + h²) / 12``."""
        r, h = self.radius, self.length
        m = density * np.pi * r * r * h
        ixx = m * (3.0 * r * r + h * h) / 12.0
        return m, np.zeros(3), np.diag([ixx, ixx, 0.5 * m * r * r])

    def thinnest(self):
        return float(min(2.0 * self.radius, self.length))

    def sizes(self):
        return self.thinnest(), float(np.hypot(self.radius, 0.5 * self.length))

    def __repr__(self):
        return f"Cylinder(radius={self.radius}, length={self.length})"
