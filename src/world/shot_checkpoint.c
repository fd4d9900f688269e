/* A shot's checkpoint: the shot's file and its groups' (shot_checkpoint.h). */
#define _POSIX_C_SOURCE 200809L
#include "shot_checkpoint.h"
#include "scene_internal.h"

#include <dirent.h>
#include <stdio.h>
#include <string.h>

static void group_path(char *out, size_t size, const char *path, int64_t frames, int g)
{
    snprintf(out, size, "%s.f%lld.g%d", path, (long long)frames, g);
}

static void remove_set(const char *path, int64_t frames, int groups)
{
    char name[FM_PATH_MAX + 64];
    for (int g = 0; g < groups; g++) group_path(name, sizeof name, path, frames, g), remove(name);
}

fm_status fm_shot_ckpt_save(const char *path, const fm_shot_ckpt *c, int64_t *saved, fm_error *err)
{
    const int64_t frames = c->shot.frames;
    char name[FM_PATH_MAX + 64];
    fm_status st = FM_OK;
    for (int g = 0; g < c->groups && st == FM_OK; g++) {
        group_path(name, sizeof name, path, frames, g);
        st = c->save_group(c->user, g, name, frames, err); /* agreed by every rank */
    }
    if (st == FM_OK) st = fm_ckpt_save(path, &c->shot, err);
    if (st != FM_OK) return st;
    if (*saved > 0 && *saved != frames && fm_dist_rank(c->shot.dist) == 0) remove_set(path, *saved, c->groups);
    *saved = frames;
    return FM_OK;
}

fm_status fm_shot_ckpt_load(const char *path, fm_shot_ckpt *c, int64_t *frames, fm_error *err)
{
    fm_status st = fm_ckpt_load(path, &c->shot, frames, err);
    char name[FM_PATH_MAX + 64];
    for (int g = 0; g < c->groups && st == FM_OK; g++) {
        int64_t held = 0;
        group_path(name, sizeof name, path, *frames, g);
        st = c->load_group(c->user, g, name, &held, err);
        if (st == FM_OK && held != *frames)
            st = fm_fail(err, FM_ERR_INPUT, "%s: holds %lld frames where %s holds %lld: the shot's checkpoint files "
                         "do not belong together; run again without --resume", name, (long long)held, path,
                         (long long)*frames);
    }
    return st;
}

void fm_shot_ckpt_remove_groups(const char *path)
{
    char dir[FM_PATH_MAX + 1], prefix[FM_PATH_MAX + 8], name[2 * FM_PATH_MAX + 8];
    const char *slash = strrchr(path, '/');
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - path) + 1 : 1, slash ? path : ".");
    snprintf(prefix, sizeof prefix, "%s.f", slash ? slash + 1 : path);
    DIR *d = opendir(dir);
    if (!d) return;
    for (struct dirent *e; (e = readdir(d));) {
        const char *rest = e->d_name + strlen(prefix);
        if (strncmp(e->d_name, prefix, strlen(prefix)) != 0 || !strstr(rest, ".g")) continue;
        snprintf(name, sizeof name, "%s%s%s", dir, slash ? "" : "/", e->d_name);
        remove(name);
    }
    closedir(d);
}

const char *fm_shot_ckpt_check_clock(int groups, int64_t step, const int *started, const int *ended, const int *writes,
                                     const int64_t *start_step, const int64_t *end_step)
{
    for (int g = 0; g < groups; g++)
        if ((unsigned)started[g] > 1 || (unsigned)ended[g] > 1 || (unsigned)writes[g] > 1 || start_step[g] > step ||
            end_step[g] > step || (ended[g] && !started[g]))
            return "the groups' clock out of range";
    return step < 0 ? "the groups' clock out of range" : NULL;
}

uint64_t fm_shot_ckpt_groups_hash(const fm_scene_def *defs, const int64_t *agents, int count)
{
    fm_hash *h = fm_hash_begin();
    if (!h) return 0;
    fm_hash_bytes(&count, sizeof count, h);
    for (int g = 0; g < count; g++) fm_scene_def_feed(&defs[g], fm_hash_bytes, h), fm_hash_bytes(&agents[g], sizeof agents[g], h);
    return fm_hash_end(h);
}
