/* The element counts a mesh file declares up front, checked against the file's size before the
 * file goes to assimp. assimp allocates from a PLY or OFF header's counts (and a binary STL's
 * triangle count) before it reads a single element, so a 165-byte PLY that claims 2e9 vertices
 * would make it try to allocate tens of GiB. Every element takes a least number of bytes (below),
 * so a file cannot hold more elements than its size allows; a header that claims more is damaged.
 * The same holds for the length of every list in a binary PLY body, which assimp allocates for
 * before it reads the list (walk_ply_body). */
#define _POSIX_C_SOURCE 200809L
#include "geom.h"

#include <ctype.h>
#include <math.h>
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

/* Where the checks read the bytes after the head: the open file, or the whole file in memory. */
typedef struct body_reader {
    FILE *f;                  /* NULL: mem */
    const unsigned char *mem;
    uint64_t pos;             /* in mem */
} body_reader;

/* The callers check that n bytes are left. */
static int body_seek(body_reader *r, uint64_t offset)
{
    if (!r->f) return r->pos = offset, 1;
    return fseeko(r->f, (off_t)offset, SEEK_SET) == 0;
}

static int body_read(body_reader *r, void *out, size_t n)
{
    if (!r->f) return memcpy(out, r->mem + r->pos, n), r->pos += n, 1;
    return fread(out, 1, n, r->f) == n;
}

static int body_skip(body_reader *r, uint64_t n)
{
    unsigned char scratch[256]; /* a short skip is a copy within stdio's buffer, not a seek */
    if (!r->f) return r->pos += n, 1;
    if (n <= sizeof scratch) return fread(scratch, 1, (size_t)n, r->f) == n;
    return fseeko(r->f, (off_t)n, SEEK_CUR) == 0;
}

/* The scalar types of the PLY format (assimp reads these names and no others). */
enum { PLY_TYPES = 8 };
static const char *const PLY_TYPE_NAMES[PLY_TYPES][2] = {{"char", "int8"}, {"uchar", "uint8"}, {"short", "int16"},
                                                        {"ushort", "uint16"}, {"int", "int32"}, {"uint", "uint32"},
                                                        {"float", "float32"}, {"double", "float64"}};
static const int PLY_TYPE_BYTES[PLY_TYPES] = {1, 1, 2, 2, 4, 4, 4, 8};
enum { PLY_CHAR, PLY_UCHAR, PLY_SHORT, PLY_USHORT, PLY_INT, PLY_UINT, PLY_FLOAT, PLY_DOUBLE };

/* The type's index; -1 if unknown. */
static int ply_type(const char *t)
{
    for (int i = 0; t && i < PLY_TYPES; i++)
        if (!strcmp(t, PLY_TYPE_NAMES[i][0]) || !strcmp(t, PLY_TYPE_NAMES[i][1])) return i;
    return -1;
}

typedef struct ply_property {
    char name[32];
    int type;      /* a scalar's type, a list's count type; -1 unknown */
    int item_type; /* a list's entries' type (-1 unknown); -2: not a list */
} ply_property;

typedef struct ply_element {
    char name[32];
    uint64_t count;
    int first, n; /* its properties: props[first .. first + n) */
} ply_element;

typedef struct ply_header {
    int binary, big_endian;
    size_t body; /* the body's offset in the file */
    ply_element *elements;
    ply_property *props;
    int n_elements, n_props;
} ply_header;

static void ply_header_free(ply_header *h)
{
    free(h->elements);
    free(h->props);
}

/* The least bytes one property takes: binary, its type's (a list: its count's, the list may be
 * empty); ASCII, one number and a separator. */
static uint64_t ply_property_bytes(const ply_property *p, int binary)
{
    if (!binary) return 2;
    return p->type >= 0 ? (uint64_t)PLY_TYPE_BYTES[p->type] : 0;
}

/* The least bytes of all the element's rows (an element without properties counted as 1 byte a
 * row: no writer makes those, and it keeps the count bounded by the file). */
