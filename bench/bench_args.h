/* Command-line parsing for the benchmarks (bench_suite, bench_step). `--help` or `-h` anywhere
 * prints the usage on stdout and exits 0. An unknown option, a missing value or a value out of
 * range is a usage error: one line naming the option on stderr, then the usage, exit status 1, as
 * for flockmorph (docs/errors.md), so a script can tell "these arguments are not accepted" from a
 * benchmark that failed. Header-only: each benchmark is one program. */
#ifndef FM_BENCH_ARGS_H
#define FM_BENCH_ARGS_H

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { BENCH_EXIT_USAGE = 1 };

typedef struct bench_args {
    const char *prog, *usage;
    int argc, i;
    char **argv;
} bench_args;

static inline bench_args bench_args_begin(const char *prog, const char *usage, int argc, char **argv)
{
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) fputs(usage, stdout), exit(0);
    return (bench_args){prog, usage, argc, 0, argv};
}

__attribute__((noreturn, format(printf, 2, 3))) static inline void bench_usage_error(const bench_args *a, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", a->prog);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\n\n%s", a->usage);
    exit(BENCH_EXIT_USAGE);
}

/* Moves to the next option; 0 at the end. */
static inline int bench_next(bench_args *a) { return ++a->i < a->argc; }

static inline int bench_is(const bench_args *a, const char *option) { return !strcmp(a->argv[a->i], option); }

__attribute__((noreturn)) static inline void bench_unknown(const bench_args *a) { bench_usage_error(a, "unknown option '%s'", a->argv[a->i]); }

/* The current option's value (the next word), which it consumes. */
static inline const char *bench_value(bench_args *a)
{
    if (a->i + 1 >= a->argc) bench_usage_error(a, "%s needs a value", a->argv[a->i]);
    return a->argv[++a->i];
}

/* A whole number from lo to hi in s, for option `option`. */
static inline long bench_parse_long(const bench_args *a, const char *option, const char *s, long lo, long hi)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno || v < lo || v > hi)
        bench_usage_error(a, "%s wants a whole number from %ld to %ld, not '%s'", option, lo, hi, s);
    return v;
}

/* The current option's value as a whole number from lo to hi. */
static inline long bench_long(bench_args *a, long lo, long hi)
{
    const char *option = a->argv[a->i];
    return bench_parse_long(a, option, bench_value(a), lo, hi);
}

/* The current option's value, one of `names` (count of them); returns its index. */
static inline int bench_choice(bench_args *a, const char *const *names, int count)
{
    const char *option = a->argv[a->i], *v = bench_value(a);
    for (int k = 0; k < count; k++)
        if (!strcmp(v, names[k])) return k;
    char list[256] = "";
    for (int k = 0; k < count; k++)
        snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", k ? ", " : "", names[k]);
    bench_usage_error(a, "%s wants one of %s, not '%s'", option, list, v);
}

#endif
