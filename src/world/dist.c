/* The ranks of a run (dist.h): MPI when the build has it (FM_HAVE_MPI), P = 1 otherwise. */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include "dist.h"

#include <assert.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <limits.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifdef FM_HAVE_MPI
#include <mpi.h>
#endif

/* The P = 1 gather: a copy of this rank's records. */
static fm_status copy_records(const void *mine, int64_t count, size_t size, void **all, int64_t *total, fm_error *err)
{
    *all = NULL, *total = 0;
    if (count == 0) return FM_OK;
    if (!(*all = fm_alloc(size * (size_t)count))) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
    memcpy(*all, mine, size * (size_t)count);
    *total = count;
    return FM_OK;
}

#ifdef FM_HAVE_MPI

struct fm_dist {
    MPI_Comm comm;
    int rank, size;
    MPI_Comm here;            /* the ranks on this machine (MPI_COMM_TYPE_SHARED); MPI_COMM_NULL if unknown */
    int rank_here, size_here; /* this rank among them, and their count */
};

int fm_dist_launched(void)
{
    /* Open MPI's mpirun, PMIx launchers (srun --mpi=pmix), Hydra/PMI (MPICH, srun --mpi=pmi2) */
    static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"};
    for (size_t i = 0; i < sizeof vars / sizeof vars[0]; i++)
        if (getenv(vars[i])) return 1;
    return 0;
}

static void split_machines(fm_dist *d);

fm_dist *fm_dist_init(int *argc, char ***argv, fm_error *err)
{
    /* Open MPI busy-polls in a collective unless the node is oversubscribed; a rank waiting for the
     * others then takes a core from its own OpenMP threads and cache writer. Yield by default (the
     * user's setting, environment or --mca, wins). */
    setenv("OMPI_MCA_mpi_yield_when_idle", "1", 0);
    int provided = 0;
    if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
        fm_fail(err, FM_ERR_INTERNAL, "MPI_Init_thread failed");
        return NULL;
    }
    fm_dist *d = calloc(1, sizeof *d);
    if (!d) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory");
        MPI_Abort(MPI_COMM_WORLD, FM_ERR_MEMORY);
        return NULL;
    }
    d->comm = MPI_COMM_WORLD;
    MPI_Comm_rank(d->comm, &d->rank);
    MPI_Comm_size(d->comm, &d->size);
    split_machines(d);
    return d;
}

/* The ranks that share a machine's memory. FM_TEST_RANKS_PER_MACHINE=k makes ranks r / k one
 * "machine" instead, so that one machine's tests run what several machines do (a first rank on
 * each, building and sharing its own copy of the model). */
static void split_machines(fm_dist *d)
{
    d->here = MPI_COMM_NULL, d->rank_here = 0, d->size_here = 1;
    const char *test = getenv("FM_TEST_RANKS_PER_MACHINE");
    const int k = test ? atoi(test) : 0;
    int ok = k > 0 ? MPI_Comm_split(d->comm, d->rank / k, d->rank, &d->here)
                   : MPI_Comm_split_type(d->comm, MPI_COMM_TYPE_SHARED, d->rank, MPI_INFO_NULL, &d->here);
    if (ok != MPI_SUCCESS) return; /* every rank its own machine: nothing is shared */
    MPI_Comm_rank(d->here, &d->rank_here);
    MPI_Comm_size(d->here, &d->size_here);
}

void fm_dist_finalize(fm_dist *d)
{
    if (!d) return;
    if (d->here != MPI_COMM_NULL) MPI_Comm_free(&d->here);
    free(d);
    MPI_Finalize();
}

void fm_dist_abort(const fm_dist *d, int code)
{
    if (d) MPI_Abort(d->comm, code);
    exit(code);
}

int fm_dist_rank(const fm_dist *d) { return d ? d->rank : 0; }
int fm_dist_size(const fm_dist *d) { return d ? d->size : 1; }
int fm_dist_size_here(const fm_dist *d) { return d ? d->size_here : 1; }
int fm_dist_first_here(const fm_dist *d) { return d ? d->rank_here == 0 : 1; }