static uint64_t element_bytes(const ply_header *h, const ply_element *e)
{
    uint64_t row = 0;
    for (int i = e->first; i < e->first + e->n; i++) row += ply_property_bytes(&h->props[i], h->binary);
    return e->count * (row ? row : 1);
}

/* Splits a header line into at most 6 words. */
static int split_words(char *line, char *words[6])
{
    int n = 0;
    char *save = NULL;
    for (char *w = strtok_r(line, " \t\r", &save); w && n < 6; w = strtok_r(NULL, " \t\r", &save)) words[n++] = w;
    return n;
}

/* One header line into h, read as assimp reads it: the first format line, an element (its count
 * the leading digits, 0 without any) or a property of the last element. */
static void ply_header_line(ply_header *h, char *text, int *format_seen)
{
    char *w[6];
    int n = split_words(text, w);
    if (n >= 2 && !strcmp(w[0], "format") && !*format_seen) {
        *format_seen = 1;
        h->binary = !strncmp(w[1], "binary_", 7), h->big_endian = h->binary && (w[1][7] == 'b' || w[1][7] == 'B');
    } else if (n >= 2 && !strcmp(w[0], "element")) {
        ply_element *e = &h->elements[h->n_elements++];
        snprintf(e->name, sizeof e->name, "%s", w[1]);
        e->count = n >= 3 && isdigit((unsigned char)w[2][0]) ? strtoull(w[2], NULL, 10) : 0;
        e->first = h->n_props, e->n = 0;
    } else if (n >= 2 && !strcmp(w[0], "property") && h->n_elements) {
        ply_property *p = &h->props[h->n_props++];
        const int list = !strcmp(w[1], "list");
        p->type = ply_type(w[list ? 2 : 1]);
        p->item_type = list ? ply_type(n > 3 ? w[3] : NULL) : -2;
        snprintf(p->name, sizeof p->name, "%s", n > (list ? 4 : 2) ? w[list ? 4 : 2] : "");
        h->elements[h->n_elements - 1].n++;
    }
}

/* assimp ends a line at any of these (IsLineEnd). */
static int line_end(char c) { return c == '\n' || c == '\r' || c == '\f' || c == 0; }

/* Reads the header in head (the file's first bytes) into h. Where the body starts is where assimp
 * starts it: one character after end_header's line (for "\r\n", at the '\n'). */
static fm_status parse_ply_header(const char *head, size_t head_len, const char *name, ply_header *h, fm_error *err)
{
    memset(h, 0, sizeof *h);
    const char *end = NULL, *stop = head + head_len;
    for (const char *p = head; p + 10 <= stop && !end; p++)
        if (!memcmp(p, "end_header", 10) && (p == head || line_end(p[-1]))) end = p;
    if (!end)
        return fm_fail(err, FM_ERR_INPUT, "%s: the PLY header has no end_header in its first %zu bytes", name, head_len);
    const char *body = end + 10;
    while (body < stop && !line_end(*body)) body++;
    h->body = body < stop ? (size_t)(body + 1 - head) : head_len;
    size_t lines = 1;
    for (const char *p = head; p < end; p++) lines += line_end(*p);
    h->elements = malloc(sizeof *h->elements * lines), h->props = malloc(sizeof *h->props * lines);
    if (!h->elements || !h->props) return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory reading the PLY header", name);
    int format_seen = 0;
    for (const char *line = head; line < end;) {
        size_t len = 0;
        while (line + len < end && !line_end(line[len])) len++;
        char text[256];
        snprintf(text, sizeof text, "%.*s", (int)(len < sizeof text ? len : sizeof text - 1), line);
        line += len + 1;
        ply_header_line(h, text, &format_seen);
    }
    return FM_OK;
}

