#!/usr/bin/env python3
"""Checks flockmorph's VTK output with Python's xml and zlib modules alone, independently of the
writer (run by the export tests, tests/cli/test_export_cli.c and tests/io/test_export_formats.c).

  check_vtk.py vtu[-raw] FILE.vtu EXPECTED tets|points [ARRAY...]
      EXPECTED holds little-endian raw values: the Points coordinates (tets: 12n f32, points:
      3n f32), then each ARRAY's values in the order named (agent_id and id: n u32; phase, group: n u8;
      velocity: 3n f32; orient: 4n f32, x y z w). The cell data (tets) or point data (points)
      must be exactly the ARRAYs named. Tets' point data must be exactly `id`, unique per point:
      4 × the tet's agent_id (from EXPECTED, or 0 … n−1 when not named) + the vertex, 0 … 3.
      vtu: the appended data must be compressed as VTK's vtkZLibDataCompressor writes it: per
      array a UInt64 header [blocks, block size, partial last block size or 0, compressed size
      of each block] and the zlib blocks, each inflating to exactly its size. vtu-raw: each array
      a UInt64 byte count and the values.
      Checks the header, that the arrays tile the appended data, the point count, the cell
      types, offsets and connectivity, and the coordinates and arrays bit for bit.
  check_vtk.py pvd FILE.pvd FRAME_RATE FRAME...
      Checks that the collection lists DIR/<stem>_<frame, 5 digits>.vtu for exactly these frames,
      in order, each at timestep frame / FRAME_RATE, and that every file exists.

Exits 0 when everything holds; otherwise prints what did not and exits 1.
"""
import os
import struct
import sys
import xml.etree.ElementTree as ET
import zlib

VTK_VERTEX, VTK_TETRA = 1, 10
FORMATS = {"Float32": "f", "Int64": "q", "UInt8": "B", "UInt32": "I"}
# the data arrays an EXPECTED file may hold: type and components
DATA_ARRAYS = {"agent_id": ("UInt32", 1), "id": ("UInt32", 1), "phase": ("UInt8", 1),
               "velocity": ("Float32", 3), "orient": ("Float32", 4), "group": ("UInt8", 1)}
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
    return cond


def split_appended(raw):
    """The XML with the raw AppendedData bytes cut out (they are not XML), and those bytes."""
    start = raw.index(b'<AppendedData encoding="raw">')
    underscore = raw.index(b"_", start)
    end = raw.rindex(b"</AppendedData>")
    data = raw[underscore + 1:end]
    text = raw[:underscore] + raw[end:]
    return ET.fromstring(text), data


def raw_block(name, data, offset):
    """A raw array at offset: its values' bytes and where it ends."""
    (nbytes,) = struct.unpack_from("<Q", data, offset)
    return data[offset + 8:offset + 8 + nbytes], offset + 8 + nbytes


def compressed_block(name, data, offset):
    """A compressed array at offset (vtkZLibDataCompressor, UInt64 header): its values' bytes,
    inflated block by block, and where it ends; every size in the header is checked."""
    blocks, block_size, last_size = struct.unpack_from("<3Q", data, offset)
    sizes = struct.unpack_from("<%dQ" % blocks, data, offset + 24)
    at, values = offset + 24 + 8 * blocks, []
    for b, size in enumerate(sizes):
        want = last_size if b == blocks - 1 and last_size else block_size
        z = zlib.decompressobj()
        out = z.decompress(data[at:at + size])
        check(z.eof and not z.unused_data and len(data[at:at + size]) == size,
              f"{name}: block {b} is not one zlib stream of {size} bytes")
        check(len(out) == want, f"{name}: block {b} inflates to {len(out)} bytes, the header says {want}")
        values.append(out)
        at += size
    check(last_size < block_size, f"{name}: last block size {last_size} not below the block size {block_size}")
    return b"".join(values), at


