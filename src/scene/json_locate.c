#include "json_locate.h"

#include <stdlib.h>
#include <string.h>

typedef struct cursor {
    const char *s;
    long i;
} cursor;

static void skip_ws(cursor *c)
{
    while (c->s[c->i] == ' ' || c->s[c->i] == '\t' || c->s[c->i] == '\n' || c->s[c->i] == '\r') c->i++;
}

/* Appends code point cp to buf as UTF-8 (jansson gives keys as UTF-8). */
static int put_utf8(char *buf, int n, unsigned cp)
{
    if (cp < 0x80) buf[n++] = (char)cp;
    else if (cp < 0x800) buf[n++] = (char)(0xC0 | cp >> 6), buf[n++] = (char)(0x80 | (cp & 0x3F));
    else if (cp < 0x10000)
        buf[n++] = (char)(0xE0 | cp >> 12), buf[n++] = (char)(0x80 | (cp >> 6 & 0x3F)), buf[n++] = (char)(0x80 | (cp & 0x3F));
    else
        buf[n++] = (char)(0xF0 | cp >> 18), buf[n++] = (char)(0x80 | (cp >> 12 & 0x3F)),
        buf[n++] = (char)(0x80 | (cp >> 6 & 0x3F)), buf[n++] = (char)(0x80 | (cp & 0x3F));
    return n;
}

static unsigned read_hex4(cursor *c)
{
    unsigned v = 0;
    for (int k = 0; k < 4 && c->s[c->i]; k++) {
        char h = c->s[c->i++];
        v = v * 16 + (unsigned)(h >= 'a' ? h - 'a' + 10 : h >= 'A' ? h - 'A' + 10 : h - '0');
    }
    return v;
}

/* Reads a string token and returns it decoded (escapes resolved, \u as UTF-8) in a malloc'd
 * buffer, or NULL when out of memory (the cursor still moves past the token). */
static char *read_string(cursor *c)
{
    long start = c->i + 1, end = start;
    while (c->s[end] && c->s[end] != '"') end += c->s[end] == '\\' && c->s[end + 1] ? 2 : 1;
    char *buf = malloc((size_t)(end - start) * 2 + 8); /* \uXXXX (6 bytes) never decodes to more than 4 */
    int n = 0;
    c->i = start;
    while (c->s[c->i] && c->s[c->i] != '"') {
        char ch = c->s[c->i++];
        if (ch != '\\') {
            if (buf) buf[n++] = ch;
            continue;
        }
        char e = c->s[c->i++];
        unsigned cp = e == 'n' ? '\n' : e == 't' ? '\t' : e == 'r' ? '\r' : e == 'b' ? '\b' : e == 'f' ? '\f' : (unsigned char)e;
        if (e == 'u') {
            cp = read_hex4(c);
            if (cp >= 0xD800 && cp < 0xDC00 && c->s[c->i] == '\\' && c->s[c->i + 1] == 'u') { /* surrogate pair */
                c->i += 2;
                cp = 0x10000 + ((cp - 0xD800) << 10) + (read_hex4(c) - 0xDC00);
            }
        }
        if (buf) n = put_utf8(buf, n, cp);
    }
    if (c->s[c->i] == '"') c->i++;
    if (buf) buf[n] = 0;
    return buf;
}

static void skip_value(cursor *c);

static void skip_container(cursor *c, char close)
{
    c->i++;
    skip_ws(c);
    while (c->s[c->i] && c->s[c->i] != close) {
        if (close == '}') {
            free(read_string(c));
            skip_ws(c);
            c->i++; /* ':' */
        }
        skip_value(c);
        skip_ws(c);
        if (c->s[c->i] == ',') c->i++, skip_ws(c);
    }
    if (c->s[c->i]) c->i++;
}

static void skip_value(cursor *c)
{
    skip_ws(c);
    char ch = c->s[c->i];
    if (ch == '{') skip_container(c, '}');
    else if (ch == '[') skip_container(c, ']');
    else if (ch == '"') free(read_string(c));
    else
        while (c->s[c->i] && !strchr(",]} \t\r\n", c->s[c->i])) c->i++;
}

/* Moves the cursor onto the member `key` of the object at the cursor (onto the key itself when
 * stop_at_key). Returns 0 if found. */
static int enter_member(cursor *c, const char *key, int stop_at_key)
{
    if (c->s[c->i] != '{') return -1;
    c->i++;
    skip_ws(c);
    while (c->s[c->i] == '"') {
        long key_pos = c->i;
        char *name = read_string(c);
        int match = name && strcmp(name, key) == 0;
        free(name);
        skip_ws(c);
        c->i++; /* ':' */
        skip_ws(c);
        if (match) {
            if (stop_at_key) c->i = key_pos;
            return 0;
        }
        skip_value(c);
        skip_ws(c);
        if (c->s[c->i] == ',') c->i++, skip_ws(c);
    }
    return -1;
}

static int enter_element(cursor *c, int index)
{
    if (c->s[c->i] != '[') return -1;
    c->i++;
    skip_ws(c);
    for (int k = 0; c->s[c->i] && c->s[c->i] != ']'; k++) {
        if (k == index) return 0;
        skip_value(c);
        skip_ws(c);
        if (c->s[c->i] == ',') c->i++, skip_ws(c);
    }
    return -1;
}

int fm_json_locate(const char *text, const fm_json_step *path, int depth, int want_key, int *line,
                   int *col)
{
    cursor c = {text, 0};
    *line = *col = 0;
    skip_ws(&c);
    for (int d = 0; d < depth; d++) {
        int last = d == depth - 1;
        int rc = path[d].key ? enter_member(&c, path[d].key, last && want_key) : enter_element(&c, path[d].index);
        if (rc != 0) return -1;
    }
    int ln = 1, cl = 1;
    for (long i = 0; i < c.i; i++) {
        if (text[i] == '\n') ln++, cl = 1;
        else cl++;
    }
    *line = ln;
    *col = cl;
    return 0;
}
