#!/usr/bin/env python3
"""Writes a flapping bird as an OBJ mesh sequence for examples/flock_bird (a deforming target of the
shape flock, docs/shape-flock.md#a-flapping-bird).

    tools/make-bird-sequence.py OUT_DIR        # writes OUT_DIR/bird_000.obj ... bird_023.obj

One wingbeat in FRAMES meshes, looping (mesh FRAMES would be mesh 0 again). The bird flies along +x
with +z up: a body, head, beak and fan tail as one closed tube along x (elliptic sections, a pole at
each end), and two wings, each a closed thin tube along the span, hinged at the shoulders on axes
parallel to x. A wing's root angle is theta = DIHEDRAL + AMPLITUDE sin(2 pi k / FRAMES) in mesh k,
bending more toward the tip. Mesh 0 (wings near level) is also the rest shape the scene uses as
target.mesh.

Every mesh has the same vertices in the same order and the same triangles; only the wings' y and z
change (the wings rotate about axes parallel to x). flockmorph matches a sequence's meshes to the
target vertex for vertex as the files list them. A wing vertex's x is made unique at the printed
precision (moved by 0.001 where it would equal another's): an older flockmorph matched meshes by the
sorted order of their positions, and the meshes are kept as they were committed then. The script
checks that no two vertices coincide (the engine would weld them into one) and that each part is
closed and outward, and fails otherwise.

Deterministic, standard library only; positions printed with DECIMALS decimals.
"""
import argparse
import math
import os
import sys

FRAMES = 24
DECIMALS = 3
SCALE = 10 ** DECIMALS

# Body, head and tail: stations (x, half-width y, half-height z, centre z), interpolated by
# Catmull-Rom between them. Tail fan at x = -3.4, beak tip at x = 3.2.
BODY_STATIONS = [
    (-3.40, 1.00, 0.05, 0.15),
    (-2.60, 0.62, 0.07, 0.12),
    (-1.80, 0.36, 0.24, 0.05),
    (-1.00, 0.70, 0.64, 0.00),
    (-0.20, 0.80, 0.74, 0.00),
    (0.60, 0.72, 0.70, 0.05),
    (1.30, 0.45, 0.45, 0.25),
    (1.70, 0.36, 0.37, 0.42),
    (2.10, 0.47, 0.45, 0.52),
    (2.50, 0.36, 0.34, 0.50),
    (2.75, 0.14, 0.12, 0.44),
    (3.20, 0.02, 0.02, 0.38),
]
BODY_RINGS = 20        # sections between the poles
BODY_SIDES = 12        # vertices per section
POLE_GAP = 0.05        # a pole lies this far beyond its tube's last section

# Wings: the hinge (shoulder) of the right wing; the left one is its mirror image in y = 0.
HINGE = (0.20, 0.95, 0.30)
SPAN = 4.6             # hinge to tip along the wing
WING_RINGS = 8
WING_SIDES = 10
ROOT_CHORD, TIP_CHORD = 1.70, 0.25
ROOT_THICKNESS, TIP_THICKNESS = 0.16, 0.04
SWEEP = 0.45           # the tip's chord centre lies this far behind the root's
DIHEDRAL = 0.10        # rad, the mean wing angle
AMPLITUDE = 0.60       # rad, the flap's amplitude at the root
TIP_BEND = 0.50        # the angle grows by this fraction from root to tip
RING_PHASE = 0.25      # sections start a quarter step off the axes, so no two of a ring's x are equal


def catmull_rom(points, u):
    """The Catmull-Rom spline through points (tuples) at u in [0, len - 1]."""
    i = min(int(u), len(points) - 2)
    t = u - i
    p0, p1, p2, p3 = (points[max(0, min(len(points) - 1, j))] for j in (i - 1, i, i + 1, i + 2))
    return tuple(0.5 * (2 * b + (c - a) * t + (2 * a - 5 * b + 4 * c - d) * t * t + (3 * b - a - 3 * c + d) * t ** 3)
                 for a, b, c, d in zip(p0, p1, p2, p3))


