/* flockmorph: the command line.
 *
 *   flockmorph run SCENE.json -o OUTDIR [--threads N] [--quiet] [--checkpoint-every K] [--resume]
 *   flockmorph export CACHE --format ply|obj|vtk|vdb [--frames A:B[:S]] -o DIR   (or -o FILE [--frame K])
 *   flockmorph export CACHE -o FILE.pc2|FILE.mdd [--frames A:B[:S]]            (a point cache)
 *   flockmorph render CACHE -o FILE.png [--frame K] | -o FILE.mp4|NAME.%04d.png [--frames A:B[:S]] [options]
 *   flockmorph inspect CACHE [--json]
 *   flockmorph info CACHE              (inspect --json)
 *   flockmorph wedge list|count WEDGES.json
 *   flockmorph studio SCENE.json|CACHE.fmc [--port N] [--host H] [--no-browser] [-o DIR]
 *   flockmorph run SCENE.json --set KEY=VALUE --wedge-file WEDGES.json [--wedge I] -o 'out/{wedge}' 
 *   flockmorph help [COMMAND]          (COMMAND --help)
 *   flockmorph --version | -V
 *
 * Exit status: 0 success, 1 usage, 2 bad input, 3 I/O, 4 memory, 5 internal. */
#define _GNU_SOURCE /* SIGXFSZ, sigaltstack, alloca */
#include "cli.h"
#include "memory.h"

#include <alloca.h>
#include <omp.h>
#include <setjmp.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *USAGE_MAIN =
    "usage: flockmorph <command> [options]\n"
    "\n"
    "Turns one 3D shape into another as a flock of tetrahedra and caches every frame.\n"
    "\n"
    "commands:\n"
    "  run      simulate a scene file and write the frame cache and stats.json\n"
    "  export   write frames of a cache as PLY, OBJ, VTK, OpenVDB points, PC2 or MDD\n"
    "  render   ray-cast a frame of a cache to a PNG, or frames to an MP4 (ffmpeg)\n"
    "  inspect  describe a cache: attributes, options, sizes, compression, bounds\n"
    "  info     the same as 'inspect --json'\n"
    "  wedge    list or count the variants of a wedge file (run --wedge-file runs one)\n"
    "  studio   shape a scene live in a browser, or play back a cache\n"
    "\n"
    "'flockmorph help <command>' or 'flockmorph <command> --help' describes each command;\n"
    "'flockmorph --version' prints the version. docs/ has the scene file reference.\n";

static const struct {
    const char *name;
    int (*fn)(int argc, char **argv);
} COMMANDS[] = {
    {"run", cli_run}, {"export", cli_export}, {"render", cli_render}, {"inspect", cli_inspect}, {"info", cli_info},
    {"wedge", cli_wedge}, {"studio", cli_studio},
};

static int (*find_command(const char *name))(int, char **)
{
    for (size_t i = 0; i < sizeof COMMANDS / sizeof COMMANDS[0]; i++)
        if (!strcmp(name, COMMANDS[i].name)) return COMMANDS[i].fn;
    return NULL;
}

fm_dist *cli_dist; /* the run's ranks under mpirun; NULL otherwise */

/* Threads per rank when neither --threads nor OMP_NUM_THREADS says: a rank that may run on every
 * core would start a thread per core, and P such ranks on one machine P threads a core, which
 * OpenMP's spinning barriers turn into minutes for a one-second run. So the machine's cores are
 * shared among its ranks; a rank bound to fewer cores (mpirun's default binding, --map-by
 * slot:PE=T) keeps its own, if the ranks' cores together fit the machine. */
static void share_cores(int ranks_here)
{
    const char *user = getenv("OMP_NUM_THREADS");
    if (ranks_here <= 1 || (user && *user)) return;
    const long machine = sysconf(_SC_NPROCESSORS_ONLN);
    const int mine = omp_get_num_procs(); /* the cores this rank may run on */
    if (machine < 1 || (long)mine * ranks_here <= machine) return;
    omp_set_num_threads((int)FM_MAX(1, machine / ranks_here));
}

/* Under an MPI launcher: MPI initialised, and the ranks but 0 silent (every rank reads the same
 * scene and meets the same errors; what only one rank meets reaches rank 0 with the status). */
static int start_ranks(int *argc, char ***argv)
{
    if (!fm_dist_launched()) return 0;
    fm_error err = {0};
    if (!(cli_dist = fm_dist_init(argc, argv, &err))) return cli_report(&err);
    fm_memory_set_ranks(fm_dist_size(cli_dist), fm_dist_size_here(cli_dist)); /* a run's estimate is one rank's */
    share_cores(fm_dist_size_here(cli_dist));
    if (fm_dist_rank(cli_dist) != 0 && !getenv("FM_RANK_OUTPUT")) {
        if (!freopen("/dev/null", "w", stdout) || !freopen("/dev/null", "w", stderr)) return FM_ERR_IO;
    }
    return 0;
}

static int dispatch(int argc, char **argv);