void fm_dist_bcast_here(const fm_dist *d, void *data, size_t bytes)
{
    assert(bytes <= INT_MAX);
    if (d && d->size_here > 1) MPI_Bcast(data, (int)bytes, MPI_BYTE, 0, d->here);
}

void fm_dist_sum_i64(const fm_dist *d, int64_t *v, int count)
{
    if (d && d->size > 1) MPI_Allreduce(MPI_IN_PLACE, v, count, MPI_INT64_T, MPI_SUM, d->comm);
}

void fm_dist_max_i64(const fm_dist *d, int64_t *v, int count)
{
    if (d && d->size > 1) MPI_Allreduce(MPI_IN_PLACE, v, count, MPI_INT64_T, MPI_MAX, d->comm);
}

void fm_dist_max_f64(const fm_dist *d, double *v, int count)
{
    if (d && d->size > 1) MPI_Allreduce(MPI_IN_PLACE, v, count, MPI_DOUBLE, MPI_MAX, d->comm);
}

void fm_dist_sum_f64(const fm_dist *d, double *v, int count)
{
    if (d && d->size > 1) MPI_Allreduce(MPI_IN_PLACE, v, count, MPI_DOUBLE, MPI_SUM, d->comm);
}

void fm_dist_min_f32(const fm_dist *d, float *v, int count)
{
    if (d && d->size > 1) MPI_Allreduce(MPI_IN_PLACE, v, count, MPI_FLOAT, MPI_MIN, d->comm);
}

void fm_dist_bcast(const fm_dist *d, void *data, size_t bytes, int root)
{
    assert(bytes <= INT_MAX); /* a value or a path: MPI counts are int */
    if (d && d->size > 1) MPI_Bcast(data, (int)bytes, MPI_BYTE, root, d->comm);
}

fm_status fm_dist_agree(const fm_dist *d, fm_status st, fm_error *err)
{
    if (!d || d->size == 1) return st;
    /* MAXLOC on (status, -rank): the worst status, and of the ranks that had it the lowest */
    struct { int value, rank; } mine = {(int)st, -d->rank}, worst;
    MPI_Allreduce(&mine, &worst, 1, MPI_2INT, MPI_MAXLOC, d->comm);
    if (worst.value == FM_OK) return FM_OK;
    fm_error shared = {0};
    if (d->rank == -worst.rank && err) shared = *err;
    MPI_Bcast(&shared, (int)sizeof shared, MPI_BYTE, -worst.rank, d->comm);
    shared.status = (fm_status)worst.value;
    if (err) *err = shared;
    return shared.status;
}

/* The all-gather and the exchanges count records in ints (MPI's counts): a datatype of `size`
 * bytes keeps the limit at 2^31 records rather than bytes. */
static int record_type(size_t size, MPI_Datatype *type)
{
    if (MPI_Type_contiguous((int)size, MPI_BYTE, type) != MPI_SUCCESS) return 0;
    return MPI_Type_commit(type) == MPI_SUCCESS;
}

/* displ[r] = the records before rank r's; the total, or -1 past MPI's int counts. */
static int64_t displacements(const int *count, int size, int *displ)
{
    int64_t total = 0;
    for (int r = 0; r < size; r++) {
        if (total > INT_MAX) return -1;
        displ[r] = (int)total, total += count[r];
    }
    return total > INT_MAX ? -1 : total;
}

static fm_status too_many(fm_error *err, int64_t count)
{
    return fm_fail(err, FM_ERR_INPUT, "an exchange between ranks of %lld records exceeds MPI's 2^31: run on more ranks",
                   (long long)count);
}