def ring_angles(sides):
    return [2 * math.pi * (k + RING_PHASE) / sides for k in range(sides)]


def body_vertices():
    """Sections from the tail to the beak, then the tail pole and the beak pole."""
    verts = []
    for r in range(BODY_RINGS):
        x, ry, rz, zc = catmull_rom(BODY_STATIONS, r * (len(BODY_STATIONS) - 1) / (BODY_RINGS - 1))
        verts += [(x, ry * math.cos(a), zc + rz * math.sin(a)) for a in ring_angles(BODY_SIDES)]
    tail, beak = BODY_STATIONS[0], BODY_STATIONS[-1]
    verts.append((tail[0] - POLE_GAP, 0.0, tail[3]))
    verts.append((beak[0] + POLE_GAP, 0.0, beak[3]))
    return verts


def wing_angle(theta, s):
    """The wing's angle above the horizontal at span s, for the root angle theta."""
    return theta * (1 + TIP_BEND * s / SPAN)


def wing_centre(theta, s):
    """The right wing's centre line at span s in the (y, z) plane: the integral of its direction."""
    a, b = theta, theta * TIP_BEND / SPAN
    if abs(b) < 1e-12:
        dy, dz = s * math.cos(a), s * math.sin(a)
    else:
        dy, dz = (math.sin(a + b * s) - math.sin(a)) / b, (math.cos(a) - math.cos(a + b * s)) / b
    return HINGE[1] + dy, HINGE[2] + dz


def wing_station(s):
    """Chord centre x, half chord and half thickness at span s (elliptic planform)."""
    f = s / SPAN
    chord = TIP_CHORD + (ROOT_CHORD - TIP_CHORD) * math.sqrt(max(0.0, 1 - f * f))
    thickness = ROOT_THICKNESS + (TIP_THICKNESS - ROOT_THICKNESS) * f
    return HINGE[0] - SWEEP * f * f, chord / 2, thickness / 2


def wing_spans():
    """The sections' span, then the root pole's and the tip pole's."""
    return [SPAN * i / (WING_RINGS - 1) for i in range(WING_RINGS)] + [-POLE_GAP, SPAN + 2 * POLE_GAP]


def wing_x(body_xs):
    """Each right-wing vertex's x (the same in every mesh), rounded, and unique against body_xs."""
    used = {round(x * SCALE) for x in body_xs}
    xs = []
    spans = wing_spans()
    for i, s in enumerate(spans):
        xc, half_chord, _ = wing_station(min(max(s, 0.0), SPAN))
        ring = [xc + half_chord * math.cos(a) for a in ring_angles(WING_SIDES)] if i < WING_RINGS else [xc]
        for x in ring:
            q = round(x * SCALE)
            while q in used:
                q += 1
            used.add(q)
            xs.append(q / SCALE)
    return xs


def right_wing_vertices(theta, xs):
    """The right wing at root angle theta: sections from root to tip, then the root and tip poles."""
    verts, at = [], 0
    for i, s in enumerate(wing_spans()):
        sc = min(max(s, 0.0), SPAN)
        y, z = wing_centre(theta, s)
        phi = wing_angle(theta, sc)
        _, _, half_thick = wing_station(sc)
        angles = ring_angles(WING_SIDES) if i < WING_RINGS else [0.0]
        for a in angles:
            h = half_thick * math.sin(a) if i < WING_RINGS else 0.0
            verts.append((xs[at], y - h * math.sin(phi), z + h * math.cos(phi)))
            at += 1
    return verts


def tube_faces(rings, sides, base):
    """Triangles of a tube of `rings` sections of `sides` vertices from index base, closed by the
    pole after them (first end) and the one after that (last end)."""
    faces = []
    v = lambda r, k: base + r * sides + k % sides
    for r in range(rings - 1):
        for k in range(sides):
            faces += [(v(r, k), v(r + 1, k), v(r + 1, k + 1)), (v(r, k), v(r + 1, k + 1), v(r, k + 1))]
    first, last = base + rings * sides, base + rings * sides + 1
    for k in range(sides):
        faces += [(first, v(0, k), v(0, k + 1)), (last, v(rings - 1, k + 1), v(rings - 1, k))]
    return faces


