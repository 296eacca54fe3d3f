/* test_util.h — a minimal assertion layer for ctest programs.
 * A failed CHECK prints file:line and the condition and marks the test failed;
 * main returns test_finish(), non-zero when anything failed. */
#ifndef LUMESH_TEST_UTIL_H
#define LUMESH_TEST_UTIL_H

#include <stdio.h>

extern int test_failures;
extern int test_checks;

#define CHECK(cond)                                                                   \
    do {                                                                              \
        test_checks++;                                                                \
        if (!(cond)) {                                                                \
            test_failures++;                                                          \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);  \
        }                                                                             \
    } while (0)

#define CHECK_MSG(cond, ...)                                                          \
    do {                                                                              \
        test_checks++;                                                                \
        if (!(cond)) {                                                                \
            test_failures++;                                                          \
            fprintf(stderr, "%s:%d: CHECK failed: %s: ", __FILE__, __LINE__, #cond);  \
            fprintf(stderr, __VA_ARGS__);                                             \
            fputc('\n', stderr);                                                      \
        }                                                                             \
    } while (0)

#define CHECK_NEAR(a, b, tol)                                                          \
    do {                                                                               \
        double ca_ = (double)(a), cb_ = (double)(b);                                   \
        test_checks++;                                                                 \
        if (!(ca_ - cb_ <= (tol) && cb_ - ca_ <= (tol))) {                              \
            test_failures++;                                                           \
            fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.9g, %s = %.9g, tol %g\n", \
                    __FILE__, __LINE__, #a, ca_, #b, cb_, (double)(tol));              \
        }                                                                              \
    } while (0)

#include <stddef.h>
#include <stdint.h>

/* Writes text to LUMESH_TMP_DIR/name (the test's build directory) and puts the
 * full path into path_out. A failure to write is a failed check. */
void test_write_file(const char *name, const char *text, char *path_out, size_t n);

/* Writes an OBJ icosphere of radius `radius` about the origin, `level` times
 * subdivided (20·4^level faces), wound to face the centre. Returns the relative
 * bound (R/d)² − 1 on how far the irradiance I·cosθ/r² from a point light at the
 * centre departs from I/R² on its facets (d: the smallest facet-plane distance). */
double test_write_icosphere(int level, double radius, const char *path);

/* A diffuse plane y = 0 under a parallel, downward-facing square area light, the
 * camera between them at (0, cam_height, 0) looking straight down with up
 * (0, 0, -1) (screen right = +x, screen up = -z; the camera is not geometry).
 * With the model transport every image sample is kd/π · Le · G(x), G by
 * Lambert's formula: the bounce adds nothing (the light's kd is 0). */
typedef struct test_plane {
    double kd[3], le[3];
    double ks[3], n;           /* the plane's modified Phong lobe; ks 0: none */
    double plane_half;         /* half the plane's side; 0 = 4 */
    double light_x, light_z;   /* the light's centre */
    double light_half;         /* half its side */
    double light_height, cam_height, fov_y;
    int width, height;
    /* Where the file puts it: every position p written as offset + scale·p (in every
     * axis), by the description's mesh transform, or, with offset_in_file, in the
     * OBJ's own coordinates. G is the same at any offset and scale; 0 scale = 1. */
    double offset, scale;
    int offset_in_file;
    /* Two triangles 10^5 units away on either side, below the plane's horizon and
     * outside the view (they change no pixel): the scene's extent, and so its
     * largest coordinate, is then 10^4 times the plane's. */
    int far_geometry;
} test_plane;

/* Writes NAME.obj and NAME.json and loads them; NULL (a failed check) on error. */
struct scene;
struct scene *test_plane_load(const test_plane *p, const char *name);
/* Writes text as the test file `name` (a JSON scene) and loads it with a light
 * required; NULL (and a failed CHECK) when it does not load. */
struct scene *test_load_json(const char *name, const char *text);
/* Mean G over the sub×sub grid of centres in pixel (px, py), top row 0, as the
 * renderer's s×s samples (and a midpoint rule for a box-filtered pixel). */
double test_plane_pixel_G(const test_plane *p, int px, int py, int sub);
/* The same mean of the specular integral S (samp_polygon_phong: the plane's
 * Phong lobe over the light, seen from the camera): radiance ks·Le·S. */
double test_plane_pixel_S(const test_plane *p, int px, int py, int sub);

/* The GL side of a closed-form plane test: an EGL context, the plane loaded as
 * NAME, its ID pass at the plane's image size (ids.pixels: the worker's pixel
 * counts) and a renderer with ss×ss samples a pixel. test_plane_gl_open returns
 * 77 (skipped) without any GL, 1 when a step failed (a failed check), else 0. */
struct glctx;
struct rend_id;
struct rend_frame;
typedef struct test_plane_gl {
    struct glctx *ctx;
    struct scene *s;
    struct rend_id *ip;
    struct rend_frame *f;
    const uint32_t *pixels;
} test_plane_gl;
int test_plane_gl_open(const test_plane *p, const char *name, int ss, test_plane_gl *t);
void test_plane_gl_close(test_plane_gl *t);
/* CIE76 ΔE between two linear colours after the display's tone mapping. */
struct tm_desc;
double test_tone_delta_e(const struct tm_desc *tm, const float a[3], const float b[3]);
/* An image's error against the exact one, pixel by pixel (test_pixel_error_add
 * for each of `count` pixels): mean and largest tone-mapped ΔE, where the largest
 * is, the pixels above `jnd`, and relMSE as `lumesh compare` computes it
 * (linear, (a−b)²/(b²+0.01) over pixels and channels). Zero it to start. */
typedef struct test_pixel_error {
    double mean_de, max_de, relmse;
    int above, worst;
} test_pixel_error;
void test_pixel_error_add(test_pixel_error *e, const struct tm_desc *tm, const float got[3], const float exact[3],
                          int pixel, int count, double jnd);

/* Waits up to `seconds` for a snapshot that is finished (or failed); the last one
 * acquired otherwise (NULL if none). */
struct cache_worker;
struct cache_snapshot;
const struct cache_snapshot *test_wait_finished(struct cache_worker *w, double seconds);

/* Prints a summary and returns the process exit code. */
int test_finish(const char *name);
/* The exit status of a GL test that found no GL context (why: the reason, printed):
 * 77, skipped, or 1 where LUMESH_REQUIRE_GL says one must exist (tools/test.sh, CI:
 * llvmpipe is installed there, so a missing context is a broken install). */
int test_no_gl(const char *why);

#endif
