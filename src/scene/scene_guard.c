/* scene_guard.c — checks in front of Assimp's parsers: what its readers cannot
 * take safely is rejected with a message, or rewritten, before Assimp sees it.
 * Each guard answers a finding (docs/robustness.md has the list and the fuzzing
 * that found them; every case is a file in tests/badinput).
 *
 * Numbers a float cannot hold (scene_guard_numbers). Assimp's number parser (fast_atof) does not report range errors: an OBJ vertex
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
        /* Without an exponent, 18 characters cannot leave the range (under 10^18,
         * above 10^-17 when not 0): the common case skips strtod. */
        if (len <= 18 && !memchr(tok, 'e', len) && !memchr(tok, 'E', len)) continue;
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

/* The line at *at (ending at a newline or `end`): its first non-blank character,
 * its end in *eol; *at moves past it. */
static char *take_line(char **at, char *end, char **eol)
{
    char *line = *at, *e = memchr(line, '\n', (size_t)(end - line));
    if (!e) e = end;
    *eol = e;
    *at = e + 1;
    while (line < e && is_space(*line)) ++line;
    return line;
}

static int starts_with_word(const char *p, const char *end, const char *word)
{
    size_t n = strlen(word);
    return (size_t)(end - p) > n && memcmp(p, word, n) == 0 && is_space(p[n]);
}

void scene_guard_numbers(const char *ext, char *data, size_t size, scene_number_scan *out)
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
    for (char *at = data; at < end;) {
        char *eol, *p = take_line(&at, end, &eol);
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
    }
}

/* ---- MTL: texture statements before the first newmtl --------------------- */

/* Assimp 5.2's MTL reader dereferences its current material, NULL until the first
 * `newmtl`, for texture statements (map_Kd, bump, disp, norm ...): a segmentation
 * fault on a two-line file. Such statements describe no material, so they are
 * commented out ('#' over their first character). Only texture statements: the
 * guard also runs over the OBJ itself (a file may name itself as its material
 * library), where they mean nothing either. */
uint32_t scene_guard_mtl(char *data, size_t size)
{
    static const char *const textures[] = {"map_", "bump", "disp", "decal", "norm", "refl", NULL};
    uint32_t dropped = 0;
    char *end = data + size;
    for (char *at = data; at < end;) {
        char *eol, *p = take_line(&at, end, &eol);
        if (eol - p >= 6 && memcmp(p, "newmtl", 6) == 0) return dropped;
        for (const char *const *t = textures; *t; ++t)
            if ((size_t)(eol - p) >= strlen(*t) && memcmp(p, *t, strlen(*t)) == 0) {
                *p = '#';
                dropped++;
                break;
            }
    }
    return dropped;
}

/* ---- PLY: the header's grammar -------------------------------------------- */

static int word_in(const char *w, size_t n, const char *const *set)
{
    for (; *set; ++set)
        if (strlen(*set) == n && memcmp(w, *set, n) == 0) return 1;
    return 0;
}

/* The next whitespace-separated word of [*p, end): its start and length. */
static size_t next_word(const char **p, const char *end, const char **w)
{
    while (*p < end && is_space(**p)) ++*p;
    *w = *p;
    while (*p < end && !is_space(**p)) ++*p;
    return (size_t)(*p - *w);
}

/* Assimp 5.2's PLY reader loops forever on some broken headers (one found by
 * fuzzing: an `element` line with bytes 0x01 0x00 in its name), so the header is
 * checked against the PLY grammar first: `ply`, one `format`, `comment` and
 * `obj_info` lines, `element NAME COUNT`, `property TYPE NAME`, `property list
 * TYPE TYPE NAME`, `end_header`, printable ASCII only. The counts must fit the
 * file: every element takes at least one byte (two in ASCII: a digit and a
 * separator). Returns NULL, or what is wrong (static text) with *line set. */
