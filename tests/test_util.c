#include "test_util.h"

int test_failures = 0;
int test_checks = 0;

int test_finish(const char *name)
{
    printf("%s: %d checks, %d failed\n", name, test_checks, test_failures);
    return test_failures == 0 && test_checks > 0 ? 0 : 1;
}

void test_write_file(const char *name, const char *text, char *path_out, size_t n)
{
    snprintf(path_out, n, "%s/%s", LUMESH_TMP_DIR, name);
    FILE *f = fopen(path_out, "wb");
    CHECK_MSG(f != NULL, "cannot write %s", path_out);
    if (!f) return;
    fputs(text, f);
    fclose(f);
}
