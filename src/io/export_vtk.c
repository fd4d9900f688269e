/* VTK XML UnstructuredGrid (.vtu) for one frame, in the layout VTK's own writer uses: the XML
 * header lists every array with format="appended" and its offset into the AppendedData block.
 * Compressed (compressor="vtkZLibDataCompressor", the default), each array there is a header of
 * UInt64s [number of blocks, block size, size of a partial last block or 0, compressed size of
 * each block] followed by the blocks, each one zlib stream of up to VTU_BLOCK bytes of values, so
 * a reader can inflate blocks independently. Raw (zlib level 0), each array is a UInt64 byte
 * count followed by the little-endian values.
 *
 * Tets are VTK_TETRA cells (type 10) with 4 points each; cells share no points, so the
 * connectivity is 0 1 2 3 | 4 5 6 7 | ... in every frame and only the coordinates change. VTK's
 * tetra orders its points like the cache (positive volume for v3 above the face v0 v1 v2 seen
 * counter-clockwise), so the points go out as they are; their point data `id` is unique per point
 * (fm_tet_point_id), the cell data the tet's. Points are VTK_VERTEX cells (type 1). */
#define _POSIX_C_SOURCE 200809L /* open_memstream */
#include "export.h"

#include <errno.h>
#include <stdlib.h>
#include <zlib.h>

enum { VTK_VERTEX = 1, VTK_TETRA = 10 };

/* The uncompressed size of a block: vtkXMLWriter's default, so files look like VTK's own. */
enum { VTU_BLOCK = 1 << 15 };

/* Points, connectivity, offsets, types, id, phase, velocity, orient, group, and a tet's point ids. */
enum { VTU_MAX_ARRAYS = 10 };

typedef enum vtu_section { SEC_POINTS, SEC_CELLS, SEC_CELL_DATA, SEC_POINT_DATA, SEC_COUNT } vtu_section;

typedef void (*vtu_emit_fn)(fm_le_writer *w, const fm_export_frame *frame);

typedef struct vtu_array {
    vtu_section section;
    const char *type, *name;
    int components;
    uint64_t bytes;         /* of the values */
    vtu_emit_fn emit;
    unsigned char *packed;  /* compressed: the header and blocks as they go into the file */
    uint64_t stored;        /* the array's bytes in AppendedData (raw: 8 + bytes) */
} vtu_array;

static int is_tets(const fm_export_frame *f) { return f->tet_vertices != NULL; }
static size_t points_per_cell(const fm_export_frame *f) { return is_tets(f) ? 4 : 1; }

static void emit_points(fm_le_writer *w, const fm_export_frame *f)
{
    const float *p = is_tets(f) ? f->tet_vertices : f->positions;
    for (size_t i = 0; i < 3 * points_per_cell(f) * f->n; i++) fm_le_f32(w, p[i]);
}

static void emit_connectivity(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < points_per_cell(f) * f->n; i++) fm_le_u64(w, i);
}

/* The end of each cell's points in the connectivity (VTK XML 1.0: no leading zero). */
static void emit_offsets(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 1; i <= f->n; i++) fm_le_u64(w, points_per_cell(f) * i);
}

static void emit_types(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < f->n; i++) fm_le_u8(w, is_tets(f) ? VTK_TETRA : VTK_VERTEX);
}

static void emit_ids(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < f->n; i++) fm_le_u32(w, f->ids ? f->ids[i] : (uint32_t)i);
}

/* Tets: each point's own id, 4 × its tet's id + the vertex (ids unique per point, as Houdini's). */
static void emit_point_ids(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < f->n; i++)
        for (int j = 0; j < 4; j++) fm_le_u32(w, fm_tet_point_id(f->ids ? f->ids[i] : (uint32_t)i, j));
}

static void emit_phases(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < f->n; i++) fm_le_u8(w, f->phases[i]);
}

static void emit_groups(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < f->n; i++) fm_le_u8(w, f->groups[i]);
}

static void emit_velocities(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < 3 * f->n; i++) fm_le_f32(w, f->velocities[i]);
}

/* Houdini's orient (x, y, z, w), as the PLY and VDB exports write it. */
static void emit_orientations(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < f->n; i++)
        for (int c = 0; c < 4; c++) fm_le_f32(w, fm_orient_xyzw(f->orientations + 4 * i, c));
}

