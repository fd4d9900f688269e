/* flockmorph caches: the native frame cache (docs/cache-format.md), its writer and its reader. */
#ifndef FLOCKMORPH_CACHE_H
#define FLOCKMORPH_CACHE_H

#include "flockmorph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The native frame cache (docs/cache-format.md): one zstd-compressed chunk per frame, an index
 * for random access. Written as PATH.partial and renamed to PATH only by finish(). */
typedef struct fm_cache_writer fm_cache_writer;

fm_cache_writer *fm_cache_writer_create(const char *path, uint64_t agents, double frame_rate,
                                        int compression_level, fm_error *err);
/* verts: agents × 12 floats. */
fm_status fm_cache_writer_add_frame(fm_cache_writer *w, const float *verts, fm_error *err);
/* Writes the index and renames PATH.partial to PATH; frees w. If anything failed (now or on the
 * writer thread: disk full, file-size limit), PATH.partial stays, readable by fm_cache_open up to
 * its last complete frame, and nothing is under PATH. */
fm_status fm_cache_writer_finish(fm_cache_writer *w, fm_error *err);
void fm_cache_writer_abort(fm_cache_writer *w);                       /* frees w, deletes file */

typedef struct fm_cache_reader fm_cache_reader;

/* Opens a cache for random access by frame. A cache without a valid index (the run was killed,
 * the file was cut short) is opened up to its last complete frame, and fm_cache_warning says so. */
fm_cache_reader *fm_cache_open(const char *path, fm_error *err);
/* "" for a complete cache; otherwise what was wrong and how many frames were recovered. */
const char *fm_cache_warning(const fm_cache_reader *r);
uint64_t fm_cache_agents(const fm_cache_reader *r);
uint32_t fm_cache_frames(const fm_cache_reader *r);
double fm_cache_frame_rate(const fm_cache_reader *r);
/* The tet vertices of one frame (agents × 12 floats); an error if the cache has no tet vertices. */
fm_status fm_cache_read_frame(fm_cache_reader *r, uint32_t frame, float *out, fm_error *err);
void fm_cache_close(fm_cache_reader *r);

/* ---------------------------------------------------------------- attributes (formats 2 and 3)
 *
 * A cache holds, per frame, one array per attribute, agents in id order. The tetra morph writes
 * tet vertices and phase; point flocks (the shape-constrained flock) write position, velocity and
 * orientation. fm_cache_writer_create above is the tetra morph's shorthand for
 * {FM_ATTR_TET_VERTICES} with default options. */
typedef enum fm_cache_attr {
    FM_ATTR_TET_VERTICES = 1, /* 12 × f32: 4 vertices × xyz */
    FM_ATTR_POSITION = 2,     /* 3 × f32 */
    FM_ATTR_VELOCITY = 3,     /* 3 × f32 */
    FM_ATTR_ORIENTATION = 4,  /* 4 × f32: unit quaternion w x y z, the agent's frame (x along velocity) */
    FM_ATTR_ID = 5,           /* 1 × u32: stable agent id */
    FM_ATTR_PHASE = 6,        /* 1 × u8: fm_phase (tetra morph) or the flock's own phase */
    FM_ATTR_GROUP = 7         /* 1 × u8: the index of the scene's group that moves the agent (a shot) */
} fm_cache_attr;

typedef enum fm_cache_scalar { FM_SCALAR_F32 = 1, FM_SCALAR_U32 = 2, FM_SCALAR_U8 = 3 } fm_cache_scalar;

typedef struct fm_cache_attr_info {
    fm_cache_attr attr;
    const char *name;        /* "tet_vertices", "position", ... as in docs/cache-format.md */
    int components;          /* values per agent */
    fm_cache_scalar scalar;
    size_t bytes_per_agent;  /* components × scalar size */
} fm_cache_attr_info;

/* Fixed facts about an attribute kind; NULL for an unknown one. */
const fm_cache_attr_info *fm_cache_attr_describe(fm_cache_attr attr);

typedef struct fm_cache_options {
    int compression_level;   /* zstd 1..19 (default 1) */
    int delta;               /* 1 (the default): every attribute stored as the XOR of its bits with
                                the previous frame's (lossless); every key_interval-th frame is
                                stored whole. 0: every frame whole */
    int key_interval;        /* frames from one whole frame to the next when delta is on (default 16):
                                random access decodes at most this many chunks */
    double quantum;          /* > 0: f32 attributes rounded to multiples of quantum and stored as
                                int32 multiples (lossy, error <= quantum / 2 before the read value's
                                own float rounding); 0: lossless (the default) */
    int piece_agents;        /* agents per piece, 256 … 2^30 (default 65536; 0 means the default):
                                each piece of every attribute is filtered and compressed on its own,
                                so the writer's threads, and P ranks, encode a frame in parallel.
                                A reader of a format-3 or older cache gives 0: one piece */
} fm_cache_options;

