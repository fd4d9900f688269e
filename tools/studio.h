/* flockmorph studio (docs/studio.md): one process that runs a scene through `run`'s own path in a
 * worker thread, or plays a cache, and serves the page of web/ and its WebSocket with CivetWeb.
 *
 *   cli_studio.c       the command: options, the page's folder, the address, the signals
 *   studio_server.c    CivetWeb: the token, the Origin check, the page's files, the WebSocket
 *   studio_messages.c  the protocol's messages (docs/studio.md has the table), checked here
 *   studio_live.c      the scene document, its edits and save, the worker's runs, kept frames
 *   studio_frames.c    the binary frame message, from a run's tap or a cache's reader
 *   studio_render.c    the Render button: `flockmorph run` of the saved scene as a child process */
#ifndef FM_STUDIO_H
#define FM_STUDIO_H

#include "cli.h"

#include <jansson.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <sys/types.h>

#define STUDIO_PROTOCOL 1
#define STUDIO_MAX_CLIENTS 16
#define STUDIO_MAX_MESSAGE 65536 /* a page's edit is a few hundred bytes; a sketch of 256 points fits */
#define STUDIO_MAX_KEPT_BYTES ((uint64_t)2 << 30) /* frames kept for the timeline, all together */
#define STUDIO_TOKEN_CHARS 32
#define STUDIO_EDIT_SETTLE 0.05 /* seconds without an edit before a run starts (studio_live.c) */

struct mg_context;
struct mg_connection;

/* One binary frame message (docs/studio.md, "Frames"): ready to send as it is. */
typedef struct studio_frame {
    size_t bytes;
    unsigned char data[];
} studio_frame;

typedef struct studio {
    /* fixed after start */
    int playback;                   /* 1: a cache (.fmc) is played; 0: a scene runs live */
    char path[FM_PATH_MAX];         /* the scene or the cache, as given */
    char page_dir[FM_PATH_MAX];     /* the built page; "" when none was found */
    char token[STUDIO_TOKEN_CHARS + 1];
    char host[256];
    int port;
    char outdir[FM_PATH_MAX];       /* the live runs' scratch OUTDIR (mkdtemp), removed at the end */
    struct mg_context *ctx;
    /* everything below under lock */
    pthread_mutex_t lock;
    struct mg_connection *clients[STUDIO_MAX_CLIENTS];
    int client_count;
    uint32_t generation;            /* the run the kept frames are of; raised by every edit */
    studio_frame **frames;          /* kept frames 0 .. frame_count-1 of this generation */
    uint32_t frame_count, frame_cap;
    uint64_t kept_bytes;
    int frames_dropped;             /* past STUDIO_MAX_KEPT_BYTES: later frames are not kept */
    uint64_t agents;
    char kind[16];                  /* "tets" or "points" */
    double frame_rate;
    const char *stage;              /* "building", "running", "finished", "failed", "cancelled", "playback" */
    char failure[2200];             /* the run's error, when it failed */
    double last_status;             /* when the last status went out (they are sent at most every 0.1 s) */
    /* live */
    json_t *doc;                    /* the scene document as edited; Save writes it */
    char *shapes;                   /* the "shapes" message of the latest run (meshes as placed) */
    int dirty;                      /* edited since the last save */
    fm_scene_def *def;              /* the doc read as the loader reads it: what the next run runs */
    fm_scene_def *first;            /* the scene as the studio started, then a shot's every group (first_count
                                       in all): the files it may read */
    int first_count;
    int run_wanted;                 /* the worker should start a run of def (the latest edit wins) */
    double last_edit;               /* when the last edit was accepted (cli_seconds) */
    cli_model_keep keep;            /* the worker's: the model's costly part, for the next edit's run */
    int model_kept;                 /* this run's model build reused it (0 until the build is done) */
    int groups_kept;                /* ... a shot: of how many groups (a scene: 0 or 1) */
    int grids_kept, routes_kept;    /* of how many groups the obstacles' grid, and the routed path, were kept */
    char *run_text;                 /* what the current generation's run simulates (studio_live.c's run_text) */
    int64_t unrun_edits;            /* edits accepted that left it so: no run started for them */
    double build_seconds;           /* this run's model build time (0 until it is done) */
    int quit;
    volatile sig_atomic_t stop;     /* cancels the worker's run at the next frame boundary */
    pthread_t worker;
    pthread_cond_t wake;
    int worker_started;
    /* playback */
    fm_cache_reader *reader;        /* used under lock (it keeps the last decoded frame) */
    /* Render (--output DIR) */
    char render_dir[FM_PATH_MAX];   /* "" without --output: no Render */
    int rendering, render_joinable;
    pid_t render_pid;
    int render_fd;                  /* the child's stdout and stderr */
    pthread_t render_thread;
} studio;

/* studio_server.c */
int studio_server_start(studio *s);          /* 0 or an exit status, printed */
void studio_server_stop(studio *s);
/* Sends a text message to every page; with lock held. */
void studio_broadcast(studio *s, const char *text);
/* Sends to one page (any thread: CivetWeb locks the connection). */
void studio_send_text(struct mg_connection *conn, const char *text);
void studio_send_binary(struct mg_connection *conn, const void *data, size_t bytes);
/* {"type": "error", "message": ..., "request": ...}: what a page's bad message gets. */
void studio_send_error(struct mg_connection *conn, const char *request, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* studio_messages.c */
void studio_on_ready(studio *s, struct mg_connection *conn);   /* hello, then the status */
void studio_on_message(studio *s, struct mg_connection *conn, int opcode, const char *data, size_t bytes);
char *studio_status_text(studio *s);                           /* with lock held; free() it */

/* studio_live.c */
int studio_live_open(studio *s);             /* reads the scene, starts the worker's first run */
void studio_live_close(studio *s);
/* Applies {key: value} to the scene document, checked as the loader checks a file; on success the
 * run starts over. 0, or -1 with the loader's message (naming the key) in msg. */
int studio_live_edit(studio *s, const char *key, const json_t *value, char *msg, size_t size);
int studio_live_save(studio *s, char *msg, size_t size); /* atomically: PATH.partial, fsync, rename */
/* The scene file's text as Save writes it (a new string). */
char *studio_scene_text(const json_t *doc);
/* Keeps a frame of the current generation (with lock held); takes f. */
void studio_keep_frame(studio *s, studio_frame *f);

/* studio_render.c */
int studio_render_start(studio *s, char *msg, size_t size); /* 0, or -1 with why not in msg */
void studio_render_stop(studio *s);

/* studio_frames.c */
/* A frame message of `frame` from attribute arrays (the writer's order), orientation left out. */
studio_frame *studio_frame_make(uint32_t generation, uint32_t frame, uint64_t agents, int attr_count,
                                const fm_cache_attr_info *const *attrs, const void *const *data);
int studio_playback_open(studio *s);         /* 0 or an exit status, printed */
/* Frame k of the played cache (with lock held); NULL with msg on failure. */
studio_frame *studio_playback_frame(studio *s, uint32_t k, char *msg, size_t size);
/* What the page shows beside a played cache: its header's facts and stats.json's plain values from
 * beside it ("stats": null without one). With lock held. */
json_t *studio_cache_json(studio *s);
/* "tets" when the attributes hold tet vertices, else "points". */
const char *studio_kind(int attr_count, const fm_cache_attr_info *const *attrs);

#endif
