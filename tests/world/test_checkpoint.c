/* The checkpoint file's generic reader (src/world/checkpoint.c): a load that keeps one part of the
 * agents (a rank's share, on P ranks) gets exactly those agents' values at the element asked for,
 * whether the part starts on a piece or inside one, and still checks every piece of the file. */
#include "checkpoint.h"
#include "flockmorph/scene.h"
#include "test_macros.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum { AGENTS = 1000, PIECE = 128 };

/* A toy store: one per-agent array and one scalar. */
typedef struct toy {
    float *x;
    int64_t step;
} toy;

static const fm_store_member TOY_MEMBERS[] = {
    {"x", offsetof(toy, x), sizeof(float), 1},
    FM_STORE_SCALAR(toy, step),
};

static const char *no_check(const void *state) { return (void)state, NULL; }

static fm_ckpt_store toy_store(toy *t, const fm_scene_def *def)
{
    return (fm_ckpt_store){.members = TOY_MEMBERS, .member_count = 2, .state = t, .n = AGENTS, .def = def,
                           .model_hash = 42, .model_what = "the toy", .check = no_check, .frames = 3,
                           .piece_agents = PIECE};
}

/* Loads part {first, count, at} into a buffer of at + count + 4 floats set to -1: the part's agents
 * (x = id) at `at`, nothing else touched. */
static void check_part(const char *path, const fm_scene_def *def, int64_t first, int64_t count, int64_t at)
{
    const int64_t len = at + count + 4;
    float *buf = malloc(sizeof(float) * (size_t)len);
    ENSURE(buf != NULL);
    if (!buf) return;
    for (int64_t i = 0; i < len; i++) buf[i] = -1;
    toy t = {buf, 0};
    fm_ckpt_store c = toy_store(&t, def);
    c.parts[0] = (fm_ckpt_part){first, count, at}, c.part_count = 1;
    fm_error err = {0};
    int64_t frames = 0;
    ENSURE_MSG(fm_ckpt_load(path, &c, &frames, &err) == FM_OK, "%s", err.message);
    ENSURE(frames == 3 && t.step == 17);
    int64_t wrong = 0;
    for (int64_t i = 0; i < len; i++) {
        const float want = i >= at && i < at + count ? (float)(first + i - at) : -1.0f;
        wrong += buf[i] != want;
    }
    ENSURE_MSG(wrong == 0, "part %lld + %lld at %lld: %lld values wrong", (long long)first, (long long)count,
               (long long)at, (long long)wrong);
    free(buf);
}

static void test_a_part_of_the_agents(void)
{
    const char *dir = FM_TEST_TMP "/checkpoint_parts", *path = FM_TEST_TMP "/checkpoint_parts/toy.fmck";
    mkdir(dir, 0777);
    fm_scene_def def = fm_default_scene_def();
    float x[AGENTS];
    for (int i = 0; i < AGENTS; i++) x[i] = (float)i;
    toy t = {x, 17};
    const fm_ckpt_store c = toy_store(&t, &def);
    fm_error err = {0};
    ENSURE_MSG(fm_ckpt_save(path, &c, &err) == FM_OK, "%s", err.message);
    check_part(path, &def, 2 * PIECE, 3 * PIECE, 0);  /* whole pieces, as the ranks' shares are */
    check_part(path, &def, 200, 300, 5);              /* starting and ending inside pieces */
    check_part(path, &def, 7 * PIECE, AGENTS - 7 * PIECE, 3); /* the last, short piece */
    check_part(path, &def, 0, 0, 0);                  /* an empty share */

    /* A byte of a piece outside the part changed: the load still reads and checks that piece. */
    FILE *f = fopen(path, "r+b");
    ENSURE(f != NULL);
    if (!f) return;
    /* from the end: the trailer (8 bytes), the piece table (2 words a piece), the scalar (8) and its
     * heading (4 + 4 + 8), then x's last piece: 40 bytes before its end is agent 990's value */
    const long table = (long)(sizeof(uint64_t) * 2 * ((AGENTS + PIECE - 1) / PIECE));
    fseek(f, -8 - table - 8 - 16 - 40, SEEK_END);
    const int byte = fgetc(f);
    fseek(f, -1, SEEK_CUR);
    ENSURE(byte != EOF);
    fputc(byte ^ 0x5A, f);
    fclose(f);
    float buf[PIECE];
    toy u = {buf, 0};
    fm_ckpt_store d = toy_store(&u, &def);
    d.parts[0] = (fm_ckpt_part){0, PIECE, 0}, d.part_count = 1;
    int64_t frames = 0;
    ENSURE(fm_ckpt_load(path, &d, &frames, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "damaged checkpoint"), "%s", err.message);
}

int main(void)
{
    RUN_TEST(test_a_part_of_the_agents);
    return test_result();
}
