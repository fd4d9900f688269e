"""A tiny mesh for the Python tests: the octahedron tests/helpers/test_cli_helpers.h writes."""


def octahedron_obj():
    """The regular octahedron |x| + |y| + |z| <= 1, outward triangles (as write_octahedron in test_cli_helpers.h)."""
    lines = [f"v {x} {y} {z}" for x, y, z in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]
    for s in range(8):  # one face per octant; a reflection reverses the winding
        x, y, z = (2 if s & 1 else 1), (4 if s & 2 else 3), (6 if s & 4 else 5)
        odd = ((s & 1) + (s >> 1 & 1) + (s >> 2 & 1)) & 1
        lines.append(f"f {x} {z if odd else y} {y if odd else z}")
    return "\n".join(lines) + "\n"