/* Under ulimit -v the main thread's stack grows into the address space like any allocation, but a
 * growth that does not fit is SIGSEGV, not an error one can report (a scene definition is 136 KB,
 * and a few are on the stack at once: issue 42). So the stack the CLI needs is touched at the
 * start, and a failure there, caught on an alternate stack, is out of memory (exit 4). */
enum { STACK_RESERVE = 4 << 20 };
static sigjmp_buf stack_fault;

static void on_stack_fault(int sig) { siglongjmp(stack_fault, sig); }

static __attribute__((noinline)) void touch_stack(size_t bytes)
{
    volatile char *pad = alloca(bytes);
    for (size_t i = 0; i < bytes; i += 4096) pad[i] = 0;
}

/* STACK_RESERVE, or less under a smaller stack limit (ulimit -s), leaving room above it. */
static size_t stack_to_reserve(void)
{
    struct rlimit limit;
    if (getrlimit(RLIMIT_STACK, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return STACK_RESERVE;
    return limit.rlim_cur > (1 << 20) ? FM_MIN((size_t)STACK_RESERVE, (size_t)limit.rlim_cur - (512 << 10)) : 0;
}

static int reserve_stack(void)
{
    static char alternate[64 << 10];
    stack_t ss = {.ss_sp = alternate, .ss_size = sizeof alternate}, off = {.ss_flags = SS_DISABLE};
    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stack_fault, sa.sa_flags = SA_ONSTACK;
    sigemptyset(&sa.sa_mask);
    if (stack_to_reserve() == 0 || sigaltstack(&ss, NULL) != 0 || sigaction(SIGSEGV, &sa, &old) != 0) return 0;
    const int failed = sigsetjmp(stack_fault, 1); /* no local is live across it (-Wclobbered) */
    if (!failed) touch_stack(stack_to_reserve());
    sigaction(SIGSEGV, &old, NULL);
    sigaltstack(&off, NULL);
    if (!failed) return 0;
    fprintf(stderr, "flockmorph: error: out of memory: cannot have %zu MB of stack for the main thread (the "
            "address-space limit, ulimit -v, is too low)\n", stack_to_reserve() >> 20);
    return FM_ERR_MEMORY;
}

/* Descriptors 0, 1 and 2 open, on /dev/null where closed (`flockmorph run ... >&- 2>&-`): the first
 * file the run opens would otherwise get descriptor 1 or 2, and a progress line or a message
 * written to stdout or stderr would land in the cache. -1 if one cannot be opened. */
static int open_standard_streams(void)
{
    for (int fd = 0; fd <= 2; fd++) {
        if (fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
        int got = open("/dev/null", fd == 0 ? O_RDONLY : O_WRONLY); /* the lowest free number: fd */
        if (got != fd) return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (open_standard_streams() != 0) return FM_ERR_IO; /* before anything else opens a file */
    int rc = reserve_stack();
    if (rc) return rc;
    rc = start_ranks(&argc, &argv);
    if (rc) return rc;
    rc = dispatch(argc, argv);
    fm_dist_finalize(cli_dist);
    return rc;
}

static int dispatch(int argc, char **argv)
{
    /* Past the file-size limit (ulimit -f) the kernel's SIGXFSZ would kill the process mid-write;
     * ignored, write() fails with EFBIG, which every writer reports as an I/O error (exit 3). */
    signal(SIGXFSZ, SIG_IGN);
    /* OpenMP's default team (OMP_NUM_THREADS, unbounded) capped as the engine caps it (fm_threads),
     * for any parallel region that does not name its thread count */
    omp_set_num_threads(fm_threads(0));
    int rc = cli_threads_fit(fm_threads(0)); /* before any parallel region; run checks its --threads too */
    if (rc) return rc;
    if (argc < 2) return fprintf(stderr, "%s", USAGE_MAIN), FM_ERR_USAGE;
    const char *cmd = argv[1];
    if (!strcmp(cmd, "--version") || !strcmp(cmd, "-V")) return printf("flockmorph %s\n", FM_VERSION_STRING), 0;
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || (!strcmp(cmd, "help") && argc == 2))
        return printf("%s", USAGE_MAIN), 0;
    if (!strcmp(cmd, "help")) {
        /* 'help CMD' is 'CMD --help': each command keeps its one usage text. */
        int (*fn)(int, char **) = find_command(argv[2]);
        char help[] = "--help", *args[] = {help, NULL};
        if (fn) return fn(1, args);
        fprintf(stderr, "flockmorph: unknown command '%s'\nsee 'flockmorph help'\n", argv[2]);
        return FM_ERR_USAGE;
    }
    int (*fn)(int, char **) = find_command(cmd);
    if (fn && fn != cli_run && fm_dist_size(cli_dist) > 1) {
        fprintf(stderr, "flockmorph: '%s' runs on one process: only 'run' runs on several MPI ranks\n", cmd);
        return FM_ERR_USAGE;
    }
    if (fn) return fn(argc - 2, argv + 2);
    fprintf(stderr, "flockmorph: unknown command '%s'\nsee 'flockmorph help'\n", cmd);
    return FM_ERR_USAGE;
}