/* The frame's arrays in file order; returns how many. */
static int vtu_arrays(const fm_export_frame *f, vtu_array a[VTU_MAX_ARRAYS])
{
    uint64_t n = f->n, np = points_per_cell(f) * n;
    int k = 0;
    a[k++] = (vtu_array){SEC_POINTS, "Float32", "Points", 3, 12 * np, emit_points, NULL, 0};
    a[k++] = (vtu_array){SEC_CELLS, "Int64", "connectivity", 1, 8 * np, emit_connectivity, NULL, 0};
    a[k++] = (vtu_array){SEC_CELLS, "Int64", "offsets", 1, 8 * n, emit_offsets, NULL, 0};
    a[k++] = (vtu_array){SEC_CELLS, "UInt8", "types", 1, n, emit_types, NULL, 0};
    /* per tet: cell data; per point: point data (a vertex cell and its point are one agent) */
    vtu_section data = is_tets(f) ? SEC_CELL_DATA : SEC_POINT_DATA;
    a[k++] = (vtu_array){data, "UInt32", is_tets(f) ? "agent_id" : "id", 1, 4 * n, emit_ids, NULL, 0};
    if (f->phases) a[k++] = (vtu_array){data, "UInt8", "phase", 1, n, emit_phases, NULL, 0};
    if (f->velocities) a[k++] = (vtu_array){data, "Float32", "velocity", 3, 12 * n, emit_velocities, NULL, 0};
    if (f->orientations && !is_tets(f))
        a[k++] = (vtu_array){SEC_POINT_DATA, "Float32", "orient", 4, 16 * n, emit_orientations, NULL, 0};
    if (f->groups) a[k++] = (vtu_array){data, "UInt8", "group", 1, n, emit_groups, NULL, 0};
    if (is_tets(f)) a[k++] = (vtu_array){SEC_POINT_DATA, "UInt32", "id", 1, 4 * np, emit_point_ids, NULL, 0};
    return k;
}

static int vtu_header(FILE *file, const fm_export_frame *f, const vtu_array *a, int count, int compressed)
{
    static const char *const open[SEC_COUNT] = {"      <Points>\n", "      <Cells>\n",
                                                "      <CellData>\n", "      <PointData>\n"};
    static const char *const close[SEC_COUNT] = {"      </Points>\n", "      </Cells>\n",
                                                 "      </CellData>\n", "      </PointData>\n"};
    if (fprintf(file,
                "<?xml version=\"1.0\"?>\n"
                "<!-- flockmorph " FM_VERSION_STRING " -->\n"
                "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
                "header_type=\"UInt64\"%s>\n"
                "  <UnstructuredGrid>\n"
                "    <Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n",
                compressed ? " compressor=\"vtkZLibDataCompressor\"" : "", points_per_cell(f) * f->n, f->n) < 0)
        return -1;
    uint64_t offset = 0;
    for (int i = 0; i < count; i++) {
        if ((i == 0 || a[i].section != a[i - 1].section) && fputs(open[a[i].section], file) < 0)
            return -1;
        if (fprintf(file,
                    "        <DataArray type=\"%s\" Name=\"%s\" NumberOfComponents=\"%d\" "
                    "format=\"appended\" offset=\"%llu\"/>\n",
                    a[i].type, a[i].name, a[i].components, (unsigned long long)offset) < 0)
            return -1;
        offset += a[i].stored;
        if ((i == count - 1 || a[i].section != a[i + 1].section) && fputs(close[a[i].section], file) < 0)
            return -1;
    }
    return fputs("    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _", file) < 0
               ? -1 : 0;
}

static int vtu_footer(FILE *file) { return fputs("\n  </AppendedData>\n</VTKFile>\n", file) < 0 ? -1 : 0; }

typedef struct vtu_layout {
    const fm_export_frame *frame;
    vtu_array a[VTU_MAX_ARRAYS];
    int count;
} vtu_layout;

/* ---------------------------------------------------------------- raw */

/* Each array as a UInt64 byte count and its values. */
static void vtu_appended_raw(fm_le_writer *w, const void *data)
{
    const vtu_layout *l = data;
    for (int i = 0; i < l->count; i++) {
        fm_le_u64(w, l->a[i].bytes);
        l->a[i].emit(w, l->frame);
    }
}

