/* A full disk for the tests of failing writes: a small tmpfs mounted on a folder of the test's
 * scratch directory, where a file can be created but every write past `free_bytes` fails with
 * ENOSPC. The writers never follow a symlink at their temporary name (issue 42), so /dev/full can
 * no longer stand in for the disk. Mounting needs root (CAP_SYS_ADMIN): elsewhere the caller
 * skips. Include after test_macros.h with _POSIX_C_SOURCE (or _DEFAULT_SOURCE) defined. */
#ifndef FM_TEST_FULL_DISK_H
#define FM_TEST_FULL_DISK_H

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

enum { FULL_DISK_PAGE = 4096 };

/* Mounts a tmpfs of `free_bytes` (rounded up to whole pages; 0: one page, filled so that nothing
 * is left) on dir, made if missing; 0, or -1 (and a note) when this process may not mount. */
static inline int full_disk_mount(const char *dir, size_t free_bytes)
{
    umount2(dir, MNT_DETACH); /* a mount a failed earlier run left */
    mkdir(dir, 0777);
    size_t pages = free_bytes ? (free_bytes + FULL_DISK_PAGE - 1) / FULL_DISK_PAGE : 1;
    char options[64];
    snprintf(options, sizeof options, "size=%zu", pages * FULL_DISK_PAGE);
    if (mount("tmpfs", dir, "tmpfs", 0, options) != 0) {
        printf("  (skipped: cannot mount a tmpfs on %s: %s; run as root)\n", dir, strerror(errno));
        return -1;
    }
    if (free_bytes) return 0;
    char fill[4200];
    snprintf(fill, sizeof fill, "%s/fill", dir);
    int fd = open(fill, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    static const char page[FULL_DISK_PAGE];
    while (fd >= 0 && write(fd, page, sizeof page) > 0) {}
    if (fd >= 0) close(fd);
    return 0;
}

/* The entries in dir, . and .. aside (a writer's partial files left behind show here). */
static inline int files_in(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));) n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    if (d) closedir(d);
    return n;
}

static inline void full_disk_unmount(const char *dir)
{
    umount2(dir, MNT_DETACH);
    rmdir(dir);
}

#endif