def signed_volume(verts, faces):
    total = 0.0
    for a, b, c in faces:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = verts[a], verts[b], verts[c]
        total += ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
    return total / 6


def outward(verts, faces):
    """faces, reversed if they enclose a negative volume."""
    return faces if signed_volume(verts, faces) > 0 else [(a, c, b) for a, b, c in faces]


def theta_at(frame):
    return DIHEDRAL + AMPLITUDE * math.sin(2 * math.pi * frame / FRAMES)


def bird(frame, xs):
    """The vertices of mesh `frame`: body, right wing, left wing (the right one mirrored)."""
    right = right_wing_vertices(theta_at(frame), xs)
    return body_vertices() + right + [(x, -y, z) for x, y, z in right]


def bird_faces(rest):
    """The triangles (0-based), each part turned outward on the rest shape."""
    nb, nw = BODY_RINGS * BODY_SIDES + 2, WING_RINGS * WING_SIDES + 2
    parts = [tube_faces(BODY_RINGS, BODY_SIDES, 0), tube_faces(WING_RINGS, WING_SIDES, nb),
             tube_faces(WING_RINGS, WING_SIDES, nb + nw)]
    return [f for part in parts for f in outward(rest, part)]


def fmt(value):
    text = f"{value:.{DECIMALS}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def rounded(verts):
    return [tuple(float(fmt(c)) for c in p) for p in verts]


def check_closed(faces, nverts):
    """Every directed edge once and its reverse once: closed, manifold and consistently oriented."""
    edges = {}
    for f in faces:
        for k in range(3):
            e = (f[k], f[(k + 1) % 3])
            edges[e] = edges.get(e, 0) + 1
    bad = [e for e, n in edges.items() if n != 1 or edges.get((e[1], e[0])) != 1]
    used = {i for f in faces for i in f}
    if bad or len(used) != nverts:
        sys.exit(f"make-bird-sequence: not a closed oriented mesh ({len(bad)} bad edges, "
                 f"{nverts - len(used)} unused vertices)")


def check_distinct(meshes):
    """No two vertices at one position in any mesh: the engine welds such vertices into one."""
    for k, verts in enumerate(meshes):
        if len(set(verts)) != len(verts):
            sys.exit(f"make-bird-sequence: mesh {k} has two vertices at one position")


def write_obj(path, frame, verts, faces):
    with open(path, "w", newline="\n") as f:
        f.write(f"# flockmorph flapping bird, mesh {frame} of {FRAMES} (one wingbeat): "
                f"tools/make-bird-sequence.py\n")
        for p in verts:
            f.write("v " + " ".join(fmt(c) for c in p) + "\n")
        for a, b, c in faces:
            f.write(f"f {a + 1} {b + 1} {c + 1}\n")


def main():
    parser = argparse.ArgumentParser(
        description=f"Write a flapping bird as {FRAMES} OBJ meshes, OUT_DIR/bird_000.obj ... "
                    f"bird_{FRAMES - 1:03d}.obj: one wingbeat, looping. Mesh 0 is the rest shape.")
    parser.add_argument("out_dir", metavar="OUT_DIR", help="directory to write to (created if missing)")
    args = parser.parse_args()
    xs = wing_x([p[0] for p in body_vertices()])
    meshes = [rounded(bird(k, xs)) for k in range(FRAMES)]
    faces = bird_faces(meshes[0])
    check_closed(faces, len(meshes[0]))
    check_distinct(meshes)
    os.makedirs(args.out_dir, exist_ok=True)
    for k, verts in enumerate(meshes):
        write_obj(os.path.join(args.out_dir, f"bird_{k:03d}.obj"), k, verts, faces)
    print(f"make-bird-sequence: {FRAMES} meshes of {len(meshes[0])} vertices and {len(faces)} "
          f"triangles in {args.out_dir}")


if __name__ == "__main__":
    main()