fm_status fm_dist_allgather(const fm_dist *d, const void *mine, int64_t count, size_t size, void **all, int64_t *total,
                            fm_error *err)
{
    if (!d || d->size == 1) return fm_dist_gather(NULL, mine, count, size, all, total, err);
    int *counts = calloc((size_t)d->size, 2 * sizeof(int)), *displ = counts + d->size, c = (int)FM_MIN(count, INT_MAX);
    if (!counts) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
    MPI_Allgather(&c, 1, MPI_INT, counts, 1, MPI_INT, d->comm);
    *total = displacements(counts, d->size, displ);
    fm_status st = *total < 0 || count > INT_MAX ? too_many(err, FM_MAX(*total, count)) : FM_OK;
    *all = st == FM_OK && *total > 0 ? fm_alloc(size * (size_t)*total) : NULL;
    if (st == FM_OK && *total > 0 && !*all) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld records", (long long)*total);
    MPI_Datatype type;
    const int typed = st == FM_OK && record_type(size, &type);
    if (st == FM_OK && !typed) st = fm_fail(err, FM_ERR_INTERNAL, "MPI_Type_contiguous failed");
    st = fm_dist_agree(d, st, err);
    if (st == FM_OK && *total > 0) MPI_Allgatherv(mine, c, type, *all, counts, displ, type, d->comm);
    if (typed) MPI_Type_free(&type);
    if (st != FM_OK) fm_free(*all), *all = NULL, *total = 0;
    free(counts);
    return st;
}

fm_status fm_dist_exchange(const fm_dist *d, const void *send, const int64_t *send_count, size_t size, void **recv,
                           int64_t *recv_count, fm_error *err)
{
    if (!d || d->size == 1) return fm_dist_gather(NULL, send, send_count[0], size, recv, recv_count, err);
    const int p = d->size;
    int *sc = calloc((size_t)p, 4 * sizeof(int)), *sd = sc + p, *rc = sd + p, *rd = rc + p;
    if (!sc) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
    fm_status st = FM_OK;
    for (int r = 0; r < p; r++) {
        if (send_count[r] > INT_MAX) st = too_many(err, send_count[r]);
        sc[r] = (int)FM_MIN(send_count[r], INT_MAX);
    }
    MPI_Alltoall(sc, 1, MPI_INT, rc, 1, MPI_INT, d->comm);
    int64_t sent = displacements(sc, p, sd);
    *recv_count = displacements(rc, p, rd);
    if (st == FM_OK && (sent < 0 || *recv_count < 0)) st = too_many(err, FM_MAX(sent, *recv_count));
    *recv = st == FM_OK && *recv_count > 0 ? fm_alloc(size * (size_t)*recv_count) : NULL;
    if (st == FM_OK && *recv_count > 0 && !*recv) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for a halo exchange");
    MPI_Datatype type;
    const int typed = st == FM_OK && record_type(size, &type);
    if (st == FM_OK && !typed) st = fm_fail(err, FM_ERR_INTERNAL, "MPI_Type_contiguous failed");
    st = fm_dist_agree(d, st, err);
    if (st == FM_OK) MPI_Alltoallv(send, sc, sd, type, *recv, rc, rd, type, d->comm);
    if (typed) MPI_Type_free(&type); /* also when another rank failed */
    if (st != FM_OK) fm_free(*recv), *recv = NULL, *recv_count = 0;
    free(sc);
    return st;
}

fm_status fm_dist_gather(const fm_dist *d, const void *mine, int64_t count, size_t size, void **all, int64_t *total,
                         fm_error *err)
{
    if (!d || d->size == 1) return copy_records(mine, count, size, all, total, err);
    *all = NULL, *total = 0;
    const int p = d->size, root = d->rank == 0;
    int *counts = calloc((size_t)p, 2 * sizeof(int)), *displ = counts + p, c = (int)FM_MIN(count, INT_MAX);
    if (!counts) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
    MPI_Gather(&c, 1, MPI_INT, counts, 1, MPI_INT, 0, d->comm);
    fm_status st = count > INT_MAX ? too_many(err, count) : FM_OK;
    if (root) {
        int64_t n = displacements(counts, p, displ);
        if (st == FM_OK && n < 0) st = too_many(err, n);
        if (st == FM_OK && n > 0 && !(*all = fm_alloc(size * (size_t)n))) st = fm_fail(err, FM_ERR_MEMORY, "out of memory");
        *total = st == FM_OK ? n : 0;
    }
    MPI_Datatype type;
    const int typed = st == FM_OK && record_type(size, &type);
    if (st == FM_OK && !typed) st = fm_fail(err, FM_ERR_INTERNAL, "MPI_Type_contiguous failed");
    st = fm_dist_agree(d, st, err);
    if (st == FM_OK) MPI_Gatherv(mine, c, type, *all, counts, displ, type, 0, d->comm);
    else if (root) fm_free(*all), *all = NULL, *total = 0;
    if (typed) MPI_Type_free(&type); /* also when another rank failed */
    free(counts);
    return st;
}

