/* The element counts a mesh file declares up front, checked against the file's size before the
 * file goes to assimp. assimp allocates from a PLY or OFF header's counts (and a binary STL's
 * triangle count) before it reads a single element, so a 165-byte PLY that claims 2e9 vertices
 * would make it try to allocate tens of GiB. Every element takes a least number of bytes (below),
 * so a file cannot hold more elements than its size allows; a header that claims more is damaged. */
#define _POSIX_C_SOURCE 200809L
#include "geom.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* Counts above this are refused outright (so the byte sums below cannot overflow). */
#define MAX_COUNT ((uint64_t)1 << 40)

static fm_status too_many(const char *name, const char *what, uint64_t count, uint64_t need, uint64_t have,
                          fm_error *err)
{
    return fm_fail(err, FM_ERR_INPUT, "%s: the file declares %llu %s, which take at least %llu bytes, but it holds "
                   "%llu: it is damaged or cut short", name, (unsigned long long)count, what,
                   (unsigned long long)need, (unsigned long long)have);
}

/* ---------------------------------------------------------------- PLY */

/* Bytes of a binary PLY scalar type; 0 if unknown. */
static int ply_type_bytes(const char *t)
{
    static const char *const names[][2] = {{"char", "int8"}, {"uchar", "uint8"}, {"short", "int16"},
                                           {"ushort", "uint16"}, {"int", "int32"}, {"uint", "uint32"},
                                           {"float", "float32"}, {"double", "float64"}};
    static const int bytes[] = {1, 1, 2, 2, 4, 4, 4, 8};
    for (int i = 0; i < 8; i++)
        if (!strcmp(t, names[i][0]) || !strcmp(t, names[i][1])) return bytes[i];
    return 0;
}

typedef struct ply_element {
    char name[32];
    uint64_t count, min_bytes; /* the least bytes one element takes */
} ply_element;

/* The least bytes of all the element's rows (an element without properties counted as 1 byte a
 * row: no writer makes those, and it keeps the count bounded by the file). */
static uint64_t element_bytes(const ply_element *e) { return e->count * (e->min_bytes ? e->min_bytes : 1); }

/* The least bytes one property takes: binary, its type's (a list: its count's, the list may be
 * empty); ASCII, one number and a separator. */
static uint64_t ply_property_bytes(char *line, int binary)
{
    char *words[4] = {0};
    int n = 0;
    for (char *w = strtok(line, " \t\r"); w && n < 4; w = strtok(NULL, " \t\r")) words[n++] = w;
    if (!binary) return 2;
    if (n >= 3 && !strcmp(words[1], "list")) return (uint64_t)ply_type_bytes(words[2]);
    return n >= 2 ? (uint64_t)ply_type_bytes(words[1]) : 0;
}

/* Walks the header in head (the file's first bytes) and compares the elements' least sizes with
 * the bytes after end_header. */
static fm_status check_ply(const char *head, size_t head_len, uint64_t file_bytes, const char *name, fm_error *err)
{
    const char *end = NULL;
    for (const char *p = head; p + 10 <= head + head_len && !end; p++)
        if (!memcmp(p, "end_header", 10) && (p == head || p[-1] == '\n')) end = p;
    if (!end)
        return fm_fail(err, FM_ERR_INPUT, "%s: the PLY header has no end_header in its first %zu bytes", name, head_len);
    const char *body = memchr(end, '\n', (size_t)(head + head_len - end));
    size_t header = body ? (size_t)(body + 1 - head) : head_len;
    uint64_t have = file_bytes > header ? file_bytes - header : 0;
    int binary = 0;
    uint64_t need = 0;
    ply_element e = {"", 0, 0};
    for (const char *line = head; line < end;) {
        const char *nl = memchr(line, '\n', (size_t)(end - line));
        size_t len = nl ? (size_t)(nl - line) : (size_t)(end - line);
        char text[256];
        snprintf(text, sizeof text, "%.*s", (int)(len < sizeof text ? len : sizeof text - 1), line);
        line += len + 1;
        unsigned long long count;
        char ename[32];
        if (!strncmp(text, "format ", 7)) binary = strstr(text, "binary") != NULL;
        else if (sscanf(text, "element %31s %llu", ename, &count) == 2) {
            need += element_bytes(&e), e.count = 0;
            if (need > have) break; /* the elements so far do not fit: stop before the sum could overflow */
            char what[48];
            snprintf(what, sizeof what, "'%s' elements", ename);
            if (count > MAX_COUNT || count > file_bytes) return too_many(name, what, count, count, have, err);
            snprintf(e.name, sizeof e.name, "%s", ename), e.count = count, e.min_bytes = 0;
        } else if (!strncmp(text, "property ", 9) && e.count) {
            e.min_bytes += ply_property_bytes(text, binary);
        }
    }
    need += element_bytes(&e);
    if (!binary && need) need--; /* the last ASCII number needs no separator */
    return need > have ? fm_fail(err, FM_ERR_INPUT, "%s: the PLY header declares elements that take at least %llu "
                                 "bytes, but the file holds %llu after its header: it is damaged or cut short",
                                 name, (unsigned long long)need, (unsigned long long)have)
                       : FM_OK;
}

