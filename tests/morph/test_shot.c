/* Shots: several morphs of one scene's `groups` on one clock, in one cache (docs/scene.md, "Groups").
 *   castling: examples/castling, the king's morph and then the rook's past it. Every vertex of every
 *             frame is checked with the tests' own inside test (ray parity, tests/helpers/inside_test.h)
 *             against the shapes each group avoids: no king vertex enters the waiting rook, no rook
 *             vertex the king where it formed; the cache bytes are the same for 1 and 2 threads.
 *   chain:    A -> B -> C, each group starting from the shape the previous one formed: the same rows
 *             fly on, unbroken at every hand-over, and the group attribute says who moves them.
 *   errors:   the group keys' refusals name the file, line and key. */
#include "flockmorph/flockmorph.h"
#include "geom.h"
#include "inside_test.h"
#include "shot_helpers.h"
#include "test_macros.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double DEPTH_TOL = 1e-5;

/* Runs the shot into `cache`; 0 on success. */
static int run_shot(const fm_scene_def *defs, int count, int threads, const char *cache, fm_shot_stats *stats)
{
    fm_error err = {0};
    fm_shot *shot = fm_shot_build(defs, count, threads, NULL, NULL, &err);
    ENSURE_MSG(shot != NULL, "%s", err.message);
    if (!shot) return -1;
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE, FM_ATTR_GROUP};
    fm_cache_options opts = fm_default_cache_options();
    fm_cache_writer *w = fm_cache_writer_create_attrs(cache, (uint64_t)fm_shot_rows(shot), defs[0].frame_rate, attrs, 4,
                                                      &opts, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    fm_run_control c = fm_default_run_control();
    fm_status st = w ? fm_shot_run(shot, w, &c, stats, &err) : FM_ERR_IO;
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    if (w) ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    fm_shot_destroy(shot);
    return st == FM_OK ? 0 : -1;
}

typedef struct placed {
    fm_mesh mesh;
    inside_mesh inside;
} placed;

static int place(const fm_mesh_ref *ref, placed *p)
{
    fm_error err = {0};
    memset(p, 0, sizeof *p);
    ENSURE_MSG(fm_mesh_load(ref->path, &p->mesh, &err) == FM_OK, "%s", err.message);
    if (err.status != FM_OK) return -1;
    fm_mesh_place(&p->mesh, ref);
    return inside_build(&p->inside, p->mesh.v, p->mesh.nv, p->mesh.tri, p->mesh.nt);
}

/* Vertex-frames of the rows of group `g` deeper than DEPTH_TOL inside `obstacle`. */
static int64_t count_inside(fm_cache_reader *r, int g, const placed *obstacle, double *deepest)
{
    const uint64_t n = fm_cache_agents(r);
    float *verts = malloc(sizeof(float) * 12 * n);
    uint8_t *group = malloc(n);
    int64_t inside = 0;
    fm_error err = {0};
    for (uint32_t f = 0; verts && group && f < fm_cache_frames(r); f++) {
        ENSURE(fm_cache_read_attr(r, f, FM_ATTR_TET_VERTICES, verts, &err) == FM_OK);
        ENSURE(fm_cache_read_attr(r, f, FM_ATTR_GROUP, group, &err) == FM_OK);
        for (uint64_t a = 0; a < n; a++) {
            if (group[a] != g) continue;
            for (int v = 0; v < 4; v++) {
                const double p[3] = {verts[12 * a + 3 * v], verts[12 * a + 3 * v + 1], verts[12 * a + 3 * v + 2]};
                if (!inside_point(&obstacle->inside, p)) continue;
                double d = inside_depth(&obstacle->inside, p);
                if (d > DEPTH_TOL) inside++, *deepest = fmax(*deepest, d);
            }
        }
    }
    free(verts), free(group);
    return inside;
}