#else /* one process: every collective acts for P = 1 */

int fm_dist_launched(void) { return 0; }
fm_dist *fm_dist_init(int *argc, char ***argv, fm_error *err)
{
    (void)argc, (void)argv;
    fm_fail(err, FM_ERR_USAGE, "this flockmorph was built without MPI (FM_MPI=OFF)");
    return NULL;
}
void fm_dist_finalize(fm_dist *d) { (void)d; }
void fm_dist_abort(const fm_dist *d, int code) { (void)d, exit(code); }
int fm_dist_rank(const fm_dist *d) { return (void)d, 0; }
int fm_dist_size(const fm_dist *d) { return (void)d, 1; }
int fm_dist_size_here(const fm_dist *d) { return (void)d, 1; }
int fm_dist_first_here(const fm_dist *d) { return (void)d, 1; }
void fm_dist_bcast_here(const fm_dist *d, void *data, size_t bytes) { (void)d, (void)data, (void)bytes; }
void fm_dist_sum_i64(const fm_dist *d, int64_t *v, int count) { (void)d, (void)v, (void)count; }
void fm_dist_max_i64(const fm_dist *d, int64_t *v, int count) { (void)d, (void)v, (void)count; }
void fm_dist_max_f64(const fm_dist *d, double *v, int count) { (void)d, (void)v, (void)count; }
void fm_dist_sum_f64(const fm_dist *d, double *v, int count) { (void)d, (void)v, (void)count; }
void fm_dist_min_f32(const fm_dist *d, float *v, int count) { (void)d, (void)v, (void)count; }
void fm_dist_bcast(const fm_dist *d, void *data, size_t bytes, int root) { (void)d, (void)data, (void)bytes, (void)root; }
fm_status fm_dist_agree(const fm_dist *d, fm_status st, fm_error *err) { return (void)d, (void)err, st; }

fm_status fm_dist_gather(const fm_dist *d, const void *mine, int64_t count, size_t size, void **all, int64_t *total,
                         fm_error *err)
{
    (void)d;
    return copy_records(mine, count, size, all, total, err);
}

fm_status fm_dist_allgather(const fm_dist *d, const void *mine, int64_t count, size_t size, void **all, int64_t *total,
                            fm_error *err)
{
    return fm_dist_gather(d, mine, count, size, all, total, err);
}

fm_status fm_dist_exchange(const fm_dist *d, const void *send, const int64_t *send_count, size_t size, void **recv,
                           int64_t *recv_count, fm_error *err)
{
    return fm_dist_gather(d, send, send_count[0], size, recv, recv_count, err);
}

#endif

/* ---------------------------------------------------------------- memory a machine's ranks share */

struct fm_dist_shared {
    void *alone;  /* the only rank on its machine: a plain allocation */
    void *map;    /* several: the machine's segment, mapped (read-only but on its first rank) */
    size_t bytes; /* of the mapping */
};

#ifdef FM_HAVE_MPI
/* Segments that a job killed or hung between making a segment and removing its name left behind
 * (/dev/shm/flockmorph.PID.K whose process PID is gone): removed before a new one is made, so they
 * do not pile up in a machine's memory (issue 42). Another user's, or a live process's, stay. */