/* ---------------------------------------------------------------- OFF */

/* Skips blanks and # comments. */
static const char *off_skip(const char *p, const char *end)
{
    while (p < end) {
        if (*p == '#')
            while (p < end && *p != '\n') p++;
        else if (isspace((unsigned char)*p)) p++;
        else break;
    }
    return p;
}

/* The whole number after blanks and comments at *p (saturating above MAX_COUNT); *p moves past it.
 * *found says whether there was one. */
static uint64_t off_count(const char **p, const char *end, int *found)
{
    uint64_t n = 0;
    const char *q = off_skip(*p, end);
    *found = q < end && isdigit((unsigned char)*q);
    for (; q < end && isdigit((unsigned char)*q); q++)
        if (n <= MAX_COUNT) n = 10 * n + (uint64_t)(*q - '0');
    *p = q;
    return n;
}

/* "OFF" (or COFF, NOFF, ...), then the vertex, face and edge counts. A vertex takes at least 6
 * bytes ("0 0 0\n"), a face at least 2 ("0\n"). */
static fm_status check_off(const char *head, size_t head_len, uint64_t file_bytes, const char *name, fm_error *err)
{
    const char *end = head + head_len, *p = head;
    while (p < end && isalpha((unsigned char)*p)) p++; /* the OFF keyword */
    int found_v, found_f;
    uint64_t nv = off_count(&p, end, &found_v), nf = off_count(&p, end, &found_f);
    if (!found_v || !found_f) return FM_OK; /* no counts: assimp says what is wrong */
    if (nv > MAX_COUNT || nv > file_bytes) return too_many(name, "vertices", nv, nv, file_bytes, err);
    if (nf > MAX_COUNT || nf > file_bytes) return too_many(name, "faces", nf, nf, file_bytes, err);
    uint64_t need = nv + nf ? 6 * nv + 2 * nf - 1 : 0; /* the last line needs no newline */
    return need > file_bytes ? too_many(name, "vertices and faces", nv + nf, need, file_bytes, err) : FM_OK;
}

/* ---------------------------------------------------------------- STL */

/* A binary STL: an 80-byte header, the triangle count, 50 bytes per triangle. An ASCII STL starts
 * with "solid" and declares no count. */
static fm_status check_stl(const char *head, size_t head_len, uint64_t file_bytes, const char *name, fm_error *err)
{
    if (head_len < 84) return FM_OK; /* no count to check: assimp says what is wrong */
    const unsigned char *c = (const unsigned char *)head + 80;
    uint64_t count = (uint64_t)c[0] | (uint64_t)c[1] << 8 | (uint64_t)c[2] << 16 | (uint64_t)c[3] << 24;
    uint64_t need = 84 + 50 * count;
    if (!strncmp(head, "solid", 5) && need != file_bytes) return FM_OK; /* ASCII (a binary one fits exactly) */
    return need > file_bytes ? too_many(name, "triangles", count, need, file_bytes, err) : FM_OK;
}

/* ---------------------------------------------------------------- entry */

fm_status fm_mesh_check_counts(const char *head, size_t head_len, uint64_t file_bytes, const char *format,
                               const char *name, fm_error *err)
{
    if (head_len >= 4 && !strncmp(head, "ply", 3) && (head[3] == '\n' || head[3] == '\r'))
        return check_ply(head, head_len, file_bytes, name, err);
    size_t k = 0;
    while (k < head_len && k < 8 && isalpha((unsigned char)head[k])) k++;
    if (k >= 3 && !strncasecmp(head + k - 3, "off", 3)) return check_off(head, head_len, file_bytes, name, err);
    if (!strcasecmp(format, "stl")) return check_stl(head, head_len, file_bytes, name, err);
    return FM_OK;
}

fm_status fm_mesh_check_file_counts(const char *path, fm_error *err)
{
    enum { HEAD = 1 << 16 }; /* a PLY header with its comments fits */
    FILE *f = fopen(path, "rb");
    if (!f) return FM_OK; /* fm_check_input_file said it opens; assimp reports what changed */
    char *head = malloc(HEAD + 1);
    size_t len = head ? fread(head, 1, HEAD, f) : 0;
    int seek_ok = fseeko(f, 0, SEEK_END) == 0;
    uint64_t file_bytes = seek_ok ? (uint64_t)ftello(f) : len;
    fclose(f);
    if (!head) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
    head[len] = 0;
    const char *dot = strrchr(path, '.');
    fm_status st = fm_mesh_check_counts(head, len, file_bytes, dot ? dot + 1 : "", path, err);
    free(head);
    return st;
}