static void test_castling_shot(void)
{
    char path[FM_PATH_MAX], one[FM_PATH_MAX], two[FM_PATH_MAX];
    snprintf(path, sizeof path, "%s/examples/castling/scene.json", FM_SOURCE_DIR);
    snprintf(one, sizeof one, "%s/shot_castling_1.fmc", FM_TEST_TMP);
    snprintf(two, sizeof two, "%s/shot_castling_2.fmc", FM_TEST_TMP);
    static fm_scene_def defs[FM_MAX_GROUPS]; /* 120 KiB each */
    int count = 0;
    if (load_groups(path, defs, &count) != 0) return;
    ENSURE(count == 2 && !strcmp(defs[0].group.name, "king") && !strcmp(defs[1].group.name, "rook"));
    fm_shot_stats s1, s2;
    if (run_shot(defs, count, 1, one, &s1) || run_shot(defs, count, 2, two, &s2)) return;
    ENSURE_MSG(same_file(one, two), "the shot's cache differs between 1 and 2 threads");
    for (int g = 0; g < 2; g++)
        ENSURE_MSG(s1.group[g].all_arrived && s1.group[g].final_max_vertex_error <= 1e-5 && s1.group[g].target_tets_filled_once,
                   "group %d: arrived %d, error %g", g, s1.group[g].all_arrived, s1.group[g].final_max_vertex_error);
    ENSURE(s1.group[1].start_time > s1.group[0].arrival_time);
    placed rook_waiting, king_formed;
    if (place(&defs[1].source, &rook_waiting) || place(&defs[0].target, &king_formed)) return;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(one, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    double deep_king = 0, deep_rook = 0;
    int64_t king_in_rook = count_inside(r, 0, &rook_waiting, &deep_king);
    int64_t rook_in_king = count_inside(r, 1, &king_formed, &deep_rook);
    printf("  castling: %u frames, %llu rows; king vertices inside the waiting rook %lld, rook vertices inside the "
           "formed king %lld (deepest %.3g); rook's vertex clearance %.4g\n", fm_cache_frames(r),
           (unsigned long long)fm_cache_agents(r), (long long)king_in_rook, (long long)rook_in_king, deep_rook,
           s1.group[1].min_vertex_clearance);
    ENSURE(king_in_rook == 0);
    ENSURE_MSG(rook_in_king == 0, "%lld rook vertex-frames inside the king, up to %g deep", (long long)rook_in_king, deep_rook);
    fm_cache_close(r);
    inside_free(&rook_waiting.inside), inside_free(&king_formed.inside);
    fm_mesh_free(&rook_waiting.mesh), fm_mesh_free(&king_formed.mesh);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (f) fputs(text, f), fclose(f);
}

/* An octahedron |x| + |y| + |z| <= 1 as OBJ. */
static void write_octahedron(const char *path)
{
    FILE *f = fopen(path, "w");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (!f) return;
    fprintf(f, "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n");
    for (int s = 0; s < 8; s++) {
        int x = s & 1 ? 2 : 1, y = s & 2 ? 4 : 3, z = s & 4 ? 6 : 5;
        int odd = ((s & 1) + (s >> 1 & 1) + (s >> 2 & 1)) & 1;
        fprintf(f, "f %d %d %d\n", x, odd ? z : y, odd ? y : z);
    }
    fclose(f);
}

static const char CHAIN[] =
    "{\n"
    "  \"time\": { \"frame_rate\": 24, \"time_step\": 0.02083333333333333, \"frame_limit\": 600 },\n"
    "  \"speed0\": 6, \"launch_rate\": 3000, \"seed\": 9,\n"
    "  \"groups\": [\n"
    "    { \"name\": \"a\", \"n\": 1500, \"source\": { \"mesh\": \"oct.obj\", \"translate\": [-6, 0, 0] },\n"
    "      \"target\": { \"mesh\": \"oct.obj\", \"translate\": [0, 0, 0], \"scale\": 1.5 } },\n"
    "    { \"name\": \"b\", \"source\": { \"group\": \"a\" }, \"start\": 0.5,\n"
    "      \"target\": { \"mesh\": \"oct.obj\", \"translate\": [6, 0, 0], \"rotate_deg\": [0, 0, 45] } },\n"
    "    { \"name\": \"c\", \"source\": { \"group\": \"b\" },\n"
    "      \"target\": { \"mesh\": \"oct.obj\", \"translate\": [0, 6, 0], \"scale\": 0.8 } }\n"
    "  ]\n"
    "}\n";

/* The largest coordinate difference between two frames' rows whose phase now is (waiting) or is
 * not (!waiting) FM_PHASE_WAITING. */
static double frame_gap(const float *x, const float *y, const uint8_t *phase, int waiting, uint64_t n)
{
    double gap = 0;
    for (uint64_t a = 0; a < n; a++)
        if ((phase[a] == FM_PHASE_WAITING) == waiting)
            for (int i = 0; i < 12; i++) gap = fmax(gap, fabs((double)x[12 * a + i] - y[12 * a + i]));
    return gap;
}

static void test_chain_flies_on(void)
{
    char dir_oct[FM_PATH_MAX], scene[FM_PATH_MAX], cache[FM_PATH_MAX];
    snprintf(dir_oct, sizeof dir_oct, "%s/oct.obj", FM_TEST_TMP);
    snprintf(scene, sizeof scene, "%s/shot_chain.json", FM_TEST_TMP);
    snprintf(cache, sizeof cache, "%s/shot_chain.fmc", FM_TEST_TMP);
    write_octahedron(dir_oct);
    write_text(scene, CHAIN);
    static fm_scene_def defs[FM_MAX_GROUPS];
    int count = 0;
    if (load_groups(scene, defs, &count) != 0) return;
    ENSURE(count == 3 && defs[1].group.source_group == 0 && defs[2].group.source_group == 1 && defs[2].group.after == 1);
    fm_shot_stats st;
    if (run_shot(defs, count, 2, cache, &st) != 0) return;
    ENSURE_MSG(st.rows == 1500, "%lld rows: the chained groups must not add any", (long long)st.rows);
    for (int g = 0; g < 3; g++)
        ENSURE_MSG(st.group[g].all_arrived && st.group[g].final_max_vertex_error <= 1e-5 && st.group[g].agents == 1500,
                   "group %d: arrived %d, error %g, %lld agents", g, st.group[g].all_arrived,
                   st.group[g].final_max_vertex_error, (long long)st.group[g].agents);
    ENSURE(st.inverted_tet_frames == 0);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(cache, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    const uint64_t n = fm_cache_agents(r);
    float *prev = malloc(sizeof(float) * 12 * n), *cur = malloc(sizeof(float) * 12 * n);
    uint8_t *group = malloc(n), *prev_group = malloc(n), *phase = malloc(n);
    int handovers = 0;
    double worst_waiting = 0, worst_moving = 0;
    for (uint32_t f = 0; prev && cur && group && prev_group && phase && f < fm_cache_frames(r); f++) {
        ENSURE(fm_cache_read_attr(r, f, FM_ATTR_TET_VERTICES, cur, &err) == FM_OK);
        ENSURE(fm_cache_read_attr(r, f, FM_ATTR_GROUP, group, &err) == FM_OK);
        ENSURE(fm_cache_read_attr(r, f, FM_ATTR_PHASE, phase, &err) == FM_OK);
        int same = 1;
        for (uint64_t a = 1; a < n; a++) same &= group[a] == group[0]; /* the whole chain moves as one group */
        ENSURE_MSG(same, "frame %u: the rows belong to different groups", f);
        if (f > 0 && group[0] != prev_group[0]) { /* a hand-over: the new group starts where the last stopped */
            ENSURE_MSG(group[0] == prev_group[0] + 1, "frame %u: group %d after %d", f, group[0], prev_group[0]);
            handovers++;
            worst_waiting = fmax(worst_waiting, frame_gap(prev, cur, phase, 1, n));
            worst_moving = fmax(worst_moving, frame_gap(prev, cur, phase, 0, n));
        }
        float *t = prev;
        prev = cur, cur = t;
        memcpy(prev_group, group, n);
    }
    printf("  chain: %u frames, %d hand-overs; across them a waiting row moved %.3g, a launched one %.3g\n",
           fm_cache_frames(r), handovers, worst_waiting, worst_moving);
    ENSURE(handovers == 2 && prev_group[0] == 2);
    /* a row still waiting in the new group is where the last group formed it (float rounding of the
     * rest tet's centroid form); one launched since has flown at most a frame at about speed0 */
    ENSURE_MSG(worst_waiting <= 1e-5, "a waiting row jumped %g at a hand-over", worst_waiting);
    ENSURE_MSG(worst_moving < 2 * 6.0 / 24, "a launched row jumped %g at a hand-over", worst_moving);
    free(prev), free(cur), free(group), free(prev_group), free(phase);
    fm_cache_close(r);
}

/* A group scene with one item replaced, and the error it must give. */
static void expect_refusal(const char *name, const char *groups, const char *contains)
{
    char scene[FM_PATH_MAX], text[4096];
    snprintf(scene, sizeof scene, "%s/shot_bad_%s.json", FM_TEST_TMP, name);
    snprintf(text, sizeof text,
             "{\n  \"speed0\": 6,\n  \"groups\": [\n"
             "    { \"name\": \"a\", \"source\": { \"mesh\": \"oct.obj\" }, \"target\": { \"mesh\": \"oct.obj\", \"translate\": [6, 0, 0] } },\n"
             "%s\n  ]\n}\n", groups);
    write_text(scene, text);
    fm_error err = {0};
    static fm_scene_def def, defs[FM_MAX_GROUPS];
    fm_status st = fm_scene_load(scene, &def, &err);
    if (st == FM_OK) st = fm_scene_load_group(scene, NULL, 0, def.group_count - 1, &def, &err);
    if (st == FM_OK) {
        for (int g = 0; g < def.group_count; g++) fm_scene_load_group(scene, NULL, 0, g, &defs[g], &err);
        fm_shot *shot = fm_shot_build(defs, def.group_count, 1, NULL, NULL, &err);
        st = shot ? FM_OK : err.status;
        fm_shot_destroy(shot);
    }
    ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, contains), "%s: status %d, message '%s' (expected '%s')", name, st,
               err.message, contains);
}