static void remove_stale_segments(void)
{
    DIR *dir = opendir("/dev/shm");
    struct dirent *e;
    while (dir && (e = readdir(dir)) != NULL) {
        long pid = 0;
        int k = 0, end = 0;
        if (sscanf(e->d_name, "flockmorph.%ld.%d%n", &pid, &k, &end) != 2 || e->d_name[end] || pid <= 0) continue;
        if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive (or not ours to ask about) */
        char name[300];
        snprintf(name, sizeof name, "/%s", e->d_name);
        shm_unlink(name);
    }
    if (dir) closedir(dir);
}

/* A segment of POSIX shared memory (/dev/shm), named for this process: its pages reserved now
 * (posix_fallocate), so that a full /dev/shm or a file-size limit (ulimit -f) fails here and not as
 * SIGBUS on a first touch. 0 or an errno. */
static int create_segment(char name[48], size_t bytes)
{
    static int made;
    struct rlimit limit;
    if (getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY && bytes > limit.rlim_cur) return EFBIG;
    remove_stale_segments();
    snprintf(name, 48, "/flockmorph.%ld.%d", (long)getpid(), ++made);
    int fd = shm_open(name, O_CREAT | O_EXCL | O_RDWR, 0600);
    if (fd < 0) return errno;
    int e = posix_fallocate(fd, 0, (off_t)bytes);
    close(fd);
    if (e) shm_unlink(name);
    return e;
}

static int map_segment(const char *name, size_t bytes, int writable, void **map)
{
    int fd = shm_open(name, writable ? O_RDWR : O_RDONLY, 0);
    if (fd < 0) return errno;
    *map = mmap(NULL, bytes, writable ? PROT_READ | PROT_WRITE : PROT_READ, MAP_SHARED, fd, 0);
    int e = *map == MAP_FAILED ? errno : 0;
    close(fd);
    if (e) *map = NULL;
    return e;
}

/* The machine's first rank makes the segment, every rank of the machine maps it, and once all
 * have, its name is removed: the memory lives while a rank maps it, and nothing outlives the job. */
static fm_status share_segment(const fm_dist *d, fm_dist_shared *s, size_t bytes, void **base, fm_error *err)
{
    struct { int e; char name[48]; } made = {0, ""};
    const int first = fm_dist_first_here(d);
    if (first) made.e = create_segment(made.name, bytes);
    fm_dist_bcast_here(d, &made, sizeof made);
    int e = made.e ? made.e : map_segment(made.name, bytes, first, &s->map), worst = 0;
    MPI_Allreduce(&e, &worst, 1, MPI_INT, MPI_MAX, d->here);
    if (first && !made.e) shm_unlink(made.name);
    if (!worst) {
        s->bytes = bytes, *base = s->map;
        return FM_OK;
    }
    if (s->map) munmap(s->map, bytes), s->map = NULL;
    return fm_fail(err, FM_ERR_MEMORY, "cannot make %.3g MB of memory that the %d ranks on this machine share "
                   "(POSIX shared memory, /dev/shm): %s%s", (double)bytes / 1e6, d->size_here, strerror(worst),
                   worst == EFBIG ? " (the file-size limit, ulimit -f)" : worst == ENOSPC ? " (/dev/shm is full or small)" : "");
}
#endif

/* The machine's segment: the first rank's `bytes` (64 more, to align), every rank's address of it. */
static fm_status allocate_shared(const fm_dist *d, fm_dist_shared *s, size_t bytes, void **base, fm_error *err)
{
#ifdef FM_HAVE_MPI
    if (d && d->size_here > 1) return share_segment(d, s, bytes + 64, base, err);
#else
    (void)d; /* one process: no other rank */
#endif
    if ((s->alone = *base = fm_alloc(bytes + 64))) return FM_OK;
    return fm_fail(err, FM_ERR_MEMORY, "out of memory for %.3g MB", (double)bytes / 1e6);
}

