/* samp_record_test — GL's costs kept per machine (sampling/samp_record.h): none
 * at first; a note is read back; a later note keeps the lower of each cost and
 * leaves a cost it did not measure (< 0) alone; other resolutions and platforms
 * are other lines; lines it cannot read are dropped, not fatal; an empty
 * LUMESH_CACHE_DIR switches it off; a directory that cannot be made is no error. */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/samp_record.h"
#include "tests/test_util.h"

static int read_text(const char *path, char *out, size_t size)
{
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    size_t n = fread(out, 1, size - 1, f);
    out[n] = '\0';
    fclose(f);
    return 1;
}

int main(void)
{
    char dir[1024], path[1100], text[4096] = "";
    snprintf(dir, sizeof dir, "%s/samp_record_dir/a/b", LUMESH_TMP_DIR);
    snprintf(path, sizeof path, "%s/gl-costs", dir);
    remove(path);
    setenv("LUMESH_CACHE_DIR", dir, 1);
    char where[1100];
    samp_record_path(where, sizeof where);
    CHECK_MSG(strcmp(where, path) == 0, "the file is %s, not %s", where, path);

    const samp_desc d = {.backend = SAMP_BACKEND_AUTO}, hires = {.backend = SAMP_BACKEND_AUTO, .indirect_res = 128},
                    osmesa = {.backend = SAMP_BACKEND_AUTO, .gl_platform = GLCTX_OSMESA};
    samp_record rec;
    CHECK(samp_record_get(&d, &rec) == 0 && rec.direct_us < 0.0 && rec.indirect_us < 0.0);
    /* The first note makes the directories and the file. */
    samp_record_note(&d, 150.0, 50000.0);
    CHECK(samp_record_get(&d, &rec) == 1 && rec.direct_us == 150.0 && rec.indirect_us == 50000.0);
    /* The lower of each, and a cost not measured (< 0) left alone. */
    samp_record_note(&d, 200.0, 40000.0);
    CHECK(samp_record_get(&d, &rec) == 1 && rec.direct_us == 150.0 && rec.indirect_us == 40000.0);
    samp_record_note(&d, -1.0, 45000.0);
    CHECK(samp_record_get(&d, &rec) == 1 && rec.direct_us == 150.0 && rec.indirect_us == 40000.0);
    /* Other resolutions, another platform: lines of their own. Default resolutions
     * are 64, so a desc that names 64 is the same line. */
    CHECK(samp_record_get(&hires, &rec) == 0 && samp_record_get(&osmesa, &rec) == 0);
    samp_record_note(&hires, 10.0, 20.0);
    samp_record_note(&osmesa, -1.0, 7.0);
    CHECK(samp_record_get(&hires, &rec) == 1 && rec.direct_us == 10.0 && rec.indirect_us == 20.0);
    CHECK(samp_record_get(&osmesa, &rec) == 1 && rec.direct_us < 0.0 && rec.indirect_us == 7.0);
    const samp_desc named = {.backend = SAMP_BACKEND_AUTO, .direct_res = 64, .indirect_res = 64};
    CHECK(samp_record_get(&named, &rec) == 1 && rec.direct_us == 150.0);
    /* Lines it cannot read are dropped at the next note; the others stay. */
    FILE *f = fopen(path, "a");
    CHECK(f != NULL);
    if (f) {
        fputs("v1 egl 64\ngarbage\nv1 egl 64 64 otherhost nan 3\nv2 egl 64 64 x 1 1\n", f);
        fclose(f);
    }
    CHECK(samp_record_get(&d, &rec) == 1 && rec.indirect_us == 40000.0);
    samp_record_note(&d, 100.0, -1.0);
    CHECK(samp_record_get(&d, &rec) == 1 && rec.direct_us == 100.0 && rec.indirect_us == 40000.0);
    CHECK(read_text(path, text, sizeof text));
    CHECK_MSG(strstr(text, "garbage") == NULL && strstr(text, "nan") == NULL && strstr(text, "v2") == NULL,
              "unreadable lines kept:\n%s", text);
    int lines = 0;
    for (const char *c = text; *c; ++c) lines += *c == '\n';
    CHECK_MSG(lines == 4, "%d lines (a comment and three records expected):\n%s", lines, text);
    /* Switched off: nothing read, nothing written. */
    setenv("LUMESH_CACHE_DIR", "", 1);
    samp_record_path(where, sizeof where);
    CHECK(where[0] == '\0' && samp_record_get(&d, &rec) == 0);
    /* A directory that cannot be made (under a file): no error, no record. */
    char blocked[1200];
    snprintf(blocked, sizeof blocked, "%s/gl-costs/sub", dir);
    setenv("LUMESH_CACHE_DIR", blocked, 1);
    samp_record_note(&d, 1.0, 1.0);
    CHECK(samp_record_get(&d, &rec) == 0);
    printf("samp_record: %s\n%s", path, text);
    return test_finish("samp_record_test");
}
