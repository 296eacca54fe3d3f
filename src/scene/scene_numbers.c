/* scene_numbers.c — numbers in text mesh files that a float cannot hold.
 *
 * Assimp's number parser (fast_atof) does not report range errors: an OBJ vertex
 * coordinate of two million digits loaded as a finite 1, and 1e-40 as a float
 * denormal. So before Assimp reads a text file, its coordinate tokens are read
 * again with strtod, which does report them, and the file's buffer is rewritten
 * in place, token for token (same length, so Assimp sees the same lines):
 *   - beyond float's range (overflow, any number of digits): "inf", so the
 *     triangles using it are dropped and counted as NaN/Inf by scene_build;
 *   - non-zero but below float's normal range (1.18e-38, underflow to a
 *     denormal or to 0): "0", which is what a float can hold of it;
 *   - finite in float but beyond SCENE_COORD_MAX: left, and counted here so the
 *     report names the file (scene_build drops those triangles).
 * Which tokens: OBJ `v` and `vn` lines, ASCII PLY after its header, OFF after its
 * first line, ASCII STL `vertex` and `facet normal` lines. Comments are skipped.
 */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/scene/scene_internal.h"

/* Length of the decimal number spelled at p ([+-] digits [. digits] [e [+-] digits],
 * at least one digit before the exponent), or 0 when p does not start one. */
static size_t number_length(const char *p, const char *end)
{
    const char *q = p;
    if (q < end && (*q == '+' || *q == '-')) ++q;
    size_t digits = 0;
    while (q < end && *q >= '0' && *q <= '9') ++q, ++digits;
    if (q < end && *q == '.') {
        ++q;
        while (q < end && *q >= '0' && *q <= '9') ++q, ++digits;
    }
    if (!digits) return 0;
    if (q < end && (*q == 'e' || *q == 'E')) {
        const char *e = q + 1;
        if (e < end && (*e == '+' || *e == '-')) ++e;
        const char *d = e;
        while (e < end && *e >= '0' && *e <= '9') ++e;
        if (e > d) q = e;
    }
    return (size_t)(q - p);
}

static int is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/* Checks and rewrites the whitespace-separated tokens of line [p, end). */
static void scan_tokens(char *p, char *end, scene_number_scan *out)
{
    while (p < end) {
        while (p < end && is_space(*p)) ++p;
        if (p >= end || *p == '#') return;
        char *tok = p;
        while (p < end && !is_space(*p)) ++p;
        size_t len = (size_t)(p - tok);
        if (number_length(tok, p) != len) continue; /* not a plain number: Assimp's to judge */
        /* strtod needs a terminator: the token ends at whitespace or the buffer's NUL. */
        char saved = *p;
        *p = '\0';
        errno = 0;
        double v = strtod(tok, NULL);
        int range = errno == ERANGE;
        *p = saved;
        const char *put = NULL;
        if (!isfinite(v) || fabs(v) > FLT_MAX || (range && fabs(v) > 1.0)) {
            out->overflow++;
            put = "inf";
        } else if (v != 0.0 && fabs(v) < FLT_MIN) {
            out->underflow++;
            put = "0";
        } else if (range && v == 0.0) { /* e.g. 1e-400: read as 0 by strtod itself */
            out->underflow++;
            put = "0";
        } else if (fabs(v) > SCENE_COORD_MAX) {
            out->out_of_range++;
        }
        if (put && strlen(put) <= len) {
            memset(tok, ' ', len);
            memcpy(tok, put, strlen(put));
        }
    }
}

static int starts_with_word(const char *p, const char *end, const char *word)
{
    size_t n = strlen(word);
    return (size_t)(end - p) > n && memcmp(p, word, n) == 0 && is_space(p[n]);
}

void scene_scan_numbers(const char *ext, char *data, size_t size, scene_number_scan *out)
{
    memset(out, 0, sizeof *out);
    int obj = strcmp(ext, "obj") == 0, ply = strcmp(ext, "ply") == 0, off = strcmp(ext, "off") == 0;
    int stl = strcmp(ext, "stl") == 0 && size >= 5 && memcmp(data, "solid", 5) == 0;
    if (!obj && !ply && !off && !stl) return;
    if (ply) { /* ASCII only, and only after the header */
        const char *hdr = strstr(data, "end_header");
        if (!hdr || !strstr(data, "format ascii") || strstr(data, "format ascii") > hdr) return;
    }
    int body = !(ply || off); /* PLY and OFF: from the line after their header */
    char *end = data + size;
    for (char *line = data; line < end;) {
        char *eol = memchr(line, '\n', (size_t)(end - line));
        if (!eol) eol = end;
        char *p = line;
        while (p < eol && is_space(*p)) ++p;
        if (obj) {
            if (starts_with_word(p, eol, "v") || starts_with_word(p, eol, "vn")) scan_tokens(p + 2, eol, out);
        } else if (stl) {
            if (starts_with_word(p, eol, "vertex") || starts_with_word(p, eol, "facet")) scan_tokens(p, eol, out);
        } else if (body) {
            scan_tokens(p, eol, out);
        } else if (ply) {
            body = eol - p >= 10 && memcmp(p, "end_header", 10) == 0; /* the header's last line */
        } else if (p < eol && *p != '#') {
            body = 1; /* OFF: its first line ("OFF" or the counts) */
        }
        line = eol + 1;
    }
}
