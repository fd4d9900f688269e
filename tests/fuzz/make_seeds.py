#!/usr/bin/env python3
"""Writes the seed inputs of fuzz_ply_binary and fuzz_stl_binary (their input formats are in
fuzz_mesh_files.h) into corpus/ply_binary/ and corpus/stl_binary/: a tetrahedron and an octahedron in
every layout, and counts the body cannot hold. The seeds are checked in; run this again after
changing a target's input format:  python3 tests/fuzz/make_seeds.py"""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
TET = ([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
OCT = ([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)],
       [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)])


def ply_body(mesh, layout):
    end = ">" if layout & 1 else "<"
    coord, count = ("d" if layout & 2 else "f"), ("I" if layout & 4 else "B")
    out = b""
    for v in mesh[0]:
        out += struct.pack(end + 3 * coord, *v) + (b"\x01" if layout & 8 else b"")
    for f in mesh[1]:
        out += struct.pack(end + count + "3i", 3, *f)
    return out


def ply_seed(mesh, layout, nv=None, nf=None):
    nv = len(mesh[0]) if nv is None else nv
    nf = len(mesh[1]) if nf is None else nf
    return bytes([layout, nv, nf]) + ply_body(mesh, layout)


def stl_triangles(mesh):
    out = b""
    for f in mesh[1]:
        out += struct.pack("<3f", 0, 0, 0)
        for i in f:
            out += struct.pack("<3f", *mesh[0][i])
        out += b"\0\0"
    return out


def write(folder, name, data):
    os.makedirs(os.path.join(HERE, "corpus", folder), exist_ok=True)
    with open(os.path.join(HERE, "corpus", folder, name), "wb") as f:
        f.write(data)


def main():
    for layout in (0, 1, 2, 4, 8, 15):
        write("ply_binary", f"tet_layout{layout}", ply_seed(TET, layout))
    write("ply_binary", "octahedron_layout0", ply_seed(OCT, 0))
    write("ply_binary", "counts_past_the_body", ply_seed(TET, 0, nv=255, nf=255))
    write("stl_binary", "tet", b"\0" + stl_triangles(TET))
    write("stl_binary", "octahedron", b"\0" + stl_triangles(OCT))
    write("stl_binary", "tet_declared", b"\1" + struct.pack("<I", 4) + stl_triangles(TET))
    write("stl_binary", "count_past_the_end", b"\1" + struct.pack("<I", 0xFFFFFFFF) + stl_triangles(TET))
    write("stl_binary", "open_surface", b"\0" + stl_triangles((TET[0], TET[1][:3])))


if __name__ == "__main__":
    main()
