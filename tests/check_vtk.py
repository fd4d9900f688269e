#!/usr/bin/env python3
"""Checks flockmorph's VTK output with Python's xml module alone (run by the export tests, tests/cli/test_export_cli.c).

  check_vtk.py vtu FILE.vtu EXPECTED tets|points
      EXPECTED holds little-endian raw values: tets: 12n f32 vertices, n u32 ids;
      points: 3n f32 positions, 3n f32 velocities, n u32 ids; then, if the file has a phase
      array, n u8 phases.
      Checks the header, that the appended blocks tile the data, the point count, the cell
      types, offsets and connectivity, and decodes the coordinates and arrays bit for bit.
  check_vtk.py pvd FILE.pvd FRAME_RATE FRAME...
      Checks that the collection lists DIR/<stem>_<frame, 5 digits>.vtu for exactly these frames,
      in order, each at timestep frame / FRAME_RATE, and that every file exists.

Exits 0 when everything holds; otherwise prints what did not and exits 1.
"""
import os
import struct
import sys
import xml.etree.ElementTree as ET

VTK_VERTEX, VTK_TETRA = 1, 10
FORMATS = {"Float32": "f", "Int64": "q", "UInt8": "B", "UInt32": "I"}
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


def read_arrays(root, data):
    """Every DataArray by name: its values (a flat tuple) and components; checks the blocks."""
    arrays, spans = {}, []
    for da in root.iter("DataArray"):
        name, kind = da.get("Name"), da.get("type")
        check(da.get("format") == "appended", f"{name}: format {da.get('format')}")
        check(kind in FORMATS, f"{name}: type {kind}")
        offset = int(da.get("offset"))
        (nbytes,) = struct.unpack_from("<Q", data, offset)
        fmt = "<%d%s" % (nbytes // struct.calcsize(FORMATS[kind]), FORMATS[kind])
        check(struct.calcsize(fmt) == nbytes, f"{name}: {nbytes} bytes is not whole values")
        arrays[name] = (struct.unpack_from(fmt, data, offset + 8), int(da.get("NumberOfComponents", "1")))
        spans.append((offset, offset + 8 + nbytes))
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


def check_vtu(path, expected_path, kind):
    raw = open(path, "rb").read()
    root, data = split_appended(raw)
    check(root.tag == "VTKFile" and root.get("type") == "UnstructuredGrid", "not an UnstructuredGrid")
    check(root.get("header_type") == "UInt64" and root.get("byte_order") == "LittleEndian", "header")
    piece = root.find("./UnstructuredGrid/Piece")
    n = int(piece.get("NumberOfCells"))
    per_cell = 4 if kind == "tets" else 1
    check(int(piece.get("NumberOfPoints")) == per_cell * n, "NumberOfPoints")
    arrays = read_arrays(root, data)
    points, comps = arrays["Points"]
    check(comps == 3 and len(points) == 3 * per_cell * n, f"{len(points)} coordinates for {n} cells")
    check(arrays["connectivity"][0] == tuple(range(per_cell * n)), "connectivity is not 0, 1, 2, ...")
    check(arrays["offsets"][0] == tuple(per_cell * (i + 1) for i in range(n)), "offsets")
    cell_type = VTK_TETRA if kind == "tets" else VTK_VERTEX
    check(arrays["types"][0] == (cell_type,) * n, f"cell types are not all {cell_type}")

    expected = open(expected_path, "rb").read()
    nf = 3 * per_cell * n
    want_points = struct.unpack_from("<%df" % nf, expected, 0)
    check(floats_equal_bits(points, want_points), "the coordinates differ from the cache's")
    if kind == "tets":
        check(section_names(root, "CellData")[:1] == ["agent_id"], "CellData does not start with agent_id")
        want_ids = struct.unpack_from("<%dI" % n, expected, 4 * nf)
        check(arrays["agent_id"][0] == want_ids, "agent_id differs")
        phase_at = 4 * nf + 4 * n
    else:
        check({"id", "velocity"} <= set(section_names(root, "PointData")), "PointData lacks id or velocity")
        want_v = struct.unpack_from("<%df" % (3 * n), expected, 4 * nf)
        want_ids = struct.unpack_from("<%dI" % n, expected, 4 * nf + 12 * n)
        check(arrays["velocity"][1] == 3 and floats_equal_bits(arrays["velocity"][0], want_v), "velocity differs")
        check(arrays["id"][0] == want_ids, "id differs")
        phase_at = 4 * nf + 16 * n
    if "phase" in arrays:
        check(arrays["phase"][0] == struct.unpack_from("<%dB" % n, expected, phase_at), "phase differs")


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
        if len(argv) == 5 and argv[1] == "vtu" and argv[4] in ("tets", "points"):
            check_vtu(argv[2], argv[3], argv[4])
        elif len(argv) >= 4 and argv[1] == "pvd":
            check_pvd(argv[2], float(argv[3]), [int(k) for k in argv[4:]])
        else:
            print(__doc__, file=sys.stderr)
            return 2
    except (OSError, ET.ParseError, ValueError, KeyError, struct.error) as e:
        failures.append(f"{type(e).__name__}: {e}")
    for f in failures:
        print(f"{argv[2]}: {f}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
