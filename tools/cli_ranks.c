/* The ranks of one job check that they run the same job (docs/scale-out.md, "Ranks that disagree").
 *
 * mpirun starts P processes, each with its own command line and environment: an MPMD launch
 * (`mpirun -n 1 A : -n 1 B`), a per-rank `-x`, or machines with different files can give ranks
 * different scenes or options. Each rank would then simulate its share of another run, and the
 * cache would match neither (or the collectives would hang). So before any work every rank
 * describes its job (the scene as loaded, the options that change the output, the FM_ environment)
 * and compares the description with rank 0's; one difference stops every rank with exit 1, before
 * anything in the output directory (a checkpoint, a previous cache) is touched. */
#define _POSIX_C_SOURCE 200809L
#include "checkpoint.h"     /* fm_hash_* */
#include "cli.h"
#include "scene_internal.h" /* fm_scene_def_feed */

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

extern char **environ;

/* A job's description: items of three NUL-terminated strings each, back to back: what it is (for
 * messages), what is compared, what a message shows of it. */
typedef struct job_text {
    char *bytes;
    size_t size, capacity;
    int failed; /* out of memory: the description is incomplete */
} job_text;

typedef struct job_item {
    const char *name, *compared, *shown;
} job_item;

static void add_string(job_text *t, const char *s)
{
    size_t n = strlen(s) + 1;
    if (t->size + n > t->capacity) {
        size_t capacity = 2 * (t->size + n) + 256;
        char *grown = realloc(t->bytes, capacity);
        if (!grown) {
            t->failed = 1;
            return;
        }
        t->bytes = grown, t->capacity = capacity;
    }
    memcpy(t->bytes + t->size, s, n);
    t->size += n;
}

static void add_item(job_text *t, const char *name, const char *compared, const char *shown)
{
    add_string(t, name), add_string(t, compared), add_string(t, shown);
}

/* The mesh files a scene names: fm_scene_def_feed leaves them out (where a file lies does not
 * change a checkpoint), but ranks that read different meshes run different jobs. */
static void feed_mesh_paths(const fm_scene_def *def, fm_hash *h)
{
    fm_hash_bytes(def->source.path, strlen(def->source.path) + 1, h);
    fm_hash_bytes(def->target.path, strlen(def->target.path) + 1, h);
    for (int i = 0; i < def->obstacle_count; i++)
        fm_hash_bytes(def->obstacles[i].path, strlen(def->obstacles[i].path) + 1, h);
    fm_hash_bytes(def->flock.deform_sequence, strlen(def->flock.deform_sequence) + 1, h);
    fm_hash_bytes(def->target_motion.sequence, strlen(def->target_motion.sequence) + 1, h);
}

static void feed_scene(const fm_scene_def *def, fm_hash *h)
{
    fm_scene_def_feed(def, fm_hash_bytes, h);
    feed_mesh_paths(def, h);
}

/* A hash of every parameter of the scene as loaded (after --set and the wedge), each group's of a
 * shot too, and of the mesh paths; 0 when out of memory. */
static int scene_hash(const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def, uint64_t *hash)
{
    fm_scene_def *group = def->group_count > 0 ? malloc(sizeof *group) : NULL;
    fm_hash *h = def->group_count == 0 || group ? fm_hash_begin() : NULL;
    if (!h) {
        free(group);
        return 0;
    }
    feed_scene(def, h);
    for (int g = 0; g < def->group_count; g++) {
        fm_error ignored = {0};
        if (fm_scene_load_group(o->scene, ov->set, ov->count, g, group, &ignored) == FM_OK) feed_scene(group, h);
        else fm_hash_bytes(ignored.message, strlen(ignored.message), h); /* the build reports it */
    }
    free(group);
    *hash = fm_hash_end(h);
    return 1;
}

/* How the command line chose the scene: the file, the overrides and the wedge. */
static void scene_arguments(const cli_run_options *o, char *out, size_t size)
{
    size_t n = (size_t)snprintf(out, size, "%s", o->scene);
    for (int i = 0; i < o->set_count && n < size; i++) n += (size_t)snprintf(out + n, size - n, " --set %s", o->sets[i]);
    if (o->wedge_file && n < size) snprintf(out + n, size - n, " --wedge-file %s --wedge %ld", o->wedge_file, o->wedge);
}

static void add_number_item(job_text *t, const char *name, long value, const char *unset)
{
    char text[32];
    snprintf(text, sizeof text, "%ld", value);
    add_item(t, name, value < 0 ? unset : text, value < 0 ? unset : text);
}

/* FM_ variables, by name: each is compared, but FM_RANK_OUTPUT (it only lets ranks other than 0
 * print), whatever it does, since any of them may change what a rank computes. */
