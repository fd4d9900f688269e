/* The studio's server: CivetWeb from Debian (libcivetweb-dev), not a hand-written one.
 *
 * Safety (docs/studio.md, "Safety"), as Jupyter does it: every request's path starts with the
 * random token the printed address holds (/TOKEN/...), so another program or a web page that
 * does not know it gets 403; a request or WebSocket with an Origin header other than this
 * server's own address is refused (a page elsewhere cannot drive the studio through the user's
 * browser); only the built page's own files are served, by name, from its one folder. */
#define _POSIX_C_SOURCE 200809L
#include "studio.h"

#include <civetweb.h>

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Constant time, so the token cannot be guessed a character at a time from response times. */
static int same_token(const char *a, const char *b, size_t n)
{
    unsigned char diff = 0;
    for (size_t i = 0; i < n; i++) diff |= (unsigned char)(a[i] ^ b[i]);
    return diff == 0;
}

/* The URI's part after "/TOKEN/", or NULL if it does not carry the token. */
static const char *after_token(const studio *s, const char *uri)
{
    if (!uri || uri[0] != '/' || strlen(uri + 1) < STUDIO_TOKEN_CHARS) return NULL;
    if (!same_token(uri + 1, s->token, STUDIO_TOKEN_CHARS) || uri[1 + STUDIO_TOKEN_CHARS] != '/') return NULL;
    return uri + 2 + STUDIO_TOKEN_CHARS;
}

/* No Origin (a program, or a same-origin GET) or this server's own address. */
static int origin_allowed(const studio *s, const struct mg_connection *conn)
{
    const char *origin = mg_get_header(conn, "Origin");
    if (!origin) return 1;
    const char *hosts[] = {"127.0.0.1", "localhost", "[::1]", s->host};
    char own[320];
    for (size_t i = 0; i < sizeof hosts / sizeof hosts[0]; i++) {
        snprintf(own, sizeof own, "http://%s:%d", hosts[i], s->port);
        if (!strcmp(origin, own)) return 1;
    }
    /* Listening on every address (--host 0.0.0.0), the page's own origin is whichever address the
     * browser used: the one its request was sent to (the token still guards it). */
    const char *host = mg_get_header(conn, "Host");
    if (!strcmp(s->host, "0.0.0.0") && host) {
        snprintf(own, sizeof own, "http://%.300s", host);
        return !strcmp(origin, own);
    }
    return 0;
}

/* A file name of the built page: letters, digits, '.', '-', '_', not starting with '.' (no
 * folders, no "..", no hidden files). */