static void test_group_refusals(void)
{
    char oct[FM_PATH_MAX];
    snprintf(oct, sizeof oct, "%s/oct.obj", FM_TEST_TMP);
    write_octahedron(oct);
    expect_refusal("later", "    { \"name\": \"b\", \"after\": \"c\", \"source\": { \"mesh\": \"oct.obj\" }, \"target\": { \"mesh\": \"oct.obj\" } }",
                   ":5:20: groups[1].after: \"c\" is not the name of an earlier group");
    expect_refusal("twice", "    { \"name\": \"a\" }", ":5:7: groups[1].name: \"a\" names an earlier group too");
    expect_refusal("shared", "    { \"name\": \"b\", \"time\": { \"frame_rate\": 30 } }", "groups[1].time: the whole shot shares it");
    expect_refusal("mixed", "    { \"name\": \"b\", \"source\": { \"group\": \"a\", \"scale\": 2 }, \"target\": { \"mesh\": \"oct.obj\" } }",
                   "groups[1].source: a source that is a group's formed shape takes no other keys");
    expect_refusal("value", "    { \"name\": \"b\", \"speed0\": -1, \"source\": { \"group\": \"a\" }, \"target\": { \"mesh\": \"oct.obj\" } }",
                   ":5:30: groups[1].speed0: -1 is out of range");
    expect_refusal("together", "    { \"name\": \"b\", \"avoid\": [\"a\"], \"source\": { \"mesh\": \"oct.obj\", \"translate\": [0, 5, 0] },"
                   " \"target\": { \"mesh\": \"oct.obj\", \"translate\": [6, 5, 0] } }",
                   "\"a\" may fly while \"b\" does");
}

int main(void)
{
    RUN_TEST(test_group_refusals);
    RUN_TEST(test_chain_flies_on);
    RUN_TEST(test_castling_shot);
    return test_result();
}
