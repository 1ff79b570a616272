#!/usr/bin/env python3
"""arch.py — a shallow circular arch in the plane z = 0 as a triangle OBJ,
for crom-mesh import --thickness T --plane-strain (pipelines/bistable.mk).

usage: arch.py SPAN RISE DEPTH NX NY > arch.obj

The arch's mid-surface is the circular arc through (-SPAN/2, 0), (0, RISE),
(SPAN/2, 0); it is DEPTH thick (radially), meshed by NX x NY quads each cut
into two triangles along alternating diagonals, counterclockwise."""
import math
import sys


def main():
    if len(sys.argv) != 6:
        sys.exit(__doc__.strip().splitlines()[3])
    span, rise, depth = (float(a) for a in sys.argv[1:4])
    nx, ny = int(sys.argv[4]), int(sys.argv[5])
    if not (span > 0 and 0 < rise < span / 2 and 0 < depth < rise and nx >= 2 and ny >= 1):
        sys.exit("arch.py: need SPAN > 0, 0 < RISE < SPAN/2, 0 < DEPTH < RISE, NX >= 2, NY >= 1")
    R = (span * span / 4 + rise * rise) / (2 * rise)        # radius of the mid-surface
    half = math.asin(span / (2 * R))                       # half the opening angle
    cy = rise - R                                          # centre below the crown
    out = sys.stdout
    for j in range(ny + 1):
        r = R - depth / 2 + depth * j / ny
        for i in range(nx + 1):
            a = -half + 2 * half * i / nx
            out.write("v %.12g %.12g 0\n" % (r * math.sin(a), cy + r * math.cos(a)))
    idx = lambda i, j: j * (nx + 1) + i + 1
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            if (i + j) % 2:
                out.write("f %d %d %d\nf %d %d %d\n" % (a, b, c, a, c, d))
            else:
                out.write("f %d %d %d\nf %d %d %d\n" % (a, b, d, b, c, d))


if __name__ == "__main__":
    main()