fm_cache_options fm_default_cache_options(void);

fm_cache_writer *fm_cache_writer_create_attrs(const char *path, uint64_t agents, double frame_rate,
                                              const fm_cache_attr *attrs, int attr_count,
                                              const fm_cache_options *opts, fm_error *err);
/* data[i] points at agents × attribute i's values, in the order given to create_attrs. */
fm_status fm_cache_writer_add_frame_attrs(fm_cache_writer *w, const void *const *data, fm_error *err);
/* Reopens PATH.partial left by an interrupted run (format 3), checks its first `frames` chunks
 * (headers and crc32), drops anything after them, and continues writing with the attributes and
 * options of its header (checkpoint / resume). Given the same further frames the finished file is
 * byte-identical to an uninterrupted one. Fails, leaving the file alone, if fewer frames are
 * readable. */
fm_cache_writer *fm_cache_writer_resume(const char *path, uint32_t frames, fm_error *err);
uint32_t fm_cache_writer_frames(const fm_cache_writer *w); /* frames handed over so far */
/* The writer's agents and attributes, in the order given to create_attrs (as the reader's
 * fm_cache_agents, fm_cache_attr_count and fm_cache_attr_at). */
uint64_t fm_cache_writer_agents(const fm_cache_writer *w);
int fm_cache_writer_attr_count(const fm_cache_writer *w);
const fm_cache_attr_info *fm_cache_writer_attr_at(const fm_cache_writer *w, int i);
/* Called with every frame handed over, on the caller's thread before add_frame_attrs copies it:
 * `flockmorph studio` streams the very arrays the cache stores, so what a page shows is what the
 * run writes (docs/studio.md). data[i] as given to add_frame_attrs; NULL tap: none. */
typedef void (*fm_cache_frame_tap)(uint32_t frame, const void *const *data, void *user);
void fm_cache_writer_set_tap(fm_cache_writer *w, fm_cache_frame_tap tap, void *user);
/* Waits until every frame handed over so far is written, then flushes and fsyncs the file, so a
 * checkpoint taken after it can rely on those frames being on disk. */
fm_status fm_cache_writer_flush(fm_cache_writer *w, fm_error *err);
/* Stops without an index: frees w and keeps PATH.partial with every frame written so far, readable
 * by fm_cache_open up to its last complete frame and continued by fm_cache_writer_resume (a run
 * stopped by a signal, or one that failed: disk full, file-size limit). */
void fm_cache_writer_close_partial(fm_cache_writer *w);

int fm_cache_attr_count(const fm_cache_reader *r);
const fm_cache_attr_info *fm_cache_attr_at(const fm_cache_reader *r, int i);
int fm_cache_has_attr(const fm_cache_reader *r, fm_cache_attr attr);
/* Reads one attribute of one frame into out (agents × bytes_per_agent bytes, aligned for its
 * scalar type). With delta, a frame is rebuilt from the key frame before it; the last decoded frame
 * is kept, so reading frames in order decodes one chunk each. */
fm_status fm_cache_read_attr(fm_cache_reader *r, uint32_t frame, fm_cache_attr attr, void *out,
                             fm_error *err);
/* Sizes for `inspect`: the file, and the raw and compressed bytes of all frames. */
uint64_t fm_cache_file_bytes(const fm_cache_reader *r);
uint64_t fm_cache_raw_bytes(const fm_cache_reader *r);
uint64_t fm_cache_compressed_bytes(const fm_cache_reader *r);
uint64_t fm_cache_frame_bytes(const fm_cache_reader *r, uint32_t frame); /* one chunk; 0 past the end */
uint32_t fm_cache_version(const fm_cache_reader *r);                     /* 1, 2 or 3 */
/* The frame count the header states (format 3): 0 while the writer runs and in a partial file,
 * else equal to fm_cache_frames (fm_cache_open refuses a file where it differs from the index).
 * Formats 1 and 2 have none: 0. */
uint32_t fm_cache_header_frames(const fm_cache_reader *r);
/* The options the cache was written with (format 1: its level, no delta, no quantum). */
fm_cache_options fm_cache_get_options(const fm_cache_reader *r);

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_CACHE_H */