/* Streamed: the offsets are known before any value is written. */
static int vtu_write_raw(FILE *file, vtu_layout *l)
{
    for (int i = 0; i < l->count; i++) l->a[i].stored = 8 + l->a[i].bytes;
    if (vtu_header(file, l->frame, l->a, l->count, 0) || fm_le_write(file, vtu_appended_raw, l)) return -1;
    return vtu_footer(file);
}

/* ---------------------------------------------------------------- compressed */

/* One array's emitter as an fm_le_emit_fn. */
typedef struct vtu_one {
    const fm_export_frame *frame;
    vtu_emit_fn emit;
} vtu_one;

static void emit_one(fm_le_writer *w, const void *data)
{
    const vtu_one *one = data;
    one->emit(w, one->frame);
}

/* One array's values into malloc'ed memory, through the emitters the raw layout streams. */
static unsigned char *vtu_values(const vtu_layout *l, const vtu_array *a)
{
    char *buf = NULL;
    size_t size = 0;
    FILE *mem = open_memstream(&buf, &size);
    if (!mem) return NULL;
    int rc = fm_le_write(mem, emit_one, &(vtu_one){l->frame, a->emit});
    if (fclose(mem) || rc || size != a->bytes) {
        free(buf);
        return errno = ENOMEM, NULL; /* a memory stream fails only for want of memory */
    }
    return (unsigned char *)buf;
}

/* values (size bytes) in VTK's compressed layout into a->packed: the UInt64 header, then each
 * VTU_BLOCK of values as its own zlib stream. z is a deflate stream set up with the level. */
static int vtu_pack(z_stream *z, const unsigned char *values, uint64_t size, vtu_array *a)
{
    uint64_t blocks = (size + VTU_BLOCK - 1) / VTU_BLOCK, at = 8 * (3 + blocks);
    uint64_t cap = at + blocks * deflateBound(z, VTU_BLOCK);
    if (!(a->packed = malloc(cap))) return errno = ENOMEM, -1;
    fm_le_store_u64(a->packed, blocks);
    fm_le_store_u64(a->packed + 8, VTU_BLOCK);
    fm_le_store_u64(a->packed + 16, size % VTU_BLOCK); /* 0: the last block is a whole one */
    for (uint64_t b = 0; b < blocks; b++) {
        deflateReset(z);
        z->next_in = (unsigned char *)values + b * VTU_BLOCK;
        z->avail_in = (uInt)(b + 1 < blocks || !(size % VTU_BLOCK) ? VTU_BLOCK : size % VTU_BLOCK);
        z->next_out = a->packed + at, z->avail_out = (uInt)(cap - at);
        if (deflate(z, Z_FINISH) != Z_STREAM_END) return errno = EIO, -1; /* cannot happen: room for the bound */
        fm_le_store_u64(a->packed + 8 * (3 + b), z->total_out);
        at += z->total_out;
    }
    a->stored = at;
    return 0;
}

/* Every array packed before the header: its offsets are the compressed sizes. One array's values
 * are in memory at a time. */
static int vtu_pack_all(vtu_layout *l, int level)
{
    z_stream z = {0};
    if (deflateInit(&z, level) != Z_OK) return errno = ENOMEM, -1;
    int rc = 0;
    for (int i = 0; rc == 0 && i < l->count; i++) {
        unsigned char *values = vtu_values(l, &l->a[i]);
        rc = values ? vtu_pack(&z, values, l->a[i].bytes, &l->a[i]) : -1;
        free(values);
    }
    deflateEnd(&z);
    return rc;
}

static int vtu_write_compressed(FILE *file, vtu_layout *l, int level)
{
    int rc = vtu_pack_all(l, level) || vtu_header(file, l->frame, l->a, l->count, 1) ? -1 : 0;
    for (int i = 0; rc == 0 && i < l->count; i++)
        if (fwrite(l->a[i].packed, 1, l->a[i].stored, file) != l->a[i].stored) rc = -1;
    for (int i = 0; i < l->count; i++) free(l->a[i].packed);
    return rc ? -1 : vtu_footer(file);
}

int fm_vtu_body(FILE *file, const void *data)
{
    const fm_vtu_input *in = data;
    vtu_layout l = {.frame = in->frame};
    l.count = vtu_arrays(l.frame, l.a);
    return in->zlib_level > 0 ? vtu_write_compressed(file, &l, in->zlib_level) : vtu_write_raw(file, &l);
}