def read_arrays(root, data, compressed):
    """Every DataArray by name: its values (a flat tuple) and components; checks the blocks."""
    arrays, spans = {}, []
    for da in root.iter("DataArray"):
        name, kind = da.get("Name"), da.get("type")
        check(da.get("format") == "appended", f"{name}: format {da.get('format')}")
        check(kind in FORMATS, f"{name}: type {kind}")
        offset = int(da.get("offset"))
        values, end = (compressed_block if compressed else raw_block)(name, data, offset)
        fmt = "<%d%s" % (len(values) // struct.calcsize(FORMATS[kind]), FORMATS[kind])
        check(struct.calcsize(fmt) == len(values), f"{name}: {len(values)} bytes is not whole values")
        arrays[name] = (struct.unpack_from(fmt, values), int(da.get("NumberOfComponents", "1")))
        spans.append((offset, end))
    spans.sort()
    check(spans and spans[0][0] == 0, "the first block does not start at offset 0")
    for (a0, a1), (b0, b1) in zip(spans, spans[1:]):
        check(a1 == b0, f"blocks [{a0}, {a1}) and [{b0}, {b1}) leave a gap or overlap")
    # after the last block only the whitespace before </AppendedData>, which VTK ignores
    tail = data[spans[-1][1]:] if spans else data
    check(tail.strip(b" \n") == b"", f"{len(tail)} bytes after the last block are not whitespace")
    return arrays


def section_names(root, tag):
    sec = root.find(f"./UnstructuredGrid/Piece/{tag}")
    return [] if sec is None else [da.get("Name") for da in sec.iter("DataArray")]


def floats_equal_bits(a, b):
    return struct.pack("<%df" % len(a), *a) == struct.pack("<%df" % len(b), *b)


def check_vtu(path, expected_path, kind, names, compressed):
    raw = open(path, "rb").read()
    root, data = split_appended(raw)
    check(root.tag == "VTKFile" and root.get("type") == "UnstructuredGrid", "not an UnstructuredGrid")
    check(root.get("header_type") == "UInt64" and root.get("byte_order") == "LittleEndian", "header")
    want_compressor = "vtkZLibDataCompressor" if compressed else None
    check(root.get("compressor") == want_compressor, f"compressor {root.get('compressor')}, expected {want_compressor}")
    piece = root.find("./UnstructuredGrid/Piece")
    n = int(piece.get("NumberOfCells"))
    per_cell = 4 if kind == "tets" else 1
    check(int(piece.get("NumberOfPoints")) == per_cell * n, "NumberOfPoints")
    arrays = read_arrays(root, data, compressed)
    points, comps = arrays["Points"]
    check(comps == 3 and len(points) == 3 * per_cell * n, f"{len(points)} coordinates for {n} cells")
    check(arrays["connectivity"][0] == tuple(range(per_cell * n)), "connectivity is not 0, 1, 2, ...")
    check(arrays["offsets"][0] == tuple(per_cell * (i + 1) for i in range(n)), "offsets")
    cell_type = VTK_TETRA if kind == "tets" else VTK_VERTEX
    check(arrays["types"][0] == (cell_type,) * n, f"cell types are not all {cell_type}")

    section = "CellData" if kind == "tets" else "PointData"
    have = section_names(root, section)
    check(sorted(have) == sorted(names), f"{section} holds {have}, expected {names}")
    expected = open(expected_path, "rb").read()
    at = 4 * 3 * per_cell * n
    want_points = struct.unpack_from("<%df" % (3 * per_cell * n), expected, 0)
    check(floats_equal_bits(points, want_points), "the coordinates differ from the cache's")
    for name in names:
        kind_name, comps = DATA_ARRAYS[name]
        fmt = "<%d%s" % (comps * n, FORMATS[kind_name])
        want = struct.unpack_from(fmt, expected, at)
        at += struct.calcsize(fmt)
        if not check(name in arrays, f"no {name} array"):
            continue
        got, got_comps = arrays[name]
        check(got_comps == comps, f"{name}: {got_comps} components, expected {comps}")
        same = floats_equal_bits(got, want) if kind_name == "Float32" else got == want
        check(same, f"{name} differs from the expected values")
    check(at == len(expected), f"EXPECTED holds {len(expected)} bytes, the arrays named {at}")
    if kind == "tets":
        check_tet_point_ids(root, arrays, expected, names, n)


def check_tet_point_ids(root, arrays, expected, names, n):
    """Tets: PointData is `id` alone, 4 agent_id + j for vertex j of each tet: unique per point."""
    have = section_names(root, "PointData")
    check(have == ["id"], f"the tets' PointData holds {have}, expected ['id']")
    agent_ids = tuple(range(n))
    if "agent_id" in names:
        at = 4 * 12 * n + sum(struct.calcsize("<%d%s" % (DATA_ARRAYS[m][1] * n, FORMATS[DATA_ARRAYS[m][0]]))
                              for m in names[:names.index("agent_id")])
        agent_ids = struct.unpack_from("<%dI" % n, expected, at)
    want = tuple(4 * a + j for a in agent_ids for j in range(4))
    got = arrays.get("id", ((), 1))[0]
    check(got == want, "the tets' point ids are not 4 agent_id + 0 ... 3")
    check(len(set(got)) == len(got), "the tets' point ids are not unique")


def check_pvd(path, rate, frames):
    root = ET.parse(path).getroot()
    check(root.tag == "VTKFile" and root.get("type") == "Collection", "not a Collection")
    sets = root.findall("./Collection/DataSet")
    check(len(sets) == len(frames), f"{len(sets)} data sets for {len(frames)} frames")
    stem = os.path.splitext(os.path.basename(path))[0]
    for ds, k in zip(sets, frames):
        name = f"{stem}_{k:05d}.vtu"
        check(ds.get("file") == name, f"frame {k}: file {ds.get('file')}, expected {name}")
        check(float(ds.get("timestep")) == k / rate, f"frame {k}: timestep {ds.get('timestep')}")
        check(os.path.isfile(os.path.join(os.path.dirname(path), ds.get("file"))), f"{name} is missing")


def main(argv):
    try:
        if len(argv) >= 5 and argv[1] in ("vtu", "vtu-raw") and argv[4] in ("tets", "points") and \
                set(argv[5:]) <= set(DATA_ARRAYS):
            check_vtu(argv[2], argv[3], argv[4], argv[5:], argv[1] == "vtu")
        elif len(argv) >= 4 and argv[1] == "pvd":
            check_pvd(argv[2], float(argv[3]), [int(k) for k in argv[4:]])
        else:
            print(__doc__, file=sys.stderr)
            return 2
    except (OSError, ET.ParseError, ValueError, KeyError, struct.error, zlib.error) as e:
        failures.append(f"{type(e).__name__}: {e}")
    for f in failures:
        print(f"{argv[2]}: {f}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
