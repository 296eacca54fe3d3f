#define _POSIX_C_SOURCE 200809L /* nanosleep */
#include "tests/test_util.h"

#include <math.h>
#include <time.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_worker.h"
#include "sampling/analytic.h"
#include "src/base/tonemap.h"
#include "src/base/vecmath.h"
#include "src/gpu/gl_context.h"
#include "src/render/rend_frame.h"
#include "src/render/rend_id.h"
#include "src/scene/scene.h"

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

/* Icosphere of the given subdivision level, faces wound to face the centre. */
double test_write_icosphere(int level, double radius, const char *path)
{
    int cap_v = 12 * (1 << (2 * level)) * 4 + 64, cap_f = 20 * (1 << (2 * level));
    double (*v)[3] = malloc((size_t)cap_v * sizeof *v);
    int (*f)[3] = malloc((size_t)cap_f * sizeof *f), (*g)[3] = malloc((size_t)cap_f * sizeof *g);
    const double t = (1.0 + sqrt(5.0)) / 2.0;
    const double base[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    const int faces[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                              {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                              {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    int nv = 12, nf = 20;
    for (int i = 0; i < 12; ++i) {
        double l = sqrt(base[i][0] * base[i][0] + base[i][1] * base[i][1] + base[i][2] * base[i][2]);
        for (int k = 0; k < 3; ++k) v[i][k] = base[i][k] / l;
    }
    memcpy(f, faces, sizeof faces);
    for (int lv = 0; lv < level; ++lv) {
        int ng = 0;
        for (int i = 0; i < nf; ++i) {
            int m[3];
            for (int e = 0; e < 3; ++e) {
                int a = f[i][e], b = f[i][(e + 1) % 3];
                double p[3], l = 0;
                for (int k = 0; k < 3; ++k) {
                    p[k] = v[a][k] + v[b][k];
                    l += p[k] * p[k];
                }
                l = sqrt(l);
                /* a new vertex per face edge: both faces compute the same sum,
                 * so the loader's exact welding joins them */
                if (nv >= cap_v) {
                    cap_v *= 2;
                    v = realloc(v, (size_t)cap_v * sizeof *v);
                }
                for (int k = 0; k < 3; ++k) v[nv][k] = p[k] / l;
                int found = nv++;
                m[e] = found;
            }
            int tri[4][3] = {{f[i][0], m[0], m[2]}, {f[i][1], m[1], m[0]}, {f[i][2], m[2], m[1]}, {m[0], m[1], m[2]}};
            memcpy(g[ng], tri, sizeof tri);
            ng += 4;
        }
        nf = ng;
        int(*tmp)[3] = f;
        f = g;
        g = tmp;
    }
    FILE *out = fopen(path, "w");
    double dmin = 1.0;
    if (out) {
        for (int i = 0; i < nv; ++i) fprintf(out, "v %.17g %.17g %.17g\n", radius * v[i][0], radius * v[i][1], radius * v[i][2]);
        for (int i = 0; i < nf; ++i) {
            /* outward winding is (0,1,2): write (0,2,1) to face the centre */
            fprintf(out, "f %d %d %d\n", f[i][0] + 1, f[i][2] + 1, f[i][1] + 1);
            lm_dvec3 a = dv3(v[f[i][0]][0], v[f[i][0]][1], v[f[i][0]][2]);
            lm_dvec3 b = dv3(v[f[i][1]][0], v[f[i][1]][1], v[f[i][1]][2]);
            lm_dvec3 c = dv3(v[f[i][2]][0], v[f[i][2]][1], v[f[i][2]][2]);
            lm_dvec3 nrm = dv3_normalize(dv3_cross(dv3_sub(b, a), dv3_sub(c, a)));
            double d = fabs(dv3_dot(nrm, a));
            if (d < dmin) dmin = d;
        }
        fclose(out);
    }
    CHECK_MSG(out != NULL, "cannot write %s", path);
    free(v);
    free(f);
    free(g);
    return 1.0 / (dmin * dmin) - 1.0; /* relative bias bound (R/d)² − 1 */
}

struct scene *test_plane_load(const test_plane *p, const char *name)
{
    char file[256], obj[1024], text[4096], tf[512] = "";
    const double S = p->scale > 0.0 ? p->scale : 1.0, T = p->offset;
    const double in_file = p->offset_in_file ? 1.0 : 0.0;
    snprintf(file, sizeof file, "%s.obj", name);
    {
        char vs[1024];
        const double h = p->plane_half > 0.0 ? p->plane_half : 4.0;
        const double a = in_file ? T - h * S : -h, b = in_file ? T + h * S : h, y = in_file ? T : 0.0;
        /* counter-clockwise seen from +y */
        int n = snprintf(vs, sizeof vs,
                         "v %.17g %.17g %.17g\nv %.17g %.17g %.17g\nv %.17g %.17g %.17g\nv %.17g %.17g %.17g\n"
                         "f 1 4 3\nf 1 3 2\n",
                         a, y, a, b, y, a, b, y, b, a, y, b);
        if (p->far_geometry && n > 0 && (size_t)n < sizeof vs) /* 10^5 away, below the horizon */
            snprintf(vs + n, sizeof vs - (size_t)n,
                     "v -1e5 -100 0\nv -1e5 -100 1\nv -1e5 -99 0\nv 1e5 -100 0\nv 1e5 -99 0\n"
                     "v 1e5 -100 1\nf 5 6 7\nf 8 9 10\n");
        test_write_file(file, vs, obj, sizeof obj);
    }
    if (!in_file && (S != 1.0 || T != 0.0))
        snprintf(tf, sizeof tf, ", \"transform\": [%.17g,0,0,%.17g, 0,%.17g,0,%.17g, 0,0,%.17g,%.17g, 0,0,0,1]", S, T,
                 S, T, S, T);
    /* edge1 × edge2 = (1,0,0) × (0,0,1) = (0,-1,0): the light faces the plane. */
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"%s\", \"material\": \"paint\"%s}],"
             " \"materials\": {\"paint\": {\"kd\": [%g, %g, %g], \"ks\": [%g, %g, %g], \"n\": %.17g}},"
             " \"lights\": [{\"type\": \"quad\", \"corner\": [%.17g, %.17g, %.17g], \"edge1\": [%.17g, 0, 0],"
             " \"edge2\": [0, 0, %.17g], \"radiance\": [%g, %g, %g]}],"
             " \"cameras\": [{\"position\": [%.17g, %.17g, %.17g], \"target\": [%.17g, %.17g, %.17g], \"up\": [0, 0, -1],"
             " \"fov_y\": %g, \"width\": %d, \"height\": %d}]}",
             file, tf, p->kd[0], p->kd[1], p->kd[2], p->ks[0], p->ks[1], p->ks[2], p->n > 0.0 ? p->n : 1.0, T + S * (p->light_x - p->light_half), T + S * p->light_height,
             T + S * (p->light_z - p->light_half), S * 2 * p->light_half, S * 2 * p->light_half, p->le[0], p->le[1],
             p->le[2], T, T + S * p->cam_height, T, T, T, T, p->fov_y, p->width, p->height);
    snprintf(file, sizeof file, "%s.json", name);
    return test_load_json(file, text);
}

struct scene *test_load_json(const char *name, const char *text)
{
    char json[1024];
    test_write_file(name, text, json, sizeof json);
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&(scene_load_desc){.path = json, .require_light = 1}, &s, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return s;
}

/* Mean of the light's G (specular 0) or S (1) over pixel (px, py)'s sub×sub grid. */
static double plane_pixel_mean(const test_plane *p, int px, int py, int sub, int specular)
{
    const double x0 = p->light_x - p->light_half, x1 = p->light_x + p->light_half;
    const double z0 = p->light_z - p->light_half, z1 = p->light_z + p->light_half, y = p->light_height;
    const double light[4][3] = {{x0, y, z0}, {x1, y, z0}, {x1, y, z1}, {x0, y, z1}};
    const double up[3] = {0.0, 1.0, 0.0};
    const double ty = tan(0.5 * p->fov_y * M_PI / 180.0), tx = ty * (double)p->width / (double)p->height;
    double sum = 0.0;
    for (int j = 0; j < sub; ++j)
        for (int i = 0; i < sub; ++i) {
            /* Screen position in [-1, 1]², then the plane point the pinhole sees there. */
            double sx = 2.0 * (px + (i + 0.5) / sub) / p->width - 1.0;
            double sy = 1.0 - 2.0 * (py + (j + 0.5) / sub) / p->height;
            double x[3] = {p->cam_height * sx * tx, 0.0, -p->cam_height * sy * ty};
            const double wo[3] = {-x[0], p->cam_height - x[1], -x[2]}; /* towards the camera */
            sum += specular ? samp_polygon_phong(light, 4, x, up, wo, p->n) : samp_polygon_G(light, 4, x, up);
        }
    return sum / (sub * sub);
}

double test_plane_pixel_G(const test_plane *p, int px, int py, int sub) { return plane_pixel_mean(p, px, py, sub, 0); }

double test_plane_pixel_S(const test_plane *p, int px, int py, int sub) { return plane_pixel_mean(p, px, py, sub, 1); }

const cache_snapshot *test_wait_finished(cache_worker *w, double seconds)
{
    const cache_snapshot *s = NULL;
    double t0 = lm_now_seconds();
    while (w && lm_now_seconds() - t0 < seconds) {
        s = cache_worker_acquire(w);
        if (s && (s->finished || s->failed)) break;
        struct timespec t = {0, 2000000};
        nanosleep(&t, NULL);
    }
    return s;
}

int test_no_gl(const char *why)
{
    printf("no GL context: %s\n", why);
    return getenv("LUMESH_REQUIRE_GL") ? 1 : 77;
}

int test_plane_gl_open(const test_plane *p, const char *name, int ss, test_plane_gl *t)
{
    lm_error err;
    memset(t, 0, sizeof *t);
    if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &t->ctx, &err) != LM_OK) return test_no_gl(err.msg);
    const GladGLContext *gl = glctx_gl(t->ctx);
    const int w = p->width, h = p->height;
    rend_id_result ids; /* its arrays are t->ip's */
    t->s = test_plane_load(p, name);
    int ok = t->s != NULL;
    if (ok) CHECK(ok = rend_id_create(gl, &(rend_id_desc){.scene = t->s, .width = w, .height = h}, &t->ip, &err) == LM_OK);
    if (ok) CHECK(ok = rend_id_render(t->ip, &t->s->cameras[0], &ids, &err) == LM_OK);
    if (ok)
        CHECK(ok = rend_frame_create(gl, &(rend_frame_desc){.scene = t->s, .width = w, .height = h, .supersample = ss},
                                     &t->f, &err) == LM_OK);
    t->pixels = ok ? ids.pixels : NULL;
    return ok ? 0 : 1;
}

void test_plane_gl_close(test_plane_gl *t)
{
    rend_frame_destroy(t->f);
    rend_id_destroy(t->ip);
    scene_destroy(t->s);
    glctx_destroy(t->ctx);
    memset(t, 0, sizeof *t);
}

double test_tone_delta_e(const tm_desc *tm, const float a[3], const float b[3])
{
    float da[3], db[3], la[3], lb[3];
    tm_to_display(tm, a, da);
    tm_to_display(tm, b, db);
    tm_display_to_lab(da, la);
    tm_display_to_lab(db, lb);
    return tm_delta_e(la, lb);
}

void test_pixel_error_add(test_pixel_error *e, const tm_desc *tm, const float got[3], const float exact[3], int pixel,
                          int count, double jnd)
{
    double de = test_tone_delta_e(tm, got, exact);
    e->mean_de += de / count;
    if (de > e->max_de) e->max_de = de, e->worst = pixel;
    e->above += de > jnd;
    for (int k = 0; k < 3; ++k)
        e->relmse += (got[k] - exact[k]) * (got[k] - exact[k]) / (exact[k] * exact[k] + 0.01) / (3.0 * count);
}
