/* Replays a fuzz target's inputs without libFuzzer, so ctest (and its ASan run) checks them:
 *   test_fuzz_NAME DIR...   feeds every file of every DIR (sorted; hidden files skipped; a missing
 *                           DIR is empty) to LLVMFuzzerTestOneInput.
 * The target aborts on a crash or an unclean rejection (fuzz_check.h); this fails when there was
 * nothing to replay. */
#define _DEFAULT_SOURCE
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int replay_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return fprintf(stderr, "%s: cannot open\n", path), -1;
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    rewind(f);
    uint8_t *data = malloc(size > 0 ? (size_t)size : 1);
    int ok = data && size >= 0 && fread(data, 1, (size_t)size, f) == (size_t)size;
    fclose(f);
    if (ok) {
        printf("replay %s\n", path);
        fflush(stdout); /* the name of the input shows above a crash report */
        LLVMFuzzerTestOneInput(data, (size_t)size);
    }
    free(data);
    return ok ? 1 : (fprintf(stderr, "%s: cannot read\n", path), -1);
}

static int not_hidden(const struct dirent *e) { return e->d_name[0] != '.'; }

/* Number of inputs replayed from dir, or -1 on a read error. */
static int replay_dir(const char *dir)
{
    struct dirent **names;
    int count = scandir(dir, &names, not_hidden, alphasort), replayed = 0;
    for (int i = 0; i < count; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, names[i]->d_name);
        int r = replay_file(path);
        replayed = r < 0 || replayed < 0 ? -1 : replayed + r;
        free(names[i]);
    }
    if (count >= 0) free(names);
    return replayed;
}

int main(int argc, char **argv)
{
    int total = 0;
    for (int i = 1; i < argc; i++) {
        int n = replay_dir(argv[i]);
        if (n < 0) return 1;
        total += n;
    }
    printf("%d inputs replayed without a crash\n", total);
    if (total == 0) fprintf(stderr, "no inputs found: the corpus is missing\n");
    return total > 0 ? 0 : 1;
}