/* The elements' least sizes against the bytes after the header. */
static fm_status check_ply_sizes(const ply_header *h, uint64_t file_bytes, const char *name, fm_error *err)
{
    uint64_t have = file_bytes > h->body ? file_bytes - h->body : 0, need = 0;
    for (int i = 0; i < h->n_elements && need <= have; i++) { /* past have, stop before the sum could overflow */
        const ply_element *e = &h->elements[i];
        char what[48];
        snprintf(what, sizeof what, "'%s' elements", e->name);
        if (e->count > MAX_COUNT || e->count > file_bytes) return too_many(name, what, e->count, e->count, have, err);
        need += element_bytes(h, e);
    }
    if (!h->binary && need) need--; /* the last ASCII number needs no separator */
    return need > have ? fm_fail(err, FM_ERR_INPUT, "%s: the PLY header declares elements that take at least %llu "
                                 "bytes, but the file holds %llu after its header: it is damaged or cut short",
                                 name, (unsigned long long)need, (unsigned long long)have)
                       : FM_OK;
}

/* A binary body can only be read with every type known (assimp drops the rest of an element's
 * properties at an unknown one, and then reads the body at other offsets than the header says). */
static fm_status check_ply_types(const ply_header *h, const char *name, fm_error *err)
{
    for (int i = 0; i < h->n_elements; i++)
        for (int k = h->elements[i].first; k < h->elements[i].first + h->elements[i].n; k++)
            if (h->props[k].type < 0 || h->props[k].item_type == -1)
                return fm_fail(err, FM_ERR_INPUT, "%s: property '%s' of the '%s' elements has a type the PLY format "
                               "does not have: the file is damaged", name, h->props[k].name, h->elements[i].name);
    return FM_OK;
}

/* A list's count as assimp takes it (an unsigned int from any type: a negative one wraps), widened
 * so that no value is lost: a negative or non-integral count becomes UINT64_MAX. */
static uint64_t decode_count(const unsigned char *b, int type, int big_endian)
{
    const int n = PLY_TYPE_BYTES[type];
    uint64_t u = 0;
    for (int k = 0; k < n; k++) u |= (uint64_t)b[big_endian ? n - 1 - k : k] << (8 * k);
    if (type == PLY_FLOAT || type == PLY_DOUBLE) {
        double d;
        if (type == PLY_FLOAT) {
            float f;
            uint32_t w = (uint32_t)u;
            memcpy(&f, &w, sizeof f), d = f;
        } else {
            memcpy(&d, &u, sizeof d);
        }
        return d >= 0 && d < 18446744073709551616.0 && d == floor(d) ? (uint64_t)d : UINT64_MAX;
    }
    const int is_signed = type == PLY_CHAR || type == PLY_SHORT || type == PLY_INT;
    return is_signed && (u >> (8 * n - 1)) ? UINT64_MAX : u;
}

static fm_status list_too_long(const char *name, const ply_element *e, uint64_t row, const ply_property *p,
                               uint64_t count, uint64_t left, fm_error *err)
{
    if (count == UINT64_MAX)
        return fm_fail(err, FM_ERR_INPUT, "%s: '%s' element %llu: the list '%s' has a negative or fractional length: "
                       "the file is damaged", name, e->name, (unsigned long long)row + 1, p->name);
    return fm_fail(err, FM_ERR_INPUT, "%s: '%s' element %llu: the list '%s' declares %llu entries of %d bytes, but "
                   "%llu bytes are left in the file: it is damaged or cut short", name, e->name,
                   (unsigned long long)row + 1, p->name, (unsigned long long)count, PLY_TYPE_BYTES[p->item_type],
                   (unsigned long long)left);
}