const char *scene_guard_ply(const char *data, size_t size, int *line_out)
{
    static const char *const types[] = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double",
                                        "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32",
                                        "float64", NULL};
    static const char *const formats[] = {"ascii", "binary_little_endian", "binary_big_endian", NULL};
    const char *end = data + size, *p = data;
    double elements = 0.0;
    int line = 0, ascii = 0, have_format = 0, have_element = 0;
    for (;;) {
        ++line;
        *line_out = line;
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) return "the header has no end_header line";
        for (const char *c = p; c < eol; ++c) /* printable ASCII, tabs, CR: no \v or \f (Assimp looped on one) */
            if ((unsigned char)*c > 126 || ((unsigned char)*c < 32 && *c != '\t' && *c != '\r'))
                return "the header holds bytes that are not text";
        const char *q = p, *w;
        size_t n = next_word(&q, eol, &w);
        if (line == 1) {
            if (n != 3 || memcmp(w, "ply", 3) != 0) return "the file does not start with 'ply'";
        } else if (n == 7 && memcmp(w, "comment", 7) == 0) {
        } else if (n == 8 && memcmp(w, "obj_info", 8) == 0) {
        } else if (n == 6 && memcmp(w, "format", 6) == 0) {
            const char *f;
            size_t fn = next_word(&q, eol, &f);
            if (have_format || !word_in(f, fn, formats)) return "a 'format' line that is not ascii or binary";
            ascii = fn == 5;
            have_format = 1;
        } else if (n == 7 && memcmp(w, "element", 7) == 0) {
            const char *name, *count;
            size_t nn = next_word(&q, eol, &name), cn = next_word(&q, eol, &count);
            if (!nn || !cn || cn > 12) return "an 'element' line that is not 'element NAME COUNT'";
            double c = 0.0;
            for (size_t i = 0; i < cn; ++i) {
                if (count[i] < '0' || count[i] > '9') return "an 'element' count that is not a whole number";
                c = 10.0 * c + (count[i] - '0');
            }
            elements += c;
            have_element = 1;
        } else if (n == 8 && memcmp(w, "property", 8) == 0) {
            const char *t, *name;
            size_t tn = next_word(&q, eol, &t);
            if (!have_element) return "a 'property' line before any 'element'";
            if (tn == 4 && memcmp(t, "list", 4) == 0) {
                const char *t2;
                size_t t1n = next_word(&q, eol, &t), t2n = next_word(&q, eol, &t2);
                if (!word_in(t, t1n, types) || !word_in(t2, t2n, types))
                    return "a 'property list' line with an unknown type";
            } else if (!word_in(t, tn, types)) {
                return "a 'property' line with an unknown type";
            }
            if (!next_word(&q, eol, &name)) return "a 'property' line without a name";
        } else if (n == 10 && memcmp(w, "end_header", 10) == 0) {
            if (!have_format) return "the header has no 'format' line";
            double body = (double)(end - (eol + 1));
            if (elements * (ascii ? 2.0 : 1.0) > body + 1.0) return "the header counts more elements than the file holds";
            return NULL;
        } else if (n) {
            return "a header line that PLY does not define";
        }
        p = eol + 1;
    }
}

/* ---- glTF: base64 in data URIs -------------------------------------------- */

/* Assimp 5.2 leaks the decoded buffer of a glTF data URI whose base64 holds a
 * byte outside the alphabet. Every `"data:...;base64,` string of the file (the
 * JSON of a .gltf, or a .glb's JSON chunk) must hold only A-Z a-z 0-9 + / = up to
 * its closing quote. Returns NULL or what is wrong. */
const char *scene_guard_gltf(const char *data, size_t size)
{
    static const char mark[] = ";base64,";
    const char *end = data + size;
    for (const char *p = data; p < end;) {
        const char *hit = memchr(p, ';', (size_t)(end - p));
        if (!hit) break;
        p = hit + 1;
        if ((size_t)(end - hit) < sizeof mark - 1 || memcmp(hit, mark, sizeof mark - 1) != 0) continue;
        for (p = hit + sizeof mark - 1; p < end && *p != '"'; ++p) {
            char c = *p;
            int ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '+' ||
                     c == '/' || c == '=';
            if (!ok) return "a data URI whose base64 holds a byte outside the base64 alphabet";
        }
    }
    return NULL;
}