static int page_file_name(const char *name)
{
    if (!name[0] || name[0] == '.' || strlen(name) > 128) return 0;
    for (const char *c = name; *c; c++)
        if (!((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') || strchr("._-", *c)))
            return 0;
    return 1;
}

static const char *const PAGE_HEADERS =
    "Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nReferrer-Policy: no-referrer\r\n"
    "Content-Security-Policy: default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; "
    "font-src 'self' data:; "
    "connect-src 'self'\r\n";

static int serve_page_file(studio *s, struct mg_connection *conn, const char *name)
{
    char path[FM_PATH_MAX + 160];
    struct stat st;
    if (!page_file_name(name)) return mg_send_http_error(conn, 404, "not a file of the page\n"), 404;
    snprintf(path, sizeof path, "%s/%s", s->page_dir, name);
    if (!s->page_dir[0] || stat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
        if (strcmp(name, "index.html")) return mg_send_http_error(conn, 404, "not a file of the page\n"), 404;
        return mg_send_http_error(conn, 500, "flockmorph studio: the page is not built. tools/setup.sh builds it "
                                             "(it needs Node and npm: docs/studio.md)\n"), 500;
    }
    mg_send_mime_file2(conn, path, NULL, PAGE_HEADERS);
    return 200;
}

static int on_request(struct mg_connection *conn, void *cbdata)
{
    studio *s = cbdata;
    const struct mg_request_info *ri = mg_get_request_info(conn);
    const char *rest = after_token(s, ri->local_uri);
    if (!rest) return mg_send_http_error(conn, 403, "flockmorph studio: this address needs the token the studio printed\n"), 403;
    if (!origin_allowed(s, conn)) return mg_send_http_error(conn, 403, "flockmorph studio: foreign Origin refused\n"), 403;
    if (strcmp(ri->request_method, "GET") && strcmp(ri->request_method, "HEAD"))
        return mg_send_http_error(conn, 405, "flockmorph studio: the page's files are read with GET\n"), 405;
    return serve_page_file(s, conn, rest[0] ? rest : "index.html");
}

/* ---------------------------------------------------------------- the WebSocket */

static int ws_connect(const struct mg_connection *conn, void *cbdata)
{
    studio *s = cbdata;
    if (!origin_allowed(s, conn)) return fprintf(stderr, "flockmorph studio: a WebSocket from a foreign Origin was refused\n"), 1;
    pthread_mutex_lock(&s->lock);
    int full = s->client_count >= STUDIO_MAX_CLIENTS;
    pthread_mutex_unlock(&s->lock);
    return full; /* 1 closes it */
}

static void ws_ready(struct mg_connection *conn, void *cbdata)
{
    studio *s = cbdata;
    pthread_mutex_lock(&s->lock);
    if (s->client_count < STUDIO_MAX_CLIENTS) s->clients[s->client_count++] = conn;
    pthread_mutex_unlock(&s->lock);
    studio_on_ready(s, conn);
}

static int ws_data(struct mg_connection *conn, int bits, char *data, size_t bytes, void *cbdata)
{
    int opcode = bits & 0x0f, fin = bits & 0x80;
    if (opcode == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) return 0;
    if (opcode == MG_WEBSOCKET_OPCODE_PING || opcode == MG_WEBSOCKET_OPCODE_PONG) return 1;
    /* A fragmented message is refused once, at its first frame; its continuations are dropped. */
    if (opcode == MG_WEBSOCKET_OPCODE_CONTINUATION) return 1;
    studio_on_message(cbdata, conn, fin ? opcode : MG_WEBSOCKET_OPCODE_CONTINUATION, data, bytes);
    return 1;
}

static void ws_close(const struct mg_connection *conn, void *cbdata)
{
    studio *s = cbdata;
    pthread_mutex_lock(&s->lock);
    for (int i = 0; i < s->client_count; i++)
        if (s->clients[i] == conn) s->clients[i] = s->clients[--s->client_count];
    pthread_mutex_unlock(&s->lock);
}

void studio_broadcast(studio *s, const char *text)
{
    for (int i = 0; i < s->client_count; i++) studio_send_text(s->clients[i], text);
}

void studio_send_text(struct mg_connection *conn, const char *text)
{
    mg_websocket_write(conn, MG_WEBSOCKET_OPCODE_TEXT, text, strlen(text));
}

void studio_send_binary(struct mg_connection *conn, const void *data, size_t bytes)
{
    mg_websocket_write(conn, MG_WEBSOCKET_OPCODE_BINARY, data, bytes);
}

void studio_send_error(struct mg_connection *conn, const char *request, const char *fmt, ...)
{
    char msg[2304];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    json_t *j = json_pack("{ssssss}", "type", "error", "request", request, "message", msg);
    char *text = j ? json_dumps(j, JSON_COMPACT) : NULL;
    if (text) studio_send_text(conn, text);
    json_decref(j), free(text);
}

/* ---------------------------------------------------------------- start and stop */

static int log_message(const struct mg_connection *conn, const char *message)
{
    (void)conn;
    fprintf(stderr, "flockmorph studio: %s\n", message);
    return 1;
}

int studio_server_start(studio *s)
{
    char ports[300], ws_uri[64];
    snprintf(ports, sizeof ports, "%s:%d", s->host, s->port);
    /* One worker thread per open WebSocket (CivetWeb's model), and a few for the page's files. */
    const char *options[] = {"listening_ports", ports, "num_threads", "24", "request_timeout_ms", "10000",
                             "websocket_timeout_ms", "86400000", "enable_directory_listing", "no", NULL};
    struct mg_callbacks callbacks = {0};
    callbacks.log_message = log_message;
    mg_init_library(0);
    if (!(s->ctx = mg_start(&callbacks, s, options)))
        return fprintf(stderr, "flockmorph: studio: cannot listen on %s (in use? --port N picks another; 0: any free one)\n",
                       ports), FM_ERR_USAGE;
    struct mg_server_port bound[4];
    if (mg_get_server_ports(s->ctx, 4, bound) > 0) s->port = bound[0].port; /* --port 0: the one given */
    snprintf(ws_uri, sizeof ws_uri, "/%s/ws", s->token);
    mg_set_websocket_handler(s->ctx, ws_uri, ws_connect, ws_ready, ws_data, ws_close, s);
    mg_set_request_handler(s->ctx, "/", on_request, s);
    return 0;
}

void studio_server_stop(studio *s)
{
    if (s->ctx) mg_stop(s->ctx);
    s->ctx = NULL;
    mg_exit_library();
}
