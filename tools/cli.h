/* The command line's shared helpers; each command lives in tools/cli_<command>.c. */
#ifndef FM_CLI_H
#define FM_CLI_H

#include "flockmorph/flockmorph.h"
#include "fm_internal.h"

#include <stdint.h>

/* Commands: argc/argv start after the command's name. Each returns the process exit status. */
int cli_run(int argc, char **argv);
int cli_export(int argc, char **argv);
int cli_render(int argc, char **argv);
int cli_inspect(int argc, char **argv);
int cli_info(int argc, char **argv); /* inspect --json */

double cli_seconds(void);
/* Prints "flockmorph: <fmt with arg>" and the usage; returns FM_ERR_USAGE. */
int cli_usage_error(const char *usage, const char *fmt, const char *arg);
/* Prints the error; returns its status as the exit code. */
int cli_report(const fm_error *err);
int cli_wants_help(int argc, char **argv);
/* Parses a whole number in [lo, hi]; -1 if it is not one. */
int cli_parse_int(const char *s, long lo, long hi, long *out);
/* Creates dir (and parents) if needed and checks it is writable; 0 or an exit status. */
int cli_make_outdir(const char *dir, fm_error *err);

typedef struct cli_frame_options {
    const char *cache, *out, *view;
    long frame;
    int has_frame, width, height;
} cli_frame_options;

/* CACHE -o OUT [--frame K] [--size WxH] [--view V]; -o may be omitted when optional_out. */
int cli_parse_frame_options(int argc, char **argv, const char *usage, int optional_out, cli_frame_options *o);
/* Opens the cache and reads the chosen frame (default last) into a malloc'ed array. */
int cli_load_frame(const cli_frame_options *o, fm_cache_reader **reader, float **verts, uint32_t *frame);

#endif