fm_dist_shared *fm_dist_shared_create(const fm_dist *d, size_t bytes, void **base, fm_error *err)
{
    *base = NULL;
    fm_dist_shared made = {0}, *s = NULL;
    fm_status st = allocate_shared(d, &made, bytes, base, err); /* every rank, in step: it is collective */
    if (st == FM_OK && !(s = malloc(sizeof *s))) st = fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if (s) *s = made;
    else if (made.map) munmap(made.map, made.bytes);
    else fm_free(made.alone);
    if (fm_dist_agree(d, st, err) == FM_OK) {
        *base = (void *)(((uintptr_t)*base + 63) & ~(uintptr_t)63);
        return s;
    }
    fm_dist_shared_free(s);
    *base = NULL;
    return NULL;
}

static size_t round_up_64(size_t bytes) { return (bytes + 63) & ~(size_t)63; }

fm_dist_shared *fm_dist_share_arrays(const fm_dist *d, void **const *p, const size_t *bytes, int count, fm_error *err)
{
    const int built = fm_dist_first_here(d);
    size_t total = 0;
    for (int i = 0; i < count; i++) {
        if (!built) *p[i] = NULL; /* the first rank's addresses, meaningless here */
        total += round_up_64(bytes[i]);
    }
    char *base = NULL;
    fm_dist_shared *s = fm_dist_shared_create(d, total, (void **)&base, err);
    for (size_t i = 0, offset = 0; s && i < (size_t)count; offset += round_up_64(bytes[i++])) {
        if (built && bytes[i] > 0) memcpy(base + offset, *p[i], bytes[i]);
        if (built) fm_free(*p[i]);
        *p[i] = base + offset;
    }
    return s;
}

/* No segment (a full /dev/shm, a file-size limit): each of the other ranks builds its own model, as
 * every rank did before models were shared; the first ranks keep theirs. Rank 0 says so. */
static fm_status build_unshared(const fm_dist *d, const fm_dist_model_ops *ops, const fm_scene_def *def,
                                const void *context, void **m, fm_error *err)
{
    if (fm_dist_rank(d) == 0)
        fprintf(stderr, "flockmorph: warning: %s; every rank builds its own model instead (docs/scale-out.md)\n",
                err ? err->message : "cannot share the model");
    if (fm_dist_first_here(d)) return FM_OK;
    ops->destroy(*m);
    *m = ops->build(def, context, NULL, NULL, err);
    return *m ? FM_OK : err ? err->status : FM_ERR_INTERNAL;
}

void *fm_dist_build_shared(const fm_dist *d, const fm_dist_model_ops *ops, const fm_scene_def *def, const void *context,
                           fm_progress_fn progress, void *user, fm_error *err)
{
    if (fm_dist_size(d) == 1) return ops->build(def, context, progress, user, err); /* one process: its own */
    const int first = fm_dist_first_here(d);
    void *m = first ? ops->build(def, context, progress, user, err) : calloc(1, ops->size);
    fm_status st = FM_OK;
    if (!m) st = first ? (err ? err->status : FM_ERR_INTERNAL) : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if (fm_dist_agree(d, st, err) != FM_OK) {
        if (m) ops->destroy(m);
        return NULL;
    }
    fm_dist_bcast_here(d, m, ops->size);
    if (!first) ops->take_scalars(m, def);
    void **p[FM_DIST_MAX_ARRAYS];
    size_t bytes[FM_DIST_MAX_ARRAYS];
    fm_dist_shared **shared = (fm_dist_shared **)((char *)m + ops->shared_offset);
    if ((*shared = fm_dist_share_arrays(d, p, bytes, ops->arrays(m, p, bytes), err)))
        st = first ? FM_OK : ops->build_replicated(m, err);
    else
        st = build_unshared(d, ops, def, context, &m, err);
    if (fm_dist_agree(d, st, err) == FM_OK) return m;
    if (m) ops->destroy(m);
    return NULL;
}

void fm_dist_shared_free(fm_dist_shared *s)
{
    if (!s) return;
    if (s->map) munmap(s->map, s->bytes);
    fm_free(s->alone);
    free(s);
}

/* ---------------------------------------------------------------- files every rank writes */

