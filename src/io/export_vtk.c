/* VTK XML UnstructuredGrid (.vtu) for one frame, in the layout VTK's own writer uses: the XML
 * header lists every array with format="appended" and its offset into the AppendedData block,
 * which holds, per array, a UInt64 byte count followed by the raw little-endian values.
 *
 * Tets are VTK_TETRA cells (type 10) with 4 points each; cells share no points, so the
 * connectivity is 0 1 2 3 | 4 5 6 7 | ... in every frame and only the coordinates change. VTK's
 * tetra orders its points like the cache (positive volume for v3 above the face v0 v1 v2 seen
 * counter-clockwise), so the points go out as they are. Points are VTK_VERTEX cells (type 1). */
#include "export.h"


enum { VTK_VERTEX = 1, VTK_TETRA = 10 };

typedef enum vtu_section { SEC_POINTS, SEC_CELLS, SEC_CELL_DATA, SEC_POINT_DATA, SEC_COUNT } vtu_section;

typedef void (*vtu_emit_fn)(fm_le_writer *w, const fm_export_frame *frame);

typedef struct vtu_array {
    vtu_section section;
    const char *type, *name;
    int components;
    uint64_t bytes;     /* of the values, without the UInt64 byte count */
    vtu_emit_fn emit;
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

static void emit_phases(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < f->n; i++) fm_le_u8(w, f->phases[i]);
}

static void emit_velocities(fm_le_writer *w, const fm_export_frame *f)
{
    for (size_t i = 0; i < 3 * f->n; i++) fm_le_f32(w, f->velocities[i]);
}

/* The frame's arrays in file order; returns how many. */
static int vtu_arrays(const fm_export_frame *f, vtu_array a[8])
{
    uint64_t n = f->n, np = points_per_cell(f) * n;
    int k = 0;
    a[k++] = (vtu_array){SEC_POINTS, "Float32", "Points", 3, 12 * np, emit_points};
    a[k++] = (vtu_array){SEC_CELLS, "Int64", "connectivity", 1, 8 * np, emit_connectivity};
    a[k++] = (vtu_array){SEC_CELLS, "Int64", "offsets", 1, 8 * n, emit_offsets};
    a[k++] = (vtu_array){SEC_CELLS, "UInt8", "types", 1, n, emit_types};
    /* per tet: cell data; per point: point data (a vertex cell and its point are one agent) */
    vtu_section data = is_tets(f) ? SEC_CELL_DATA : SEC_POINT_DATA;
    a[k++] = (vtu_array){data, "UInt32", is_tets(f) ? "agent_id" : "id", 1, 4 * n, emit_ids};
    if (f->phases) a[k++] = (vtu_array){data, "UInt8", "phase", 1, n, emit_phases};
    if (f->velocities && !is_tets(f))
        a[k++] = (vtu_array){SEC_POINT_DATA, "Float32", "velocity", 3, 12 * n, emit_velocities};
    return k;
}

static int vtu_header(FILE *file, const fm_export_frame *f, const vtu_array *a, int count)
{
    static const char *const open[SEC_COUNT] = {"      <Points>\n", "      <Cells>\n",
                                                "      <CellData>\n", "      <PointData>\n"};
    static const char *const close[SEC_COUNT] = {"      </Points>\n", "      </Cells>\n",
                                                 "      </CellData>\n", "      </PointData>\n"};
    if (fprintf(file,
                "<?xml version=\"1.0\"?>\n"
                "<!-- flockmorph " FM_VERSION_STRING " -->\n"
                "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
                "header_type=\"UInt64\">\n"
                "  <UnstructuredGrid>\n"
                "    <Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n",
                points_per_cell(f) * f->n, f->n) < 0)
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
        offset += 8 + a[i].bytes;
        if ((i == count - 1 || a[i].section != a[i + 1].section) && fputs(close[a[i].section], file) < 0)
            return -1;
    }
    return fputs("    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _", file) < 0
               ? -1 : 0;
}

typedef struct vtu_layout {
    const fm_export_frame *frame;
    vtu_array a[8];
    int count;
} vtu_layout;

/* Each array as a UInt64 byte count and its values. */
static void vtu_appended(fm_le_writer *w, const void *data)
{
    const vtu_layout *l = data;
    for (int i = 0; i < l->count; i++) {
        fm_le_u64(w, l->a[i].bytes);
        l->a[i].emit(w, l->frame);
    }
}

int fm_vtu_body(FILE *file, const void *data)
{
    vtu_layout l = {.frame = data};
    l.count = vtu_arrays(l.frame, l.a);
    if (vtu_header(file, l.frame, l.a, l.count) || fm_le_write(file, vtu_appended, &l)) return -1;
    return fputs("\n  </AppendedData>\n</VTKFile>\n", file) < 0 ? -1 : 0;
}