/* One row of an element with lists; *left: the body's bytes not yet read. */
static fm_status walk_ply_row(const ply_header *h, const ply_element *e, uint64_t row, body_reader *r, uint64_t *left,
                              const char *name, fm_error *err)
{
    for (int k = e->first; k < e->first + e->n; k++) {
        const ply_property *p = &h->props[k];
        const uint64_t bytes = (uint64_t)PLY_TYPE_BYTES[p->type];
        unsigned char b[8];
        if (bytes > *left || !(p->item_type >= 0 ? body_read(r, b, (size_t)bytes) : body_skip(r, bytes)))
            return fm_fail(err, FM_ERR_INPUT, "%s: '%s' element %llu is cut short", name, e->name, (unsigned long long)row + 1);
        *left -= bytes;
        if (p->item_type < 0) continue;
        const uint64_t count = decode_count(b, p->type, h->big_endian), item = (uint64_t)PLY_TYPE_BYTES[p->item_type];
        if (count > *left / item) return list_too_long(name, e, row, p, count, *left, err);
        if (!body_skip(r, count * item))
            return fm_fail(err, FM_ERR_INPUT, "%s: '%s' element %llu is cut short", name, e->name, (unsigned long long)row + 1);
        *left -= count * item;
    }
    return FM_OK;
}

static int has_lists(const ply_header *h, const ply_element *e)
{
    for (int k = e->first; k < e->first + e->n; k++)
        if (h->props[k].item_type >= 0) return 1;
    return 0;
}

/* assimp sizes every list of a binary body from its count before it reads one entry (a face whose
 * uint count says 2^28 made it allocate 2 GiB for a 300-byte file), so every list must fit in the
 * bytes left after it. Rows without lists have one size and are skipped whole. */
static fm_status walk_ply_body(const ply_header *h, body_reader *r, uint64_t file_bytes, const char *name, fm_error *err)
{
    if (!body_seek(r, h->body)) return FM_OK; /* unreadable: assimp says what is wrong */
    uint64_t left = file_bytes > h->body ? file_bytes - h->body : 0;
    fm_status st = FM_OK;
    for (int i = 0; i < h->n_elements && st == FM_OK; i++) {
        const ply_element *e = &h->elements[i];
        if (!has_lists(h, e)) {
            const uint64_t bytes = element_bytes(h, e) - (e->n ? 0 : e->count); /* no properties: no bytes */
            if (bytes > left || !body_skip(r, bytes))
                return fm_fail(err, FM_ERR_INPUT, "%s: the '%s' elements are cut short", name, e->name);
            left -= bytes;
            continue;
        }
        for (uint64_t row = 0; row < e->count && st == FM_OK; row++) st = walk_ply_row(h, e, row, r, &left, name, err);
    }
    return st;
}

/* The next byte of an ASCII body, or -1 past its end (*left: the bytes not yet read). */
static int body_byte(body_reader *r, uint64_t *left)
{
    if (*left == 0) return -1;
    --*left;
    if (!r->f) return r->mem[r->pos++];
    int c = getc_unlocked(r->f); /* one byte at a time: without the stream's lock */
    if (c == EOF) *left = 0;
    return c;
}

/* The next word of an ASCII body (blanks and line ends separate words, as assimp splits them)
 * into word (cut to its size); 0 at the end of the body. */
static int body_word(body_reader *r, uint64_t *left, char *word, size_t size)
{
    int c;
    while ((c = body_byte(r, left)) >= 0 && (c == ' ' || c == '\t' || line_end((char)c))) {}
    size_t n = 0;
    for (; c >= 0 && !(c == ' ' || c == '\t' || line_end((char)c)); c = body_byte(r, left))
        if (n + 1 < size) word[n++] = (char)c;
    word[n] = 0;
    return n > 0;
}

/* An ASCII list's count: UINT64_MAX for a negative one or one that is not a number. */
static uint64_t ascii_count(const char *word)
{
    if (word[0] < '0' || word[0] > '9') return UINT64_MAX;
    uint64_t count = 0;
    for (const char *c = word; *c >= '0' && *c <= '9'; c++) count = count > MAX_COUNT ? count : count * 10 + (uint64_t)(*c - '0');
    return count;
}

/* The same for an ASCII body: assimp sizes a list from its count as well (a face line
 * "300000000 1 2 3" grew it to 4.7 GB), and a list of c entries takes at least 2c - 1 bytes. Words
 * that run out end the walk: assimp reports a body cut short itself. */