static int by_name(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static void add_environment(job_text *t)
{
    size_t count = 0;
    for (char **e = environ; *e; e++) count += !strncmp(*e, "FM_", 3) && strncmp(*e, "FM_RANK_OUTPUT=", 15);
    char **vars = count ? malloc(count * sizeof *vars) : NULL;
    if (count && !vars) {
        t->failed = 1;
        return;
    }
    size_t k = 0;
    for (char **e = environ; *e; e++)
        if (!strncmp(*e, "FM_", 3) && strncmp(*e, "FM_RANK_OUTPUT=", 15)) vars[k++] = *e;
    qsort(vars, count, sizeof *vars, by_name);
    for (size_t i = 0; i < count; i++) {
        char name[256];
        const char *eq = strchr(vars[i], '=');
        snprintf(name, sizeof name, "the environment variable %.*s", (int)(eq - vars[i]), vars[i]);
        add_item(t, name, eq + 1, eq + 1);
    }
    free(vars);
}

static void describe_job(const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def, job_text *t)
{
    char hash[32], arguments[1024];
    uint64_t h = 0;
    if (!scene_hash(o, ov, def, &h)) t->failed = 1;
    snprintf(hash, sizeof hash, "%016llx", (unsigned long long)h);
    scene_arguments(o, arguments, sizeof arguments);
    add_item(t, "the scene as loaded", hash, arguments);
    add_item(t, "-o", o->outdir, o->outdir);
    add_item(t, "--resume", o->resume ? "given" : "not given", o->resume ? "given" : "not given");
    add_number_item(t, "--stop-after-frame", o->stop_after_frame, "not given");
    add_number_item(t, "--checkpoint-every", o->checkpoint_every, "not given");
    add_item(t, "the flockmorph version", FM_VERSION_STRING, FM_VERSION_STRING);
    add_environment(t);
}

/* The items of a description; *count of them (the array malloc'd, NULL when out of memory). */
static job_item *job_items(const job_text *t, size_t *count)
{
    size_t strings = 0;
    for (size_t i = 0; i < t->size; i++) strings += t->bytes[i] == 0;
    *count = strings / 3;
    job_item *items = malloc((*count + 1) * sizeof *items);
    const char *p = t->bytes;
    for (size_t i = 0; items && i < *count; i++) {
        items[i].name = p, p += strlen(p) + 1;
        items[i].compared = p, p += strlen(p) + 1;
        items[i].shown = p, p += strlen(p) + 1;
    }
    return items;
}

static const job_item *find_item(const job_item *items, size_t count, const char *name)
{
    for (size_t i = 0; i < count; i++)
        if (!strcmp(items[i].name, name)) return &items[i];
    return NULL;
}

static fm_status differs(const job_item *root, const job_item *mine, fm_error *err)
{
    const job_item *either = root ? root : mine;
    const int same_words = root && mine && !strcmp(root->shown, mine->shown);
    return fm_fail(err, FM_ERR_USAGE, "rank %d of %d does not run rank 0's job: %s differs (rank 0: %.700s; rank %d: "
                   "%.700s)%s; start every rank with the same scene, options and FM_ environment variables "
                   "(docs/scale-out.md)", fm_dist_rank(cli_dist), fm_dist_size(cli_dist), either->name,
                   root ? root->shown : "unset", fm_dist_rank(cli_dist), mine ? mine->shown : "unset",
                   same_words ? ", from the same arguments: the files they name differ" : "");
}

/* The first item, in rank 0's order and then this rank's, that the two do not share. */
static fm_status compare_jobs(const job_text *root_text, const job_text *mine_text, fm_error *err)
{
    size_t nr = 0, nm = 0;
    job_item *root = job_items(root_text, &nr), *mine = job_items(mine_text, &nm);
    fm_status st = root && mine ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory comparing the ranks' jobs");
    for (size_t i = 0; st == FM_OK && i < nr; i++) {
        const job_item *m = find_item(mine, nm, root[i].name);
        if (!m || strcmp(m->compared, root[i].compared)) st = differs(&root[i], m, err);
    }
    for (size_t i = 0; st == FM_OK && i < nm; i++)
        if (!find_item(root, nr, mine[i].name)) st = differs(NULL, &mine[i], err);
    free(root), free(mine);
    return st;
}

/* Rank 0's description on every rank: its size, then its bytes. */
static fm_status share_root_job(const job_text *mine, job_text *root, fm_error *err)
{
    uint64_t size = mine->size;
    fm_dist_bcast(cli_dist, &size, sizeof size, 0);
    fm_status st = FM_OK;
    if (cli_is_root()) *root = *mine;
    else if ((root->bytes = malloc(size ? size : 1))) root->size = size;
    else st = fm_fail(err, FM_ERR_MEMORY, "out of memory for rank 0's job description");
    if ((st = fm_dist_agree(cli_dist, st, err)) != FM_OK) return st;
    fm_dist_bcast(cli_dist, root->bytes, size, 0);
    return FM_OK;
}

int cli_ranks_agree(int rc, const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def)
{
    rc = cli_agree(rc, NULL); /* a rank that failed before (its command line, its scene) stops every rank */
    if (rc || fm_dist_size(cli_dist) == 1) return rc;
    fm_error err = {0};
    job_text mine = {0}, root = {0};
    describe_job(o, ov, def, &mine);
    fm_status st = mine.failed ? fm_fail(&err, FM_ERR_MEMORY, "out of memory describing the job") : FM_OK;
    if (fm_dist_agree(cli_dist, st, &err) == FM_OK) { /* every rank has a description to share */
        st = share_root_job(&mine, &root, &err);
        if (st == FM_OK && !cli_is_root()) st = compare_jobs(&root, &mine, &err);
    }
    if (!cli_is_root()) free(root.bytes);
    free(mine.bytes);
    return cli_agree((int)st, &err);
}
