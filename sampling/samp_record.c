/* samp_record.c — GL's cheapest costs on this machine, kept between runs
 * (samp_record.h). A few lines of text; every failure leaves things as they
 * would be without the file. */
#define _POSIX_C_SOURCE 200809L /* gethostname, strtok_r */
#include "sampling/samp_record.h"

#include <ctype.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "src/base/util.h"

#ifndef PATH_MAX
#define PATH_MAX 4096
#endif

enum { RECORD_LINES_MAX = 64, RECORD_HOST_MAX = 64, RECORD_FILE_MAX = 16384 };

typedef struct record_line {
    char platform[16];
    int direct_res, indirect_res;
    char host[RECORD_HOST_MAX];
    double direct_us, indirect_us;
} record_line;

static const char *platform_name(glctx_platform p) { return p == GLCTX_OSMESA ? "osmesa" : "egl"; }

/* The key of desc on this host (resolutions as the GL back end resolves 0). */
static void key_of(const samp_desc *desc, record_line *k)
{
    memset(k, 0, sizeof *k);
    snprintf(k->platform, sizeof k->platform, "%s", platform_name(desc->gl_platform));
    k->direct_res = desc->direct_res > 0 ? desc->direct_res : 64;
    k->indirect_res = desc->indirect_res > 0 ? desc->indirect_res : 64;
    if (gethostname(k->host, sizeof k->host - 1) != 0 || !k->host[0]) snprintf(k->host, sizeof k->host, "unknown");
    for (char *c = k->host; *c; ++c) /* one word in the file */
        if (isspace((unsigned char)*c)) *c = '_';
}

static int same_key(const record_line *a, const record_line *b)
{
    return strcmp(a->platform, b->platform) == 0 && a->direct_res == b->direct_res &&
           a->indirect_res == b->indirect_res && strcmp(a->host, b->host) == 0;
}

/* The directory of the file: $LUMESH_CACHE_DIR, $XDG_CACHE_HOME/lumesh or
 * $HOME/.cache/lumesh; 0 when switched off or unknown. */
static int record_dir(char *out, size_t size)
{
    const char *d = getenv("LUMESH_CACHE_DIR");
    int n;
    if (d) {
        if (!d[0]) return 0; /* switched off */
        n = snprintf(out, size, "%s", d);
    } else if ((d = getenv("XDG_CACHE_HOME")) && d[0]) {
        n = snprintf(out, size, "%s/lumesh", d);
    } else if ((d = getenv("HOME")) && d[0]) {
        n = snprintf(out, size, "%s/.cache/lumesh", d);
    } else {
        return 0;
    }
    return n > 0 && (size_t)n < size;
}

void samp_record_path(char *out, size_t size)
{
    char dir[PATH_MAX];
    if (!size) return;
    out[0] = '\0';
    if (!record_dir(dir, sizeof dir) || !lm_path_join(dir, "gl-costs", out, size)) out[0] = '\0';
}

/* The lines of the file that read as records (others are dropped). */
static size_t read_lines(const char *path, record_line *lines, size_t cap)
{
    char *text = NULL;
    size_t size = 0, n = 0;
    if (lm_read_file(path, RECORD_FILE_MAX, &text, &size, NULL) != LM_OK) return 0;
    char *save = NULL;
    for (char *line = strtok_r(text, "\n", &save); line && n < cap; line = strtok_r(NULL, "\n", &save)) {
        record_line l;
        char version[8];
        memset(&l, 0, sizeof l);
        if (sscanf(line, "%7s %15s %d %d %63s %lf %lf", version, l.platform, &l.direct_res, &l.indirect_res, l.host,
                   &l.direct_us, &l.indirect_us) == 7 &&
            strcmp(version, "v1") == 0 && l.direct_res > 0 && l.indirect_res > 0 && isfinite(l.direct_us) &&
            isfinite(l.indirect_us))
            lines[n++] = l;
    }
    free(text);
    return n;
}

int samp_record_get(const samp_desc *desc, samp_record *out)
{
    out->direct_us = out->indirect_us = -1.0;
    char path[PATH_MAX];
    samp_record_path(path, sizeof path);
    if (!desc || !path[0]) return 0;
    record_line *lines = malloc(RECORD_LINES_MAX * sizeof *lines);
    if (!lines) return 0;
    record_line key;
    key_of(desc, &key);
    size_t n = read_lines(path, lines, RECORD_LINES_MAX);
    int found = 0;
    for (size_t i = 0; i < n && !found; ++i)
        if (same_key(&lines[i], &key)) {
            out->direct_us = lines[i].direct_us;
            out->indirect_us = lines[i].indirect_us;
            found = 1;
        }
    free(lines);
    return found;
}

/* mkdir -p: every missing directory of `dir`. */
static int make_dirs(const char *dir)
{
    char p[PATH_MAX];
    int n = snprintf(p, sizeof p, "%s", dir);
    if (n <= 0 || (size_t)n >= sizeof p) return 0;
    for (char *c = p + 1; *c; ++c) {
        if (*c != '/') continue;
        *c = '\0';
        if (mkdir(p, 0755) != 0 && access(p, F_OK) != 0) return 0;
        *c = '/';
    }
    return mkdir(p, 0755) == 0 || access(p, F_OK) == 0;
}

/* The whole file, replaced at once (lm_write_file); nothing if it does not fit. */
static void write_lines(const char *path, const record_line *lines, size_t n)
{
    char *text = malloc(RECORD_FILE_MAX);
    if (!text) return;
    int len = snprintf(text, RECORD_FILE_MAX,
                       "# lumesh: the GL back end's cheapest cost a point measured on this machine "
                       "(microseconds; docs/sampling.md)\n");
    for (size_t i = 0; i < n && len > 0 && len < RECORD_FILE_MAX; ++i) {
        int k = snprintf(text + len, (size_t)(RECORD_FILE_MAX - len), "v1 %s %d %d %s %.6g %.6g\n",
                         lines[i].platform, lines[i].direct_res, lines[i].indirect_res, lines[i].host,
                         lines[i].direct_us, lines[i].indirect_us);
        len = k < 0 ? -1 : len + k;
    }
    if (len > 0 && len < RECORD_FILE_MAX) (void)lm_write_file(path, "txt", text, (size_t)len, NULL);
    free(text);
}

void samp_record_note(const samp_desc *desc, double direct_us, double indirect_us)
{
    if (!desc || !(direct_us >= 0.0 || indirect_us >= 0.0)) return;
    char dir[PATH_MAX], path[PATH_MAX];
    samp_record_path(path, sizeof path);
    if (!path[0] || !record_dir(dir, sizeof dir) || !make_dirs(dir)) return;
    record_line *lines = malloc((RECORD_LINES_MAX + 1) * sizeof *lines);
    if (!lines) return;
    record_line key;
    key_of(desc, &key);
    size_t n = read_lines(path, lines, RECORD_LINES_MAX), i = 0;
    while (i < n && !same_key(&lines[i], &key)) ++i;
    if (i == n) {
        key.direct_us = key.indirect_us = -1.0;
        lines[n++] = key;
    }
    record_line *l = &lines[i];
    if (isfinite(direct_us) && direct_us >= 0.0 && (l->direct_us < 0.0 || direct_us < l->direct_us))
        l->direct_us = direct_us;
    if (isfinite(indirect_us) && indirect_us >= 0.0 && (l->indirect_us < 0.0 || indirect_us < l->indirect_us))
        l->indirect_us = indirect_us;
    write_lines(path, lines, n);
    free(lines);
}
