"""Reads flockmorph frame caches (.fmc, formats 1 to 4; docs/cache-format.md) into numpy arrays.

    import flockmorph_cache
    with flockmorph_cache.open("out/frames.fmc") as cache:
        print(len(cache), cache.agents, cache.frame_rate, cache.attributes)
        tets = cache.read(-1, "tet_vertices")                 # float32, shape (agents, 4, 3)
        for frame in cache[::10]:                             # Frame objects, read when asked
            print(frame.index, frame.time, frame.phase.max())  # attributes by name (or frame["phase"])
        ids = cache.read_range("id", 0, 50)                   # uint32, shape (50, agents, 1)
        t = cache.times()                                     # seconds, frame k at k / frame_rate
        lo, hi = cache.bounds()                               # over all frames

Frames are read by random access through the cache's index; every chunk's crc32 is checked
before it is decoded (format 1: zstd's own checksum). With delta encoding a frame is rebuilt from
the key frame before it, and the last decoded frame is kept, so reading frames in order decodes
one chunk each. A cache without a valid index, or (format 3) whose header still states 0 frames
(a run that was killed), is opened up to its last complete frame, with a warnings.warn. A file that
is not a valid cache, or whose header states another frame count than its index, raises ValueError
naming the file; a frame that does not exist raises IndexError, an attribute the cache lacks
KeyError, a frame number that is not an int (1.5, True, "3") or a name that is not a str TypeError.

Needs numpy and a zstd decoder: the zstandard module (Debian python3-zstandard) or, without it,
libzstd.so.1 through ctypes. Installs with `pip install ./python` (docs/cache-format.md), or is
used as this one file, copied or put on sys.path.
"""
import os
import stat
import struct
import warnings
import zlib
from collections.abc import Mapping

import numpy as np

try:
    import zstandard as _zstandard
except ImportError:  # pragma: no cover - exercised only where python3-zstandard is missing
    _zstandard = None

__all__ = ["open", "Cache", "Frame", "ATTRIBUTES"]

# The CMake project's version (project(flockmorph VERSION ...) in CMakeLists.txt), which
# pyproject.toml reads from here; tests/python/test_package.py checks that they agree.
__version__ = "0.1.0"

MAGIC = b"FMCACHE1"
END_MAGIC = b"FMCEND\0\0"
HEADER = 64  # the bytes every version starts with (all of format 1's header)
VERSION = 4
FIXED_HEADER = {2: 64, 3: 72, 4: 72}  # where the attribute records start
ATTR_RECORD = 16
CHUNK_HEADER = 24
FOOTER = 16
MAX_ATTRS = 6
MAX_KEY_INTERVAL = 1 << 16
MIN_PIECE, MAX_PIECE = 256, 1 << 30  # format 4: agents per piece
SHUFFLE4, DELTA, QUANTISE = 1, 2, 4
KEY_FRAME = 1

F32, U32, U8 = 1, 2, 3
_DTYPES = {F32: np.dtype("<f4"), U32: np.dtype("<u4"), U8: np.dtype("u1")}

# kind: (name, components, scalar type), as fm_cache_attr in include/flockmorph/flockmorph.h
ATTRIBUTES = {
    1: ("tet_vertices", 12, F32),
    2: ("position", 3, F32),
    3: ("velocity", 3, F32),
    4: ("orientation", 4, F32),
    5: ("id", 1, U32),
    6: ("phase", 1, U8),
    7: ("group", 1, U8),
}
_ATTRIBUTE_NAMES = frozenset(name for name, _, _ in ATTRIBUTES.values())


def _zstd_bound(n):
    """ZSTD_compressBound."""
    return n + (n >> 8) + ((((128 << 10) - n) >> 11) if n < (128 << 10) else 0)


