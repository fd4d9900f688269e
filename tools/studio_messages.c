/* The studio's protocol (docs/studio.md, "Messages"), version STUDIO_PROTOCOL. A page sends small
 * JSON objects {"type": ...}; the server answers with JSON, or a binary frame message for "frame".
 * Whatever a page sends, it gets an error message back and the connection stays up: malformed
 * JSON, an unknown type, a missing or mistyped field, a message too large or binary, an edit the
 * scene loader refuses (its message names the key, as `run --set` does). */
#define _POSIX_C_SOURCE 200809L
#include "studio.h"

#include <civetweb.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

char *studio_status_text(studio *s)
{
    json_t *j = json_pack("{sssIsssIsIsssfsbsbsssbsisfsisisI}", "type", "status", "generation", (json_int_t)s->generation,
                          "stage", s->stage ? s->stage : "starting", "frames", (json_int_t)s->frame_count, "agents",
                          (json_int_t)s->agents, "kind", s->kind, "frame_rate", s->frame_rate, "dirty", s->dirty,
                          "frames_dropped", s->frames_dropped, "failure", s->failure, "model_kept", s->model_kept,
                          "groups_kept", s->groups_kept, "build_seconds", s->build_seconds,
                          "grids_kept", s->grids_kept, "routes_kept", s->routes_kept,
                          "unrun_edits", (json_int_t)s->unrun_edits);
    char *text = j ? json_dumps(j, JSON_COMPACT) : NULL;
    json_decref(j);
    return text;
}