struct fm_dist_file {
    const fm_dist *d;
    fm_output_file names; /* PATH and PATH.partial */
    int fd;               /* one process: PATH.partial (pwrite) */
    fm_status st;         /* this rank's first failed write, its message in `failure` */
    fm_error failure;
#ifdef FM_HAVE_MPI
    MPI_File fh;          /* P ranks: MPI-IO */
#endif
};

static fm_status posix_failed(const fm_dist_file *f, int e, fm_error *err)
{
    e = e ? e : EIO;
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", f->names.path, strerror(e), fm_write_hint(e));
}

#ifdef FM_HAVE_MPI
static int one_process(const fm_dist_file *f) { return fm_dist_size(f->d) == 1; }

static fm_status mpi_failed(const fm_dist_file *f, int code, fm_error *err)
{
    char text[MPI_MAX_ERROR_STRING] = "";
    int len = 0, cls = 0;
    MPI_Error_string(code, text, &len);
    MPI_Error_class(code, &cls);
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", f->names.path, text,
                   cls == MPI_ERR_NO_SPACE ? fm_write_hint(ENOSPC) : "");
}
#endif

static fm_status close_partial(fm_dist_file *f, fm_status st, fm_error *err);

/* Every rank's handle on the file at names.partial, as it is (rank 0 created it, or it is the
 * cache being attached). */
static fm_status open_partial(fm_dist_file *f, fm_error *err)
{
#ifdef FM_HAVE_MPI
    if (!one_process(f)) {
        int rc = MPI_File_open(f->d->comm, f->names.partial, MPI_MODE_WRONLY, MPI_INFO_NULL, &f->fh);
        return rc == MPI_SUCCESS ? FM_OK : mpi_failed(f, rc, err);
    }
#endif
    errno = 0;
    if (f->fd < 0) f->fd = open(f->names.partial, O_WRONLY | O_CLOEXEC);
    return f->fd >= 0 ? FM_OK : posix_failed(f, errno, err);
}

/* Rank 0 creates the temporary file exclusively in PATH's folder (fm_output_create: never through
 * a link, never another process's) and every rank opens that one. */
fm_dist_file *fm_dist_file_open(const fm_dist *d, const char *path, fm_error *err)
{
    fm_dist_file *f = calloc(1, sizeof *f);
    fm_status st = f ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if (f) f->d = d, f->fd = -1, st = fm_output_name(&f->names, path, err);
    if (st == FM_OK && fm_dist_rank(d) == 0) st = fm_output_create_fixed(&f->names, path, err);
#ifdef FM_HAVE_MPI
    if (st == FM_OK && !one_process(f) && fm_dist_rank(d) == 0) close(f->names.fd), f->names.fd = -1; /* MPI-IO writes */
#endif
    if (fm_dist_agree(d, st, err) == FM_OK) {
        if (fm_dist_rank(d) == 0) f->fd = f->names.fd, f->names.fd = -1;
        fm_dist_bcast(d, f->names.partial, sizeof f->names.partial, 0);
        if (fm_dist_agree(d, open_partial(f, err), err) == FM_OK) return f;
        if (f->fd >= 0) close(f->fd);
    }
    if (f && fm_dist_rank(d) == 0) fm_output_discard(&f->names); /* unlinked: never a directory in the way */
    free(f);
    return NULL;
}

static fm_status write_chunk(fm_dist_file *f, uint64_t offset, const char *p, size_t n, fm_error *err)
{
#ifdef FM_HAVE_MPI
    if (!one_process(f)) {
        MPI_Status status;
        int got = 0, rc = MPI_File_write_at(f->fh, (MPI_Offset)offset, p, (int)n, MPI_BYTE, &status);
        if (rc != MPI_SUCCESS) return mpi_failed(f, rc, err);
        MPI_Get_count(&status, MPI_BYTE, &got);
        return (size_t)got == n ? FM_OK : posix_failed(f, ENOSPC, err); /* a short write: the disk is full */
    }
#endif
    while (n > 0) {
        errno = 0;
        ssize_t w = pwrite(f->fd, p, n, (off_t)offset);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return posix_failed(f, w == 0 ? ENOSPC : errno, err);
        p += w, n -= (size_t)w, offset += (uint64_t)w;
    }
    return FM_OK;
}