class _Decompressor:
    """zstd through the zstandard module, or through libzstd with ctypes."""

    def __init__(self):
        if _zstandard is not None:
            self._d = _zstandard.ZstdDecompressor()
            return
        import ctypes
        import ctypes.util
        self._lib = ctypes.CDLL(ctypes.util.find_library("zstd") or "libzstd.so.1")
        self._lib.ZSTD_decompress.restype = ctypes.c_size_t
        self._lib.ZSTD_decompress.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, ctypes.c_size_t]
        self._lib.ZSTD_isError.argtypes = [ctypes.c_size_t]
        self._lib.ZSTD_getErrorName.restype = ctypes.c_char_p
        self._lib.ZSTD_getErrorName.argtypes = [ctypes.c_size_t]
        self._ctypes = ctypes
        self._d = None

    def __call__(self, data, size):
        """Decompresses one zstd frame of exactly `size` bytes; raises ValueError otherwise."""
        if self._d is not None:
            try:
                out = self._d.decompress(data, max_output_size=size)
            except _zstandard.ZstdError as e:
                raise ValueError(str(e)) from None
        else:
            c = self._ctypes
            buf = c.create_string_buffer(max(size, 1))
            src = c.create_string_buffer(bytes(data), len(data))
            got = self._lib.ZSTD_decompress(buf, size, src, len(data))
            if self._lib.ZSTD_isError(got):
                raise ValueError(self._lib.ZSTD_getErrorName(got).decode())
            out = buf.raw[:got]
        if len(out) != size:
            raise ValueError("wrong size")
        return out


def _expected_filters(scalar, delta, quantum):
    f = SHUFFLE4 if scalar != U8 else 0
    if delta:
        f |= DELTA
    if scalar == F32 and quantum > 0:
        f |= QUANTISE
    return f


class _Attr:
    def __init__(self, kind, filters, agents):
        self.kind = kind
        self.name, self.components, self.scalar = ATTRIBUTES[kind]
        self.filters = filters
        self.dtype = _DTYPES[self.scalar]
        self.per_agent = self.components * self.dtype.itemsize
        self.nbytes = agents * self.per_agent


def _int_arg(value, path, what):
    """value as an int, or TypeError naming the file. Python ints and numpy integers only: int()
    would truncate 1.5 and parse "3", and True is an int to Python but a frame number almost only
    by mistake (read(True, ...) reading frame 1 hides a bug)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{path}: {what} must be an int, not {type(value).__name__} {value!r}")
    return int(value)


def _str_arg(value, path, what="attribute name"):
    if not isinstance(value, str):
        raise TypeError(f"{path}: {what} must be a str, not {type(value).__name__} {value!r}")
    return value


def _open_regular(path):
    """The file opened for reading if it is a regular file; ValueError for a directory, a FIFO or a
    device (a FIFO would block the read until a writer comes, /dev/zero never ends). O_NONBLOCK
    so that opening a FIFO does not wait; fstat then says what was opened."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        kind = ("a directory" if stat.S_ISDIR(mode) else "a FIFO (named pipe)" if stat.S_ISFIFO(mode)
                else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
        raise ValueError(f"{path}: cannot open the cache: it is {kind}" + ("" if kind.startswith("not") else
                         ", not a regular file"))
    os.set_blocking(fd, True)
    return os.fdopen(fd, "rb")


class Frame(Mapping):
    """One frame of a cache, as cache[k], cache[a:b] and iteration give it: a read-only mapping
    from attribute name to array (frame["position"]), also by attribute (frame.position), with
    index (the frame number, 0 ... len(cache) - 1) and time (index / frame_rate, in seconds).

    An attribute is decoded when first asked for and then kept, so iterating over a cache and
    using one attribute decodes only that one. Its arrays are Cache.read's: new arrays the caller
    may change. Reading needs the cache still open; arrays read before close stay valid."""

    def __init__(self, cache, index):
        self.cache, self.index = cache, index
        self.time = index / cache.frame_rate
        self._arrays = {}

    def __getitem__(self, name):
        if _str_arg(name, self.cache.path) not in self._arrays:
            self._arrays[name] = self.cache.read(self.index, name)
        return self._arrays[name]

    def __getattr__(self, name):
        # Called only when ordinary lookup fails. Only the attribute names resolve, so a typo
        # (frame.posiiton) or a missing attribute is an AttributeError and hasattr() works. It
        # touches self.cache only for those names: copy and pickle probe a bare instance.
        if name not in _ATTRIBUTE_NAMES:
            raise AttributeError(f"'Frame' object has no attribute {name!r}")
        if name not in self.cache.attributes:
            raise AttributeError(f"{self.cache.path}: frame {self.index} has no {name!r} attribute "
                                 f"(the cache has {', '.join(self.cache.attributes)})")
        return self[name]

    def __iter__(self):
        return iter(self.cache.attributes)

    def __len__(self):
        return len(self.cache.attributes)

    def __contains__(self, name):
        # Mapping's default would read the attribute to find out
        return name in self.cache.attributes

    # Mapping compares values, and comparing numpy arrays has no single truth value: a frame is
    # equal to the same frame of the same open cache.
    def __eq__(self, other):
        return isinstance(other, Frame) and other.cache is self.cache and other.index == self.index

    def __hash__(self):
        return hash((id(self.cache), self.index))

    def __repr__(self):
        return f"<flockmorph_cache.Frame {self.index} of {self.cache.path!r} at {self.time:g} s>"


