#include "json_locate.h"

#include <string.h>

typedef struct cursor {
    const char *s;
    long i;
} cursor;

static void skip_ws(cursor *c)
{
    while (c->s[c->i] == ' ' || c->s[c->i] == '\t' || c->s[c->i] == '\n' || c->s[c->i] == '\r') c->i++;
}

/* Reads a string token into buf (escapes resolved for ASCII; others replaced by '?'). */
static void read_string(cursor *c, char *buf, int cap)
{
    int n = 0;
    c->i++; /* opening quote */
    while (c->s[c->i] && c->s[c->i] != '"') {
        char ch = c->s[c->i++];
        if (ch == '\\') {
            char e = c->s[c->i++];
            ch = e == 'n' ? '\n' : e == 't' ? '\t' : e == 'r' ? '\r' : e == 'b' ? '\b' : e == 'f' ? '\f' : e;
            if (e == 'u') {
                ch = '?';
                for (int k = 0; k < 4 && c->s[c->i]; k++) c->i++;
            }
        }
        if (n + 1 < cap) buf[n++] = ch;
    }
    if (c->s[c->i] == '"') c->i++;
    buf[n] = 0;
}

static void skip_value(cursor *c);

static void skip_container(cursor *c, char close)
{
    c->i++;
    skip_ws(c);
    while (c->s[c->i] && c->s[c->i] != close) {
        if (close == '}') {
            char key[8];
            read_string(c, key, sizeof key);
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
    else if (ch == '"') {
        char tmp[2];
        read_string(c, tmp, sizeof tmp);
    } else
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
        char name[256];
        read_string(c, name, sizeof name);
        skip_ws(c);
        c->i++; /* ':' */
        skip_ws(c);
        if (strcmp(name, key) == 0) {
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
