#!/usr/bin/env python3
"""Tests python/flockmorph_cache.py against the C reader.

Runs small scenes through the flockmorph CLI (a cache of whole frames, and one with delta encoding
and quantisation), then compares every frame of every attribute the module returns with the bytes the
C reader decodes (tests/cache_dump.c) and its metadata with `flockmorph inspect --json`, through
read() and through the sequence API (len, iteration, cache[k], slices, Frame attributes by name,
read_range, times). Also reads the committed format-1 fixture, a cache cut short (recovery with a
warning), a flipped byte (checksum error) and files that are not caches, and checks that frame
numbers and names of the wrong type are TypeErrors. tests/python/test_package.py tests the pip
install.

    test_reader.py --cli build/flockmorph --dump build/tests/cache_dump --tmp DIR --source REPO
"""
import argparse
import json
import os
import random
import shutil
import subprocess
import struct
import sys
import unittest
import warnings
import zlib

import numpy as np

ARGS = None
AGENTS = 150
fmc = None  # the module under test, imported from --source/python


def run(*cmd):
    done = subprocess.run([str(c) for c in cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        raise AssertionError(f"{' '.join(map(str, cmd))}: exit {done.returncode}\n{done.stdout}\n{done.stderr}")
    return done.stdout


def tmp(name):
    return os.path.join(ARGS.tmp, "py_" + name)


def write_octahedron(path):
    with open(path, "w") as f:
        f.write("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n")
        for s in range(8):  # one face per octant; a reflection reverses the winding
            x, y, z = (2 if s & 1 else 1), (4 if s & 2 else 3), (6 if s & 4 else 5)
            odd = ((s & 1) + (s >> 1 & 1) + (s >> 2 & 1)) & 1
            f.write(f"f {x} {z if odd else y} {y if odd else z}\n")


def run_scene(name, output, agents=AGENTS):
    """Runs the octahedron from x = -10 to x = +10 with the given "output" keys; the cache path."""
    write_octahedron(tmp("octahedron.obj"))
    scene = {"source": {"mesh": "py_octahedron.obj", "translate": [-10, 0, 0]},
             "target": {"mesh": "py_octahedron.obj", "translate": [10, 0, 0]},
             "n": agents, "output": output}
    with open(tmp(name + ".json"), "w") as f:
        json.dump(scene, f)
    outdir = tmp(name + "_out")
    run(ARGS.cli, "run", tmp(name + ".json"), "-o", outdir, "--quiet")
    return os.path.join(outdir, "frames.fmc")


def c_frames(path, cache):
    """Every frame's attributes as the C reader decodes them: {(frame, name): array}."""
    dump = path + ".dump"
    run(ARGS.dump, path, dump)
    raw = np.fromfile(dump, dtype=np.uint8)
    out, at = {}, 0
    for k in range(cache.frames):
        for name in cache.attributes:
            _, components, scalar = next(v for v in fmc.ATTRIBUTES.values() if v[0] == name)
            dtype = fmc._DTYPES[scalar]
            n = cache.agents * components * dtype.itemsize
            out[k, name] = raw[at:at + n].view(dtype).reshape(cache.agents, components)
            at += n
    assert at == raw.size, f"{dump}: {raw.size} bytes, expected {at}"
    return out


def inspect(path):
    return json.loads(run(ARGS.cli, "inspect", path, "--json"))


def frame_number_calls(cache):
    """Every way a frame number reaches the module, by name."""
    return {"read": lambda k: cache.read(k, "phase"), "cache[k]": lambda k: cache[k], "time": cache.time,
            "frame_bytes": cache.frame_bytes}


class MatchesC:
    """Checks of a whole cache against the C reader, for the test cases that read caches."""

    def assert_matches_c(self, path):
        """Metadata as inspect reports it, and every frame bitwise equal to the C reader's, read in
        order and again in a shuffled order (random access, across key intervals)."""
        info = inspect(path)
        with fmc.open(path) as cache:
            self.assertEqual(cache.version, info["format_version"])
            self.assertEqual(cache.agents, info["agents"])
            self.assertEqual(cache.frames, info["frames"])
            self.assertEqual(cache.header_frames, info["header_frames"] or 0)
            self.assertEqual(cache.frame_rate, info["frame_rate"])
            self.assertEqual(cache.attributes, [a["name"] for a in info["attributes"]])
            self.assertEqual(cache.options, info["options"])
            self.assertEqual((cache.file_bytes, cache.raw_bytes, cache.compressed_bytes),
                             (info["file_bytes"], info["raw_bytes"], info["compressed_bytes"]))
            self.assertEqual(cache.complete, info["complete"])
            want = c_frames(path, cache)
            order = [(k, n) for k in range(cache.frames) for n in cache.attributes]
            shuffled = order[:]
            random.Random(7).shuffle(shuffled)
            for k, name in order + shuffled:
                got = cache.read(k, name)
                expect = want[k, name]
                self.assertEqual(got.dtype, expect.dtype, name)
                self.assertEqual(got.shape, (cache.agents, 4, 3) if name == "tet_vertices" else expect.shape)
                self.assertTrue(np.array_equal(got.reshape(expect.shape).view(np.uint8), expect.view(np.uint8)),
                                f"{path}: frame {k} {name} differs from the C reader")
            self.assert_sequence_matches_c(cache, want, info)
            b = info["bounds"]["tet_vertices"]
            if cache.frames == 0:
                self.assertIsNone(cache.bounds())
                self.assertIsNone(b)
                return cache
            lo, hi = cache.bounds()
            np.testing.assert_allclose(lo, b["min"], rtol=1e-6)
            np.testing.assert_allclose(hi, b["max"], rtol=1e-6)
            return cache

    def assert_same(self, got, expect, what):
        """got (the module's shape) bitwise equal to expect (the C reader's (agents, components))."""
        self.assertEqual(got.dtype, expect.dtype, what)
        self.assertTrue(np.array_equal(got.reshape(expect.shape).view(np.uint8), expect.view(np.uint8)),
                        f"{what} differs from the C reader")

    def assert_sequence_matches_c(self, cache, want, info):
        """len, iteration, cache[k], slices, range reads and frame times against the C reader's
        frames and inspect's duration."""
        self.assertEqual(len(cache), info["frames"])
        shapes = {n: cache.read(0, n).shape for n in cache.attributes} if cache.frames else {}
        frames = list(cache)
        self.assertEqual([f.index for f in frames], list(range(cache.frames)))
        for f in frames:
            self.assertEqual((list(f), len(f), f.time), (cache.attributes, len(cache.attributes),
                                                          f.index / cache.frame_rate))
            for name in reversed(cache.attributes):  # each attribute alone, not in the file's order
                self.assertIn(name, f)
                self.assert_same(getattr(f, name), want[f.index, name], f"frame {f.index}.{name}")
                self.assertIs(f[name], getattr(f, name))  # decoded once, then kept
        if cache.frames:
            self.assertEqual((cache[-1].index, cache[0]), (cache.frames - 1, frames[0]))
        n = cache.frames
        for key in (slice(None), slice(1, None, 2), slice(-3, None), slice(None, None, -1),
                    slice(2, n + 100), slice(n - 1, 2, -3), slice(5, 2), slice(-n - 9, 1)):
            ks = list(range(*key.indices(n)))
            self.assertEqual([f.index for f in cache[key]], ks, key)
            for name in cache.attributes:
                block = cache.read_range(name, key.start, key.stop, key.step)
                self.assertEqual(block.shape[0], len(ks))
                if ks:
                    self.assertEqual(block.shape[1:], shapes[name])
                for j, k in enumerate(ks):
                    self.assert_same(block[j], want[k, name], f"read_range({name!r}, {key}) row {j} (frame {k})")
        self.assertEqual(cache.read_range(cache.attributes[0]).shape[:2], (n, cache.agents))
        times = cache.times()
        self.assertEqual((times.dtype, times.shape), (np.float64, (n,)))
        self.assertTrue(np.array_equal(times, np.arange(n) / cache.frame_rate))
        if n:
            self.assertEqual((cache.time(0), cache.time(-1)), (0.0, times[-1]))
        if n >= 2:
            self.assertAlmostEqual(times[-1] - times[0], info["duration_seconds"], places=9)



class CacheCase(MatchesC, unittest.TestCase):
    lossless = compact = pieces = None

    @classmethod
    def setUpClass(cls):
        if CacheCase.lossless is None:
            CacheCase.lossless = run_scene("lossless", {"delta": False})
            CacheCase.compact = run_scene("compact", {"delta": True, "key_interval": 5, "quantum": 0.001,
                                                      "compression_level": -3})
            # four pieces, the last one of 232 agents (format 4: each piece shuffled and compressed on its own)
            CacheCase.pieces = run_scene("pieces", {"delta": True, "key_interval": 3, "quantum": 0.001,
                                                    "piece_agents": 256}, agents=1000)

    def test_lossless_run(self):
        cache = self.assert_matches_c(self.lossless)
        self.assertEqual(cache.attributes, ["tet_vertices", "id", "phase"])
        self.assertEqual((cache.version, cache.header_frames), (4, cache.frames))
        with fmc.open(self.lossless) as c:
            self.assertTrue((c.read(0, "phase") == 0).all() and (c.read(-1, "phase") == 3).all())
            self.assertEqual(c.read(c.frames // 2, "id").dtype, np.uint32)
            self.assertEqual(c.read(c.frames // 2, "id").reshape(-1).tolist(), list(range(AGENTS)))
            self.assertGreater(c.bounds()[1][0] - c.bounds()[0][0], 20)

    def test_delta_and_quantum_run(self):
        self.assert_matches_c(self.compact)
        with fmc.open(self.lossless) as a, fmc.open(self.compact) as b:
            self.assertEqual(b.options, {"compression_level": -3, "delta": True, "key_interval": 5, "quantum": 0.001,
                                         "piece_agents": 65536})
            worst = max(np.abs(a.read(k, "tet_vertices") - b.read(k, "tet_vertices")).max() for k in range(a.frames))
            self.assertLessEqual(worst, 0.0005 + 1e-6)
            self.assertGreater(worst, 0.0002)  # the values really were rounded

    def test_pieces_run(self):
        cache = self.assert_matches_c(self.pieces)
        self.assertEqual(cache.options["piece_agents"], 256)
        with fmc.open(self.pieces) as c:
            self.assertEqual(c.read(c.frames // 2, "id").reshape(-1).tolist(), list(range(1000)))

    def test_recovers_a_cut_cache(self):
        with open(self.compact, "rb") as f:
            data = f.read()
        cut = tmp("cut.fmc")
        for size in (len(data) - 1, len(data) // 2, 200):
            with open(cut, "wb") as f:
                f.write(data[:size])
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                cache = fmc.open(cut)
            self.assertEqual(len(caught), 1)
            self.assertIn("recovered", str(caught[0].message))
            self.assertIn(cut, str(caught[0].message))
            self.assertFalse(cache.complete)
            cache.close()
            self.assert_matches_c(cut)

    def test_header_frame_count(self):
        """A header count other than the index's is refused; 0 (the writer did not finish) recovers."""
        with open(self.compact, "rb") as f:
            data = bytearray(f.read())
        frames = struct.unpack_from("<I", data, 64)[0]
        self.assertGreater(frames, 5)
        bad = tmp("count.fmc")
        for count in (frames + 1, frames - 1, 0):
            struct.pack_into("<I", data, 64, count)
            struct.pack_into("<I", data, 52, 0)  # the crc field is 0 while the crc is computed
            struct.pack_into("<I", data, 52, zlib.crc32(data[:struct.unpack_from("<I", data, 12)[0]]))
            with open(bad, "wb") as f:
                f.write(data)
            if count:
                with self.assertRaisesRegex(ValueError, f"the header says {count} frames but the index lists {frames}"):
                    fmc.open(bad)
                continue
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                with fmc.open(bad) as cache:
                    self.assertEqual((cache.frames, cache.header_frames, cache.complete), (frames, 0, False))
            self.assertIn("frame count 0 in the header", str(caught[0].message))
            self.assert_matches_c(bad)

    def test_flipped_byte_fails_its_checksum(self):
        with open(self.lossless, "rb") as f:
            data = bytearray(f.read())
        with fmc.open(self.lossless) as c:
            start = c._offsets[1] + 24 + 8 * len(c.attributes)  # the first block's data
        data[start + 16] ^= 0x04
        bad = tmp("flipped.fmc")
        with open(bad, "wb") as f:
            f.write(data)
        with fmc.open(bad) as c:
            with self.assertRaisesRegex(ValueError, "chunk 1: checksum mismatch") as e:
                c.read(1, "tet_vertices")
            self.assertIn(bad, str(e.exception))
            c.read(0, "tet_vertices")
            c.read(2, "phase")

    def test_bad_arguments(self):
        with fmc.open(self.lossless) as c:
            with self.assertRaisesRegex(IndexError, "frame 100000 does not exist"):
                c.read(100000, "phase")
            with self.assertRaisesRegex(KeyError, "no 'velocity' attribute"):
                c.read(0, "velocity")

    def test_frames_out_of_range(self):
        """IndexError naming the file and the frames there are, wherever a frame number is taken."""
        with fmc.open(self.lossless) as c:
            n = c.frames
            calls = frame_number_calls(c)
            for what, call in calls.items():
                for k in (n, -n - 1, 10 ** 12):
                    with self.assertRaises(IndexError, msg=f"{what}({k})") as e:
                        call(k)
                    self.assertEqual(str(e.exception), f"{self.lossless}: frame {k} does not exist (the cache "
                                     f"has {n} frames: 0 to {n - 1}, or -{n} to -1 from the end)")
            self.assertEqual(c[-n].index, 0)

    def test_strict_argument_types(self):
        """Frame numbers are ints (Python or numpy), never floats, bools or strings; names are str."""
        with fmc.open(self.lossless) as c:
            want = c.read(1, "phase")
            for good in (1, np.int64(1), np.uint8(1), np.int32(1 - c.frames) + c.frames):
                self.assertTrue(np.array_equal(c.read(good, "phase"), want), repr(good))
                self.assertEqual(c[good].index, 1)
            calls = frame_number_calls(c)
            for bad in (1.5, 1.0, True, False, np.True_, np.float32(1), "3", b"3", None, [1]):
                for what, call in calls.items():
                    message = ("takes a frame number or a slice, not the str" if what == "cache[k]" and isinstance(bad, str)
                               else "frame must be an int, not")
                    with self.assertRaisesRegex(TypeError, message, msg=f"{what}({bad!r})") as e:
                        call(bad)
                    self.assertIn(self.lossless, str(e.exception))
            for key in (slice(1.5, 3), slice(True, None), slice(0, 2.0), slice(None, None, np.True_), slice("1", 2)):
                with self.assertRaisesRegex(TypeError, "a slice bound must be an int"):
                    c[key]
                with self.assertRaisesRegex(TypeError, "a slice bound must be an int"):
                    c.read_range("phase", key.start, key.stop, key.step)
            with self.assertRaisesRegex(ValueError, "slice step cannot be zero"):
                c.read_range("phase", 0, 2, 0)
            for bad in (5, b"phase", None, ["phase"]):
                calls = [lambda: c.read(0, bad), lambda: c.read_range(bad), lambda: c[0][bad]]
                if bad is not None:  # bounds(None): the default attribute
                    calls.append(lambda: c.bounds(bad))
                for call in calls:
                    with self.assertRaisesRegex(TypeError, "attribute name must be a str"):
                        call()
            with self.assertRaisesRegex(TypeError, r"takes a frame number or a slice.*read_range\('phase'\)"):
                c["phase"]

    def test_frame_attributes_by_name(self):
        with fmc.open(self.lossless) as c:
            f = c[2]
            self.assertEqual(set(f.keys()), {"tet_vertices", "id", "phase"})
            self.assertEqual(f.id.reshape(-1).tolist(), list(range(AGENTS)))
            self.assertEqual(f.tet_vertices.shape, (AGENTS, 4, 3))
            self.assertFalse(hasattr(f, "velocity"))
            self.assertNotIn("velocity", f)
            with self.assertRaisesRegex(AttributeError, "frame 2 has no 'velocity' attribute"):
                f.velocity
            with self.assertRaisesRegex(KeyError, "no 'velocity' attribute"):
                f["velocity"]
            with self.assertRaisesRegex(AttributeError, "no attribute 'positon'"):
                f.positon
            self.assertEqual(dict(f.items()).keys(), f.keys())
            self.assertNotEqual(c[2], c[3])
            self.assertEqual(len({c[2], c[2], c[3]}), 2)
            self.assertIn(f"Frame 2 of {self.lossless!r}", repr(f))
            kept, unread = f.phase, c[3]
        self.assertTrue(c.closed)
        self.assertIs(f.phase, kept)  # what was read stays
        with self.assertRaisesRegex(ValueError, f"{self.lossless}: the cache is closed"):
            unread.id
        with self.assertRaisesRegex(ValueError, "the cache is closed"):
            c.read(2, "phase")  # the kept chunk would answer: refused all the same


class FormatOne(unittest.TestCase):
    """tests/data/cache_v1.fmc: 5 agents, 3 frames at 24 fps, float i of frame f = 0.001 i + f."""

    def test_reads_the_fixture(self):
        path = os.path.join(ARGS.source, "tests", "data", "cache_v1.fmc")
        with fmc.open(path) as c:
            self.assertEqual((c.version, c.agents, c.frames, c.frame_rate), (1, 5, 3, 24.0))
            self.assertEqual(c.attributes, ["tet_vertices"])
            for k in (2, 0, 1):
                want = (0.001 * np.arange(60) + k).astype(np.float32).reshape(5, 4, 3)
                self.assertTrue(np.array_equal(c.read(k, "tet_vertices"), want))

    def test_zstd_checksum_catches_a_flip(self):
        path = os.path.join(ARGS.source, "tests", "data", "cache_v1.fmc")
        with open(path, "rb") as f:
            data = bytearray(f.read())
        with fmc.open(path) as c:
            start = c._offsets[1]
        data[start + 24 + 12] ^= 0x20
        bad = tmp("v1_flipped.fmc")
        with open(bad, "wb") as f:
            f.write(data)
        with fmc.open(bad) as c:
            with self.assertRaisesRegex(ValueError, "frame 1 is corrupt"):
                c.read(1, "tet_vertices")


class FormatTwo(MatchesC, unittest.TestCase):
    """tests/data/cache_v2.fmc: 5 agents, 4 frames at 24 fps, tet_vertices (float i of frame f =
    0.001 i + f) and phase ((a + f) mod 4), delta with key interval 2, level 3."""

    def test_reads_the_fixture(self):
        path = os.path.join(ARGS.source, "tests", "data", "cache_v2.fmc")
        with fmc.open(path) as c:
            self.assertEqual((c.version, c.agents, c.frames, c.header_frames, c.complete), (2, 5, 4, 0, True))
            self.assertEqual(c.options, {"compression_level": 3, "delta": True, "key_interval": 2, "quantum": 0.0})
            for k in (3, 0, 2, 1, 3):
                want = (0.001 * np.arange(60) + k).astype(np.float32).reshape(5, 4, 3)
                self.assertTrue(np.array_equal(c.read(k, "tet_vertices"), want))
                self.assertEqual(c.read(k, "phase").reshape(-1).tolist(), [(a + k) % 4 for a in range(5)])
        copy = tmp("v2.fmc")  # the C reader's dump goes next to the file, not into the source tree
        shutil.copyfile(path, copy)
        self.assertIsNone(inspect(copy)["header_frames"])
        self.assert_matches_c(copy)


class NotACache(unittest.TestCase):
    def expect_error(self, content, message):
        path = tmp("bad.fmc")
        with open(path, "wb") as f:
            f.write(content)
        with self.assertRaisesRegex(ValueError, message) as e:
            fmc.open(path)
        self.assertIn(path, str(e.exception))

    def test_bad_files(self):
        self.expect_error(b'{"agents": 5}\n' + b"x" * 100, "not a flockmorph cache")
        self.expect_error(b"", "shorter than the cache header")
        self.expect_error(b"FMCACHE1" + bytes([9, 0, 0, 0]) + bytes(52), "cache version 9 is not supported")
        with open(CacheCase.lossless or run_scene("lossless", {"delta": False}), "rb") as f:
            header = bytearray(f.read(72 + 3 * 16))
        header[20] ^= 1
        self.expect_error(bytes(header), "header checksum mismatch")

    def test_not_regular_files(self):
        """A FIFO (a read would wait for a writer), /dev/zero (never ends) and a directory are refused
        at once, without blocking."""
        fifo, folder = tmp("fifo.fmc"), tmp("folder.fmc")
        if os.path.lexists(fifo):
            os.remove(fifo)
        os.mkfifo(fifo)
        os.makedirs(folder, exist_ok=True)
        try:
            for path, kind in ((fifo, "a FIFO"), ("/dev/zero", "a device"), (folder, "a directory")):
                with self.assertRaisesRegex(ValueError, f"{path}: cannot open the cache: it is {kind}"):
                    fmc.open(path)
        finally:
            os.remove(fifo)

    def test_agents_beyond_file(self):
        """A header claiming 2^38 agents (crc32 matching) in a small cache is refused at open, before
        a frame is allocated."""
        with open(CacheCase.lossless or run_scene("lossless", {"delta": False}), "rb") as f:
            data = bytearray(f.read())
        size = struct.unpack_from("<I", data, 12)[0]
        struct.pack_into("<Q", data, 16, 1 << 38)
        struct.pack_into("<I", data, 52, 0)  # the crc field is 0 while the crc is computed
        struct.pack_into("<I", data, 52, zlib.crc32(data[:size]))
        self.expect_error(bytes(data), f"frames of {1 << 38} agents cannot come from a file of {len(data)} bytes")
        with self.assertRaisesRegex(ValueError, "no such file"):
            fmc.open(tmp("no_such.fmc"))


def main():
    global ARGS, fmc
    parser = argparse.ArgumentParser()
    for opt in ("--cli", "--dump", "--tmp", "--source"):
        parser.add_argument(opt, required=True)
    ARGS, rest = parser.parse_known_args()
    os.makedirs(ARGS.tmp, exist_ok=True)
    sys.path.insert(0, os.path.join(ARGS.source, "python"))
    import flockmorph_cache
    fmc = flockmorph_cache
    assert shutil.which(ARGS.cli) or os.path.exists(ARGS.cli), ARGS.cli
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