fm_status fm_dist_file_write_at(fm_dist_file *f, uint64_t offset, const void *bytes, size_t n, fm_error *err)
{
    const size_t most = (size_t)1 << 30; /* MPI counts are ints */
    for (size_t done = 0; f->st == FM_OK && done < n; done += most) {
        fm_status st = write_chunk(f, offset + done, (const char *)bytes + done, FM_MIN(most, n - done), &f->failure);
        if (st != FM_OK) f->st = st;
    }
    if (f->st != FM_OK && err) *err = f->failure;
    return f->st;
}

/* Syncs and closes this rank's handle (collective on P ranks). */
static fm_status close_partial(fm_dist_file *f, fm_status st, fm_error *err)
{
#ifdef FM_HAVE_MPI
    if (!one_process(f)) {
        int rc = MPI_File_sync(f->fh), closed = MPI_File_close(&f->fh);
        if (st == FM_OK && rc != MPI_SUCCESS) st = mpi_failed(f, rc, err);
        if (st == FM_OK && closed != MPI_SUCCESS) st = mpi_failed(f, closed, err);
        return st;
    }
#endif
    errno = 0;
    if (st == FM_OK && fsync(f->fd) != 0) st = posix_failed(f, errno, err);
    if (close(f->fd) != 0 && st == FM_OK) st = posix_failed(f, errno, err);
    return st;
}

fm_status fm_dist_file_commit(fm_dist_file *f, fm_status st, fm_error *err)
{
    const fm_dist *d = f->d;
    if (st == FM_OK && f->st != FM_OK) {
        st = f->st;
        if (err) *err = f->failure;
    }
    st = fm_dist_agree(d, close_partial(f, st, err), err);
    if (fm_dist_rank(d) == 0) {
        int e = st == FM_OK ? fm_output_rename(&f->names) : 0; /* the folder synced too */
        if (e) st = posix_failed(f, e, err);
        if (st != FM_OK) fm_output_discard(&f->names);
    }
    free(f);
    return fm_dist_agree(d, st, err);
}

fm_dist_file *fm_dist_file_attach(const fm_dist *d, const char *path, fm_error *err)
{
    fm_dist_file *f = calloc(1, sizeof *f);
    fm_status st = f ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if (f) {
        f->d = d, f->fd = -1, f->names.fd = f->names.dir = -1;
        snprintf(f->names.path, sizeof f->names.path, "%s", path);
        snprintf(f->names.partial, sizeof f->names.partial, "%s", path); /* written where it is */
        st = open_partial(f, err);
    }
    if (fm_dist_agree(d, st, err) == FM_OK) return f;
    if (st == FM_OK) close_partial(f, FM_ERR_IO, NULL);
    free(f);
    return NULL;
}

fm_status fm_dist_file_sync(fm_dist_file *f, fm_error *err)
{
    fm_status st = f->st;
    if (st != FM_OK && err) *err = f->failure;
#ifdef FM_HAVE_MPI
    if (!one_process(f)) {
        int rc = MPI_File_sync(f->fh); /* collective: every rank calls it, whatever its status */
        if (st == FM_OK && rc != MPI_SUCCESS) st = mpi_failed(f, rc, err);
        return fm_dist_agree(f->d, st, err);
    }
#endif
    errno = 0;
    if (st == FM_OK && fsync(f->fd) != 0) st = posix_failed(f, errno, err);
    return fm_dist_agree(f->d, st, err);
}

fm_status fm_dist_file_detach(fm_dist_file *f, fm_error *err)
{
    const fm_dist *d = f->d;
    fm_status st = f->st;
    if (st != FM_OK && err) *err = f->failure;
    st = fm_dist_agree(d, close_partial(f, st, err), err);
    free(f);
    return st;
}