static fm_status walk_ply_ascii(const ply_header *h, body_reader *r, uint64_t file_bytes, const char *name, fm_error *err)
{
    if (!body_seek(r, h->body)) return FM_OK;
    uint64_t left = file_bytes > h->body ? file_bytes - h->body : 0;
    char word[64];
    for (int i = 0; i < h->n_elements; i++) {
        const ply_element *e = &h->elements[i];
        for (uint64_t row = 0; row < e->count; row++)
            for (int k = e->first; k < e->first + e->n; k++) {
                const ply_property *p = &h->props[k];
                if (!body_word(r, &left, word, sizeof word)) return FM_OK;
                if (p->item_type == -2) continue;
                const uint64_t count = ascii_count(word);
                if (count == UINT64_MAX || count > (left + 1) / 2)
                    return count == UINT64_MAX ? list_too_long(name, e, row, p, count, left, err)
                                               : fm_fail(err, FM_ERR_INPUT, "%s: '%s' element %llu: the list '%s' declares "
                                                         "%llu entries, but %llu bytes are left in the file: it is "
                                                         "damaged or cut short", name, e->name,
                                                         (unsigned long long)row + 1, p->name, (unsigned long long)count,
                                                         (unsigned long long)left);
                for (uint64_t j = 0; j < count; j++)
                    if (!body_word(r, &left, word, sizeof word)) return FM_OK;
            }
    }
    return FM_OK;
}

static fm_status check_ply(const char *head, size_t head_len, uint64_t file_bytes, body_reader *r, const char *name,
                           fm_error *err)
{
    ply_header h;
    fm_status st = parse_ply_header(head, head_len, name, &h, err);
    if (st == FM_OK) st = check_ply_sizes(&h, file_bytes, name, err);
    if (st == FM_OK && h.binary) st = check_ply_types(&h, name, err);
    if (st == FM_OK && h.binary && r) st = walk_ply_body(&h, r, file_bytes, name, err);
    if (st == FM_OK && !h.binary && r) st = walk_ply_ascii(&h, r, file_bytes, name, err);
    ply_header_free(&h);
    return st;
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

/* head: the file's first head_len bytes; r: the whole file, for the lists of a binary PLY body. */
static fm_status check_counts(const char *head, size_t head_len, uint64_t file_bytes, body_reader *r,
                              const char *format, const char *name, fm_error *err)
{
    if (head_len >= 4 && !strncmp(head, "ply", 3) && (head[3] == '\n' || head[3] == '\r'))
        return check_ply(head, head_len, file_bytes, r, name, err);
    size_t k = 0;
    while (k < head_len && k < 8 && isalpha((unsigned char)head[k])) k++;
    if (k >= 3 && !strncasecmp(head + k - 3, "off", 3)) return check_off(head, head_len, file_bytes, name, err);
    if (!strcasecmp(format, "stl")) return check_stl(head, head_len, file_bytes, name, err);
    return FM_OK;
}

enum { HEAD = 1 << 16 }; /* a PLY header with its comments fits */

fm_status fm_mesh_check_counts(const void *data, size_t len, const char *format, const char *name, fm_error *err)
{
    body_reader r = {NULL, data, 0};
    return check_counts(data, len < HEAD ? len : HEAD, len, &r, format, name, err);
}

fm_status fm_mesh_check_file_counts(const char *path, fm_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f) return FM_OK; /* fm_check_input_file said it opens; assimp reports what changed */
    char *head = malloc(HEAD + 1);
    size_t len = head ? fread(head, 1, HEAD, f) : 0;
    int seek_ok = fseeko(f, 0, SEEK_END) == 0;
    uint64_t file_bytes = seek_ok ? (uint64_t)ftello(f) : len;
    fm_status st = FM_OK;
    if (!head) st = fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if (head) {
        head[len] = 0;
        const char *dot = strrchr(path, '.');
        body_reader r = {f, NULL, 0};
        st = check_counts(head, len, file_bytes, seek_ok ? &r : NULL, dot ? dot + 1 : "", path, err);
    }
    fclose(f);
    free(head);
    return st;
}