class Cache:
    """An open cache. Attributes: path, version, agents, frames, frame_rate, attributes (names),
    options (dict: compression_level, delta, key_interval, quantum), complete, warning (str or
    None), file_bytes, raw_bytes, compressed_bytes, header_frames (the frame count the format-3
    header states: 0 while the writer runs, and in formats 1 and 2)."""

    def __init__(self, path):
        self.path = str(path)
        try:
            self._f = _open_regular(self.path)
        except FileNotFoundError:
            raise ValueError(f"{self.path}: cannot open: no such file") from None
        except OSError as e:
            raise ValueError(f"{self.path}: cannot open: {e.strerror}") from None
        try:
            self._f.seek(0, 2)
            self.file_bytes = self._f.tell()
            self._read_header()
            self._read_index()
            self._check_plausible()
        except BaseException:
            self._f.close()
            raise
        self._zstd = _Decompressor()
        self._chunk_frame, self._chunk = -1, None
        self._words = {}  # attribute index -> (frame, stored words of that frame)

    # ------------------------------------------------------------ public

    def read(self, frame, name):
        """Attribute `name` of frame `frame` (an int; negative counts from the end) as a new numpy
        array of shape (agents, components), or (agents, 4, 3) for tet_vertices."""
        k, i = self._frame_number(frame), self._attr_index(name)
        return self._decode(k, i).reshape(self._shape(i))

    def read_range(self, name, start=None, stop=None, step=None):
        """Attribute `name` of the frames range(start, stop, step) selects, with slice semantics
        (None, negative and out-of-range bounds as in cache[start:stop:step]), as one new array of
        shape (frames, agents, components), or (frames, agents, 4, 3) for tet_vertices."""
        i = self._attr_index(name)
        frames = self._frame_range(slice(start, stop, step))
        out = np.empty((len(frames),) + self._shape(i), dtype=self._attrs[i].dtype)
        for j, k in enumerate(frames):
            out[j] = self._decode(k, i).reshape(self._shape(i))
        return out

    def time(self, frame):
        """Frame `frame`'s time in seconds: frame k lies at k / frame_rate, frame 0 at 0."""
        return self._frame_number(frame) / self.frame_rate

    def times(self):
        """Every frame's time in seconds (float64, shape (frames,)); times()[k] == time(k)."""
        return np.arange(self.frames) / self.frame_rate

    @property
    def closed(self):
        return self._f.closed

    def __len__(self):
        return self.frames

    def __iter__(self):
        for k in range(self.frames):
            yield Frame(self, k)

    def __getitem__(self, key):
        """cache[k]: frame k as a Frame (negative counts from the end); cache[a:b:s]: a list of
        Frames, with slice semantics."""
        if isinstance(key, slice):
            return [Frame(self, k) for k in self._frame_range(key)]
        if isinstance(key, str):  # a likely slip for an attribute: say where that is
            raise TypeError(f"{self.path}: cache[...] takes a frame number or a slice, not the str {key!r}; "
                            f"for an attribute over frames use read_range({key!r}) or cache[k][{key!r}]")
        return Frame(self, self._frame_number(key))

    def bounds(self, name=None):
        """(min, max), each float32 of shape (3,), of tet_vertices (or position) over all frames;
        None if the cache has no frames or no agents."""
        if name is not None:
            _str_arg(name, self.path)
        else:
            name = next((n for n in ("tet_vertices", "position") if n in self.attributes), None)
            if name is None:
                raise KeyError(f"{self.path}: the cache has neither tet_vertices nor position")
        lo = hi = None
        for k in range(self.frames):
            xyz = self.read(k, name).reshape(-1, 3)
            if xyz.size == 0:
                return None
            flo, fhi = np.nanmin(xyz, axis=0), np.nanmax(xyz, axis=0)
            lo = flo if lo is None else np.minimum(lo, flo)
            hi = fhi if hi is None else np.maximum(hi, fhi)
        return None if lo is None else (lo, hi)

    def frame_bytes(self, frame):
        """Bytes of the frame's chunk in the file."""
        return self._sizes[self._frame_number(frame)]

    def close(self):
        self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return (f"<flockmorph_cache.Cache {self.path!r}: format {self.version}, {self.agents} agents, "
                f"{self.frames} frames at {self.frame_rate:g} fps, {', '.join(self.attributes)}>")

    # ------------------------------------------------------------ header

    def _fail(self, what):
        raise ValueError(f"{self.path}: {what}")

    def _read_at(self, pos, n):
        self._f.seek(pos)
        data = self._f.read(n)
        if len(data) != n:
            self._fail(f"truncated or unreadable at byte {pos}")
        return data

    def _read_header(self):
        self._f.seek(0)
        h = self._f.read(HEADER)
        if h[:8] != MAGIC[:len(h[:8])]:
            self._fail("not a flockmorph cache (bad magic)")
        if len(h) < HEADER:
            self._fail(f"truncated: {len(h)} bytes, shorter than the cache header")
        self.version = struct.unpack_from("<I", h, 8)[0]
        self.header_frames = 0
        if self.version == 1:
            self._read_header_v1(h)
        elif self.version in FIXED_HEADER:
            self._read_header_attrs(h)
        else:
            self._fail(f"cache version {self.version} is not supported (this reader reads 1 to {VERSION})")
        if self.agents > 1 << 40:
            self._fail("implausible agent count")
        self.attributes = [a.name for a in self._attrs]

    def _read_header_v1(self, h):
        _, _, _, agents, floats, filt, codec, level, rate = struct.unpack_from("<8sIIQIIIId", h)
        if (floats, filt, codec) != (12, 1, 1):
            self._fail("unsupported attribute layout, filter or codec")
        self.agents, self.frame_rate, self._header_bytes = agents, rate, HEADER
        self.options = {"compression_level": level, "delta": False, "key_interval": 16, "quantum": 0.0}
        self._attrs = [_Attr(1, SHUFFLE4, agents)]
        self._set_pieces(0)

    def _read_header_attrs(self, first):
        """Formats 2 to 4: the options and the attribute records after the first 64 bytes."""
        size, records = struct.unpack_from("<I", first, 12)[0], FIXED_HEADER[self.version]
        if size < records + ATTR_RECORD or size > records + ATTR_RECORD * MAX_ATTRS or (size - records) % ATTR_RECORD:
            self._fail(f"bad header size {size}")
        h = first + self._read_at(HEADER, size - HEADER)
        (_, _, _, agents, count, flags, codec, level, rate, key, crc, quantum) = struct.unpack_from("<8sIIQIIIidIId", h)
        if zlib.crc32(h[56:], zlib.crc32(b"\0\0\0\0", zlib.crc32(h[:52]))) != crc:
            self._fail("header checksum mismatch")
        if not 0 < rate <= 1e9:
            self._fail(f"damaged header: frame rate {rate}")
        if codec != 1 or flags & ~1:
            self._fail("unsupported codec or flags")
        if not (-7 <= level <= -1 or 1 <= level <= 19) or not 1 <= key <= MAX_KEY_INTERVAL or not (quantum >= 0 and np.isfinite(quantum)):
            self._fail("bad options in the header")
        if not 1 <= count <= MAX_ATTRS or size != records + ATTR_RECORD * count:
            self._fail(f"bad attribute count {count} for a {size}-byte header")
        piece = 0
        if self.version >= 3:
            self.header_frames, piece = struct.unpack_from("<II", h, 64)
            if self.version == 3 and piece:
                self._fail("damaged header: reserved bytes 68..71 are not 0")
            if self.version >= 4 and not MIN_PIECE <= piece <= MAX_PIECE:
                self._fail(f"{piece} agents per piece is outside {MIN_PIECE}..{MAX_PIECE}")
        delta = bool(flags & 1)
        self.agents, self.frame_rate, self._header_bytes = agents, rate, size
        self.options = {"compression_level": level, "delta": delta, "key_interval": key, "quantum": quantum}
        self._attrs = []
        for i in range(count):
            kind, scalar, components, filters = struct.unpack_from("<IIII", h, records + ATTR_RECORD * i)
            if kind not in ATTRIBUTES:
                self._fail(f"attribute {i} has unknown kind {kind}")
            name, want_components, want_scalar = ATTRIBUTES[kind]
            if any(a.kind == kind for a in self._attrs):
                self._fail(f"attribute '{name}' appears twice")
            if (scalar, components) != (want_scalar, want_components):
                self._fail(f"attribute '{name}' has the wrong type or component count")
            if filters != _expected_filters(scalar, delta, quantum):
                self._fail(f"attribute '{name}' has unsupported filters {filters}")
            self._attrs.append(_Attr(kind, filters, agents))
        self._set_pieces(piece)
        if self.version >= 4:
            self.options["piece_agents"] = piece

    def _set_pieces(self, piece):
        """Format 4: pieces of `piece` agents (the last one shorter); before it one piece of all."""
        self._piece = piece or max(self.agents, 1)
        self._pieces = max(-(-self.agents // self._piece), 1)

    def _piece_agents(self, j):
        return max(min(self._piece, self.agents - j * self._piece), 0)

    def _blocks(self):
        """(piece, attribute index, raw bytes) of every block of a chunk, in their order."""
        return [(j, i, self._piece_agents(j) * a.per_agent)
                for j in range(self._pieces) for i, a in enumerate(self._attrs)]

    def _table_bytes(self):
        return 0 if self.version == 1 else 8 * len(self._attrs) * self._pieces

    # ------------------------------------------------------------ index and recovery

    def _index_bytes(self, frames):
        return 8 + 8 * frames if self.version == 1 else 16 + 16 * frames

    def _read_index(self):
        self.warning = None
        size = self.file_bytes
        footer = None
        if size >= self._header_bytes + self._index_bytes(0) + FOOTER:
            footer = self._read_at(size - FOOTER, FOOTER)
        if footer is None or footer[8:] != END_MAGIC:
            return self._scan("incomplete cache (no index: the run did not finish or the file was cut short)")
        index_pos = struct.unpack_from("<Q", footer)[0]
        if not self._header_bytes <= index_pos <= size - FOOTER - 8:
            return self._scan("the frame index is damaged")
        tag, frames = struct.unpack("<4sI", self._read_at(index_pos, 8))
        if tag != b"FIDX" or self._index_bytes(frames) != size - FOOTER - index_pos:
            return self._scan("the frame index is damaged")
        raw = self._read_at(index_pos, self._index_bytes(frames))
        if self.version == 1:
            self._offsets = list(struct.unpack_from(f"<{frames}Q", raw, 8))
            ends = self._offsets[1:] + [index_pos]
            self._sizes = [e - o for o, e in zip(self._offsets, ends)]
        else:
            if zlib.crc32(raw[:-8]) != struct.unpack_from("<I", raw, len(raw) - 8)[0]:
                return self._scan("the frame index is damaged")
            pairs = struct.unpack_from(f"<{2 * frames}Q", raw, 8)
            self._offsets, self._sizes = list(pairs[0::2]), list(pairs[1::2])
            if any(o < self._header_bytes or o + s > index_pos for o, s in zip(self._offsets, self._sizes)):
                return self._scan("the frame index is damaged")
        self.frames = frames
        if self.version >= 3 and self.header_frames == 0 and frames > 0:  # stopped after the index, before the header
            return self._scan("incomplete cache (frame count 0 in the header: the writer did not finish)")
        if self.header_frames not in (0, frames):
            self._fail(f"damaged cache: the header says {self.header_frames} frames but the index lists {frames}")
        self.complete = True
        self._summarise()

    def _chunk_bytes(self, h, k):
        """The chunk's bytes if h (its header, and the size table in formats 2 and 3) is frame k's, else None."""
        tag, frame = struct.unpack_from("<4sI", h)
        if tag != b"FRAM" or frame != k:
            return None
        if self.version == 1:
            packed, raw = struct.unpack_from("<QQ", h, 8)
            ok = packed <= _zstd_bound(self._attrs[0].nbytes) and raw == self._attrs[0].nbytes
            return CHUNK_HEADER + packed if ok else None
        flags, _, payload = struct.unpack_from("<IIQ", h, 8)
        if flags != (KEY_FRAME if self._is_key(k) else 0) or not self._block_sizes_ok(h[CHUNK_HEADER:], payload):
            return None
        return CHUNK_HEADER + payload

    def _block_sizes_ok(self, table, payload):
        blocks = self._blocks()
        sizes = struct.unpack_from(f"<{len(blocks)}Q", table)
        return (all(c <= _zstd_bound(n) for c, (_, _, n) in zip(sizes, blocks))
                and self._table_bytes() + sum(sizes) == payload)

    def _scan(self, why):
        """Walks the chunks from the header; every complete one is a readable frame."""
        head = CHUNK_HEADER + self._table_bytes()
        pos, self._offsets, self._sizes = self._header_bytes, [], []
        announced = self.header_frames  # a finished file cut short: no more frames than this
        while pos + head <= self.file_bytes and not (announced and len(self._offsets) == announced):
            self._f.seek(pos)
            n = self._chunk_bytes(self._f.read(head), len(self._offsets))
            if n is None or pos + n > self.file_bytes:
                break
            self._offsets.append(pos)
            self._sizes.append(n)
            pos += n
        self.frames = len(self._offsets)
        self.complete = False
        self.warning = f"{self.path}: {why}; recovered the {self.frames} complete frames before byte {pos}"
        if announced:
            self.warning += f" (the header announces {announced})"
        warnings.warn(self.warning, stacklevel=5)  # the caller of open()
        self._summarise()

    def _check_plausible(self):
        # A frame of agents x bytes per agent must come from this file's chunks, and zstd shrinks
        # by at most about 2^15:1: a header claiming far more is damaged, and reading a frame would
        # allocate for it (the C reader's check_plausible).
        raw = sum(a.nbytes for a in self._attrs)
        if self.frames > 0 and raw // 65536 > self.file_bytes:
            self._fail(f"damaged header: frames of {self.agents} agents cannot come from a file of "
                       f"{self.file_bytes} bytes")

    def _summarise(self):
        self.compressed_bytes = sum(self._sizes)
        self.raw_bytes = self.frames * sum(a.nbytes for a in self._attrs)

    # ------------------------------------------------------------ chunks and frames

    def _is_key(self, k):
        return not self.options["delta"] or k % self.options["key_interval"] == 0

    def _frame_number(self, frame):
        k = _int_arg(frame, self.path, "frame")
        if k < 0:
            k += self.frames
        if not 0 <= k < self.frames:
            has = (f"{self.frames} frames: 0 to {self.frames - 1}, or -{self.frames} to -1 from the end"
                   if self.frames else "no frames")
            raise IndexError(f"{self.path}: frame {frame} does not exist (the cache has {has})")
        return k

    def _frame_range(self, key):
        """The frame numbers slice `key` selects. Its bounds are checked as strictly as a frame
        number: slice.indices would take True as 1."""
        for bound in (key.start, key.stop, key.step):
            if bound is not None:
                _int_arg(bound, self.path, "a slice bound")
        return range(*key.indices(self.frames))

    def _attr_index(self, name):
        if _str_arg(name, self.path) not in self.attributes:
            raise KeyError(f"{self.path}: the cache has no {name!r} attribute (it has {', '.join(self.attributes)})")
        if self._f.closed:  # checked here, as the kept chunk and frame would otherwise still answer
            raise ValueError(f"{self.path}: the cache is closed")
        return self.attributes.index(name)

    def _shape(self, i):
        a = self._attrs[i]
        return (self.agents, 4, 3) if a.name == "tet_vertices" else (self.agents, a.components)

    def _decode(self, k, i):
        """Attribute i of frame k as a new flat array of its values (quantisation undone)."""
        a = self._attrs[i]
        words = self._stored(k, i)
        if a.filters & SHUFFLE4:  # four byte planes in each piece
            step = self._piece * a.per_agent
            words = np.concatenate([words[at:at + step].reshape(4, -1).T.reshape(-1)
                                    for at in range(0, max(len(words), 1), step)])
        values = np.ascontiguousarray(words).reshape(-1)
        if a.filters & QUANTISE:
            return (values.view("<i4").astype(np.float64) * self.options["quantum"]).astype(np.float32)
        return values.view(a.dtype).copy()

    def _load_chunk(self, k):
        """Chunk k's bytes, its header and crc32 checked."""
        if self._chunk_frame == k:
            return self._chunk
        self._chunk_frame = -1
        n = self._sizes[k]
        if n < CHUNK_HEADER + self._table_bytes() or n > CHUNK_HEADER + self._table_bytes() + sum(
                _zstd_bound(b) for _, _, b in self._blocks()):
            self._fail(f"frame {k}: damaged chunk header")
        chunk = self._read_at(self._offsets[k], n)
        stated = self._chunk_bytes(chunk[:CHUNK_HEADER + self._table_bytes()], k)
        if self.version != 1 and stated == n:
            if zlib.crc32(chunk[16:], zlib.crc32(chunk[:12])) != struct.unpack_from("<I", chunk, 12)[0]:
                self._fail(f"chunk {k}: checksum mismatch (frame {k} is corrupt)")
        if stated != n:
            self._fail(f"frame {k}: damaged chunk header")
        self._chunk_frame, self._chunk = k, chunk
        return chunk

    def _block(self, k, i):
        """Attribute i of chunk k, decompressed (stored words: quantised, shuffled piece by piece,
        maybe a delta): its block in every piece, one after another."""
        chunk = self._load_chunk(k)
        a = self._attrs[i]
        if self.version == 1:
            parts = [(CHUNK_HEADER, len(chunk) - CHUNK_HEADER, a.nbytes)]
        else:
            blocks = self._blocks()
            sizes = struct.unpack_from(f"<{len(blocks)}Q", chunk, CHUNK_HEADER)
            parts, start = [], CHUNK_HEADER + self._table_bytes()
            for (_, attr, raw), size in zip(blocks, sizes):
                if attr == i:
                    parts.append((start, size, raw))
                start += size
        try:
            data = b"".join(self._zstd(chunk[at:at + size], raw) for at, size, raw in parts)
        except ValueError as e:
            self._fail(f"frame {k} is corrupt ({a.name}: {e})")
        return np.frombuffer(data, dtype=np.uint8)

    def _stored(self, k, i):
        """Attribute i's stored words at frame k, deltas undone from the last key frame (or from
        the frame decoded last when it lies in between)."""
        last, words = self._words.get(i, (-1, None))
        if last == k:
            return words
        if not self._attrs[i].filters & DELTA:
            words = self._block(k, i)
        else:
            key = k - k % self.options["key_interval"]
            start = last + 1 if key <= last < k else key
            if start == key:
                words = self._block(key, i).copy()
                start += 1
            self._words.pop(i, None)
            for j in range(start, k + 1):
                words ^= self._block(j, i)
        self._words[i] = (k, words)
        return words


def open(path):  # noqa: A001 - the module's entry point, like gzip.open
    """Opens a flockmorph cache for reading; see Cache."""
    return Cache(path)