void studio_on_ready(studio *s, struct mg_connection *conn)
{
    const char *name = strrchr(s->path, '/') ? strrchr(s->path, '/') + 1 : s->path;
    pthread_mutex_lock(&s->lock);
    json_t *j = json_pack("{sssisssssOsosb}", "type", "hello", "protocol", STUDIO_PROTOCOL, "mode",
                          s->playback ? "playback" : "live", "name", name, "scene", s->doc ? s->doc : json_null(),
                          "cache", s->playback ? studio_cache_json(s) : json_null(), "render", s->render_dir[0] != 0);
    char *hello = j ? json_dumps(j, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
    char *status = studio_status_text(s);
    char *shapes = s->shapes ? strdup(s->shapes) : NULL;
    pthread_mutex_unlock(&s->lock);
    if (hello) studio_send_text(conn, hello);
    if (shapes) studio_send_text(conn, shapes);
    if (status) studio_send_text(conn, status);
    free(shapes);
    json_decref(j), free(hello), free(status);
}

/* A copy of frame k (sent outside the lock, so a slow page holds up no run). */
static studio_frame *frame_copy(studio *s, uint32_t k, char *msg, size_t size)
{
    pthread_mutex_lock(&s->lock);
    studio_frame *f = NULL;
    if (s->playback) f = k < s->frame_count ? studio_playback_frame(s, k, msg, size) : NULL;
    else if (k < s->frame_count && (f = malloc(sizeof *f + s->frames[k]->bytes)))
        memcpy(f, s->frames[k], sizeof *f + s->frames[k]->bytes);
    if (!f && !msg[0])
        snprintf(msg, size, "frame %u is not %s (%u so far)", k, s->playback ? "in the cache" : "simulated yet",
                 s->frame_count);
    pthread_mutex_unlock(&s->lock);
    return f;
}

static void on_frame(studio *s, struct mg_connection *conn, json_t *m)
{
    json_t *k = json_object_get(m, "k");
    if (!json_is_integer(k) || json_integer_value(k) < 0 || json_integer_value(k) > UINT32_MAX)
        return studio_send_error(conn, "frame", "frame: \"k\" must be a frame number (a whole number >= 0)");
    char msg[2048] = "";
    studio_frame *f = frame_copy(s, (uint32_t)json_integer_value(k), msg, sizeof msg);
    if (!f) return studio_send_error(conn, "frame", "%s", msg);
    studio_send_binary(conn, f->data, f->bytes);
    free(f);
}

/* Every page sees the edited scene (several tabs may watch one studio). */
static void tell_scene(studio *s)
{
    pthread_mutex_lock(&s->lock);
    json_t *j = json_pack("{sssOsb}", "type", "scene", "scene", s->doc, "dirty", s->dirty);
    char *text = j ? json_dumps(j, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
    if (text) studio_broadcast(s, text);
    pthread_mutex_unlock(&s->lock);
    json_decref(j), free(text);
}

static void on_set(studio *s, struct mg_connection *conn, json_t *m)
{
    json_t *key = json_object_get(m, "key"), *value = json_object_get(m, "value");
    if (s->playback) return studio_send_error(conn, "set", "set: a played cache has no scene to edit");
    if (!json_is_string(key) || !json_string_length(key))
        return studio_send_error(conn, "set", "set: \"key\" must be a scene key (\"speed0\", \"path.points\")");
    if (!value) return studio_send_error(conn, "set", "set %s: \"value\" is missing (null removes the key)", json_string_value(key));
    char msg[2048];
    if (studio_live_edit(s, json_string_value(key), value, msg, sizeof msg)) return studio_send_error(conn, "set", "%s", msg);
    tell_scene(s);
}

static void on_save(studio *s, struct mg_connection *conn, json_t *m)
{
    (void)m;
    if (s->playback) return studio_send_error(conn, "save", "save: a played cache has no scene to save");
    char msg[2048];
    if (studio_live_save(s, msg, sizeof msg)) return studio_send_error(conn, "save", "%s", msg);
    json_t *j = json_pack("{ssss}", "type", "saved", "path", s->path);
    char *text = json_dumps(j, JSON_COMPACT);
    pthread_mutex_lock(&s->lock);
    if (text) studio_broadcast(s, text);
    pthread_mutex_unlock(&s->lock);
    json_decref(j), free(text);
    tell_scene(s); /* dirty is now false on every page */
}

static void on_render(studio *s, struct mg_connection *conn, json_t *m)
{
    (void)m;
    char msg[2048];
    if (studio_render_start(s, msg, sizeof msg)) studio_send_error(conn, "render", "%s", msg);
}

static void on_hello(studio *s, struct mg_connection *conn, json_t *m)
{
    (void)s;
    json_t *v = json_object_get(m, "protocol");
    if (!json_is_integer(v) || json_integer_value(v) != STUDIO_PROTOCOL)
        studio_send_error(conn, "hello", "hello: this studio speaks protocol %d; reload the page it serves", STUDIO_PROTOCOL);
}

static const struct {
    const char *type;
    void (*fn)(studio *s, struct mg_connection *conn, json_t *m);
} HANDLERS[] = {{"hello", on_hello}, {"frame", on_frame}, {"set", on_set}, {"save", on_save}, {"render", on_render}};

/* The message's JSON object, or NULL after an error message to the page. */
static json_t *parse(struct mg_connection *conn, int opcode, const char *data, size_t bytes)
{
    if (opcode != MG_WEBSOCKET_OPCODE_TEXT)
        return studio_send_error(conn, "", "messages are JSON text; a binary or fragmented message is refused"), NULL;
    if (bytes > STUDIO_MAX_MESSAGE)
        return studio_send_error(conn, "", "a message of %zu bytes is more than the %d a message may have", bytes,
                                 STUDIO_MAX_MESSAGE), NULL;
    json_error_t jerr;
    json_t *m = json_loadb(data, bytes, JSON_REJECT_DUPLICATES, &jerr);
    if (!m) return studio_send_error(conn, "", "malformed JSON at line %d column %d: %s", jerr.line, jerr.column, jerr.text), NULL;
    if (json_is_object(m) && json_is_string(json_object_get(m, "type"))) return m;
    json_decref(m);
    return studio_send_error(conn, "", "a message is an object with a \"type\" (\"frame\", \"set\", \"save\")"), NULL;
}

void studio_on_message(studio *s, struct mg_connection *conn, int opcode, const char *data, size_t bytes)
{
    json_t *m = parse(conn, opcode, data, bytes);
    if (!m) return;
    const char *type = json_string_value(json_object_get(m, "type"));
    size_t i = 0;
    while (i < sizeof HANDLERS / sizeof HANDLERS[0] && strcmp(HANDLERS[i].type, type)) i++;
    if (i < sizeof HANDLERS / sizeof HANDLERS[0]) HANDLERS[i].fn(s, conn, m);
    else studio_send_error(conn, type, "unknown message type '%.64s' (hello, frame, set, save, render)", type);
    json_decref(m);
}
