#!/usr/bin/env python3
"""bench/scenes/make-window-room.py: writes window-room.obj beside itself.

A closed room 4 x 3 x 5 (x, y, z; y up) lit only through a window: the light
(window-room.json) stands outside, in front of a 1 x 1 opening in the wall z = 5,
so the room sees direct light only on the patch of floor the window lets through,
and everything else is indirect. The walls are one-sided, facing the room (a
second, outer face at the same place would be dropped as a duplicate by the
loader; the walls block light from either side anyway). Run it again to
regenerate the OBJ.
"""
import os

W, H, D = 4.0, 3.0, 5.0          # room size
WX0, WX1, WY0, WY1 = 1.5, 2.5, 1.2, 2.2  # the window in the wall z = D

verts, faces, groups = [], [], []


def quad(c, e1, e2, n, group):
    """c, c+e1, c+e1+e2, c+e2, wound counter-clockwise seen from the side n points to."""
    cross = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    if sum(a * b for a, b in zip(cross, n)) < 0:
        e1, e2 = e2, e1
    base = len(verts)
    for p in (c, [c[i] + e1[i] for i in range(3)], [c[i] + e1[i] + e2[i] for i in range(3)],
              [c[i] + e2[i] for i in range(3)]):
        verts.append(p)
    faces.append((group, base))


def rect_z(z, x0, x1, y0, y1, nz, group):
    quad([x0, y0, z], [x1 - x0, 0, 0], [0, y1 - y0, 0], [0, 0, nz], group)


quad([0, 0, 0], [W, 0, 0], [0, 0, D], [0, 1, 0], "floor")
quad([0, H, 0], [W, 0, 0], [0, 0, D], [0, -1, 0], "ceiling")
quad([0, 0, 0], [0, H, 0], [0, 0, D], [1, 0, 0], "walls")
quad([W, 0, 0], [0, H, 0], [0, 0, D], [-1, 0, 0], "walls")
rect_z(0, 0, W, 0, H, 1, "walls")
rect_z(D, 0, W, 0, WY0, -1, "walls")
rect_z(D, 0, W, WY1, H, -1, "walls")
rect_z(D, 0, WX0, WY0, WY1, -1, "walls")
rect_z(D, WX1, W, WY0, WY1, -1, "walls")

here = os.path.dirname(os.path.abspath(__file__))
with open(os.path.join(here, "window-room.obj"), "w") as f:
    f.write("# window-room.obj: written by make-window-room.py (a closed room lit through a window)\n")
    for v in verts:
        f.write("v %.6g %.6g %.6g\n" % tuple(v))
    last = None
    for group, base in faces:
        if group != last:
            f.write("g %s\n" % group)
            last = group
        f.write("f %d %d %d %d\n" % (base + 1, base + 2, base + 3, base + 4))
