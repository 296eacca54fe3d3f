/* analytic_irradiance_test.c — samp_polygon_G (Lambert's edge formula clipped to
 * the horizon) against adaptive quadrature of the defining integral
 *     G = ∫_P max(0,cosθ_x)·max(0,cosθ_y)/r² dA
 * on random configurations, against closed forms (parallel square and L-shape,
 * far field), and on the degenerate inputs the header promises to survive.
 *
 * The reference shares nothing with the implementation: it triangulates each shape
 * by hand, clips every triangle on its own against the horizon (only to keep the
 * integrand smooth; the clamped integrand is integrated), and refines each piece
 * with Radon's 7-point degree-5 rule until a triangle and its four children agree.
 */
#include "analytic.h"
#include "test_util.h"
#include "util.h"
#include "vecmath.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

/* ---- small vector helpers ------------------------------------------------ */

static void set3(double o[3], double a, double b, double c)
{
    o[0] = a;
    o[1] = b;
    o[2] = c;
}
static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void cross(const double a[3], const double b[3], double o[3])
{
    double r[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                   a[0] * b[1] - a[1] * b[0]};
    memcpy(o, r, sizeof r);
}
static void normalize(double a[3])
{
    double l = sqrt(dot(a, a));
    for (int k = 0; k < 3; k++) a[k] /= l;
}
/* o = a + s·b */
static void madd(const double a[3], double s, const double b[3], double o[3])
{
    for (int k = 0; k < 3; k++) o[k] = a[k] + s * b[k];
}

static double rel_err(double got, double want)
{
    if (want == 0.0) return got == 0.0 ? 0.0 : INFINITY;
    return fabs(got - want) / fabs(want);
}

/* ---- deterministic random numbers (splitmix64) ---------------------------- */

typedef struct rng { uint64_t s; } rng;
static double rnd(rng *r)
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}
static double rnd_in(rng *r, double a, double b) { return a + (b - a) * rnd(r); }
static double rnd_log(rng *r, double a, double b) { return exp(rnd_in(r, log(a), log(b))); }
static void rnd_dir(rng *r, double o[3])
{
    double z = rnd_in(r, -1.0, 1.0), phi = rnd_in(r, 0.0, 2.0 * M_PI), s = sqrt(1.0 - z * z);
    set3(o, s * cos(phi), s * sin(phi), z);
}
/* A unit vector u with u·n in [lo, hi] (n unit). */
static void rnd_dir_band(rng *r, const double n[3], double lo, double hi, double o[3])
{
    double t1[3], t2[3], a[3];
    set3(a, fabs(n[0]) < 0.9 ? 1.0 : 0.0, fabs(n[0]) < 0.9 ? 0.0 : 1.0, 0.0);
    cross(a, n, t1);
    normalize(t1);
    cross(n, t1, t2);
    double z = rnd_in(r, lo, hi), phi = rnd_in(r, 0.0, 2.0 * M_PI), s = sqrt(1.0 - z * z);
    for (int k = 0; k < 3; k++) o[k] = z * n[k] + s * (cos(phi) * t1[k] + sin(phi) * t2[k]);
}

/* ---- shapes: 2D counter-clockwise outlines with a hand triangulation ------ */

enum { SHAPE_TRI, SHAPE_QUAD, SHAPE_L, SHAPE_COUNT };
static const char *const shape_name[SHAPE_COUNT] = {"tri", "quad", "L-hex"};

#define MAXV 8
#define MAXT 6
typedef struct light {
    int n, ntri;
    double v[MAXV][3];   /* 3D, counter-clockwise about nl */
    int tri[MAXT][3];
    double nl[3];        /* unit emitting normal */
    double centroid[3], area;
} light;

typedef struct shape2d {
    int n, ntri;
    double p[MAXV][2];
    int tri[MAXT][3];
} shape2d;

static double cross2(const double a[2], const double b[2], const double c[2])
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

static void random_shape(rng *r, int kind, shape2d *s)
{
    memset(s, 0, sizeof *s);
    if (kind == SHAPE_TRI) {
        do {
            for (int i = 0; i < 3; i++) {
                double a = rnd_in(r, 0.0, 2.0 * M_PI), rad = rnd_in(r, 0.3, 1.0);
                s->p[i][0] = rad * cos(a);
                s->p[i][1] = rad * sin(a);
            }
        } while (fabs(cross2(s->p[0], s->p[1], s->p[2])) < 0.3);
        if (cross2(s->p[0], s->p[1], s->p[2]) < 0.0) {
            double t0 = s->p[1][0], t1 = s->p[1][1];
            s->p[1][0] = s->p[2][0];
            s->p[1][1] = s->p[2][1];
            s->p[2][0] = t0;
            s->p[2][1] = t1;
        }
        s->n = 3;
        s->ntri = 1;
        s->tri[0][0] = 0, s->tri[0][1] = 1, s->tri[0][2] = 2;
    } else if (kind == SHAPE_QUAD) {
        /* Convex: four points on an ellipse at increasing angles, gaps ≥ 0.4. */
        double ang[4], ex = rnd_in(r, 0.5, 1.0), base = rnd_in(r, 0.0, 2.0 * M_PI);
        for (;;) {
            double g[4], sum = 0.0;
            for (int i = 0; i < 4; i++) sum += (g[i] = rnd_in(r, 0.4, 1.0));
            double acc = base;
            for (int i = 0; i < 4; i++) {
                ang[i] = acc;
                acc += g[i] * 2.0 * M_PI / sum;
            }
            int ok = 1;
            for (int i = 0; i < 4; i++) ok &= g[i] * 2.0 * M_PI / sum < 0.95 * M_PI;
            if (ok) break;
        }
        for (int i = 0; i < 4; i++) {
            s->p[i][0] = cos(ang[i]);
            s->p[i][1] = ex * sin(ang[i]);
        }
        s->n = 4;
        s->ntri = 2;
        s->tri[0][0] = 0, s->tri[0][1] = 1, s->tri[0][2] = 2;
        s->tri[1][0] = 0, s->tri[1][1] = 2, s->tri[1][2] = 3;
    } else {
        /* L: [0,2]x[0,1] ∪ [0,1]x[1,2], random arm lengths, centred near 0. */
        double w = rnd_in(r, 1.5, 2.5), hgt = rnd_in(r, 1.5, 2.5), t = rnd_in(r, 0.5, 1.0);
        const double pts[6][2] = {{0, 0}, {w, 0}, {w, t}, {t, t}, {t, hgt}, {0, hgt}};
        const int tris[4][3] = {{0, 1, 2}, {0, 2, 3}, {0, 3, 5}, {3, 4, 5}};
        for (int i = 0; i < 6; i++) {
            s->p[i][0] = (pts[i][0] - 0.7) / 1.5;
            s->p[i][1] = (pts[i][1] - 0.7) / 1.5;
        }
        memcpy(s->tri, tris, sizeof tris);
        s->n = 6;
        s->ntri = 4;
    }
}

/* Places shape s, scaled by size, centred at c, emitting along nl (unit), turned
 * by a random angle in its plane. */
static void place_light(rng *r, const shape2d *s, double size, const double c[3],
                        const double nl[3], light *L)
{
    double t1[3], t2[3], a[3];
    set3(a, fabs(nl[0]) < 0.9 ? 1.0 : 0.0, fabs(nl[0]) < 0.9 ? 0.0 : 1.0, 0.0);
    cross(a, nl, t1);
    normalize(t1);
    cross(nl, t1, t2); /* t1 × t2 = nl: counter-clockwise in (t1,t2) is right-handed about nl */
    double phi = rnd_in(r, 0.0, 2.0 * M_PI), cs = cos(phi), sn = sin(phi);
    memset(L, 0, sizeof *L);
    L->n = s->n;
    L->ntri = s->ntri;
    memcpy(L->tri, s->tri, sizeof s->tri);
    memcpy(L->nl, nl, sizeof L->nl);
    double cen2[2] = {0.0, 0.0}, area = 0.0;
    for (int t = 0; t < s->ntri; t++) {
        const double *p0 = s->p[s->tri[t][0]], *p1 = s->p[s->tri[t][1]], *p2 = s->p[s->tri[t][2]];
        double at = 0.5 * cross2(p0, p1, p2);
        area += at;
        for (int k = 0; k < 2; k++) cen2[k] += at * (p0[k] + p1[k] + p2[k]) / 3.0;
    }
    L->area = area * size * size;
    for (int i = 0; i <= s->n; i++) {
        double px, py;
        if (i < s->n) {
            px = s->p[i][0], py = s->p[i][1];
        } else {
            px = cen2[0] / area, py = cen2[1] / area;
        }
        double u = size * (cs * px - sn * py), w = size * (sn * px + cs * py);
        double *out = i < s->n ? L->v[i] : L->centroid;
        for (int k = 0; k < 3; k++) out[k] = c[k] + u * t1[k] + w * t2[k];
    }
}

/* ---- the reference: adaptive quadrature of the defining integral ---------- */

typedef struct ref_ctx {
    double x[3], nx[3], nl[3];
    long evals;
} ref_ctx;

static double integrand(ref_ctx *c, const double y[3])
{
    double r[3] = {y[0] - c->x[0], y[1] - c->x[1], y[2] - c->x[2]};
    double r2 = dot(r, r);
    double cx = fmax(0.0, dot(r, c->nx)), cy = fmax(0.0, -dot(r, c->nl));
    c->evals++;
    return cx * cy / (r2 * r2); /* (cx/r)(cy/r)/r² */
}

/* Radon's 7-point rule, exact for degree 5. */
static double radon7(ref_ctx *c, const double a[3], const double b[3], const double d[3])
{
    static const double bary[7][3] = {
        {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0},
        {0.1012865073234563388, 0.1012865073234563388, 0.7974269853530873224},
        {0.1012865073234563388, 0.7974269853530873224, 0.1012865073234563388},
        {0.7974269853530873224, 0.1012865073234563388, 0.1012865073234563388},
        {0.47014206410511508977, 0.47014206410511508977, 0.059715871789769820459},
        {0.47014206410511508977, 0.059715871789769820459, 0.47014206410511508977},
        {0.059715871789769820459, 0.47014206410511508977, 0.47014206410511508977}};
    static const double w[7] = {0.225,
                                0.1259391805448271526,
                                0.1259391805448271526,
                                0.1259391805448271526,
                                0.13239415278850618074,
                                0.13239415278850618074,
                                0.13239415278850618074};
    double e1[3], e2[3], n[3];
    for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = d[k] - a[k];
    cross(e1, e2, n);
    double area = 0.5 * sqrt(dot(n, n)), sum = 0.0;
    for (int i = 0; i < 7; i++) {
        double y[3];
        for (int k = 0; k < 3; k++) y[k] = bary[i][0] * a[k] + bary[i][1] * b[k] + bary[i][2] * d[k];
        sum += w[i] * integrand(c, y);
    }
    return area * sum;
}

static double adapt(ref_ctx *c, const double a[3], const double b[3], const double d[3],
                    double whole, double tol, int depth)
{
    double ab[3], bd[3], da[3];
    for (int k = 0; k < 3; k++) {
        ab[k] = 0.5 * (a[k] + b[k]);
        bd[k] = 0.5 * (b[k] + d[k]);
        da[k] = 0.5 * (d[k] + a[k]);
    }
    const double *ch[4][3] = {{a, ab, da}, {ab, b, bd}, {da, bd, d}, {ab, bd, da}};
    double q[4], sum = 0.0;
    for (int i = 0; i < 4; i++) sum += (q[i] = radon7(c, ch[i][0], ch[i][1], ch[i][2]));
    if (fabs(sum - whole) <= tol || depth >= 30) return sum;
    double out = 0.0;
    for (int i = 0; i < 4; i++) out += adapt(c, ch[i][0], ch[i][1], ch[i][2], q[i], 0.25 * tol, depth + 1);
    return out;
}

/* Triangles of L clipped to the horizon of (x, nx): up to 2 per triangle. */
static int clipped_pieces(const light *L, const double x[3], const double nx[3],
                          double out[][3][3])
{
    int m = 0;
    for (int t = 0; t < L->ntri; t++) {
        double poly[4][3], d[3];
        int np = 0;
        for (int i = 0; i < 3; i++) {
            const double *v = L->v[L->tri[t][i]];
            double r[3] = {v[0] - x[0], v[1] - x[1], v[2] - x[2]};
            d[i] = dot(r, nx);
        }
        for (int i = 0; i < 3; i++) {
            int j = (i + 1) % 3;
            const double *a = L->v[L->tri[t][i]], *b = L->v[L->tri[t][j]];
            if (d[i] >= 0.0) memcpy(poly[np++], a, sizeof poly[0]);
            if ((d[i] > 0.0 && d[j] < 0.0) || (d[i] < 0.0 && d[j] > 0.0)) {
                double s = d[i] / (d[i] - d[j]);
                for (int k = 0; k < 3; k++) poly[np][k] = a[k] + s * (b[k] - a[k]);
                np++;
            }
        }
        for (int i = 1; i + 1 < np; i++) {
            memcpy(out[m][0], poly[0], sizeof poly[0]);
            memcpy(out[m][1], poly[i], sizeof poly[0]);
            memcpy(out[m][2], poly[i + 1], sizeof poly[0]);
            m++;
        }
    }
    return m;
}

static long ref_evals_total;

static double reference_G(const light *L, const double x[3], const double nx[3], double rel_tol)
{
    ref_ctx c;
    memset(&c, 0, sizeof c);
    memcpy(c.x, x, sizeof c.x);
    memcpy(c.nx, nx, sizeof c.nx);
    memcpy(c.nl, L->nl, sizeof c.nl);
    double pieces[2 * MAXT][3][3], coarse[2 * MAXT], est = 0.0;
    int m = clipped_pieces(L, x, nx, pieces);
    for (int i = 0; i < m; i++) est += (coarse[i] = radon7(&c, pieces[i][0], pieces[i][1], pieces[i][2]));
    double total = 0.0;
    /* Two passes: the first finds the value, the second refines to rel_tol of it
     * (the coarse estimate can be far off when x is close to the light). */
    for (int pass = 0; pass < 2; pass++) {
        double tol = rel_tol * fmax(fabs(pass ? total : est), 1e-300);
        total = 0.0;
        for (int i = 0; i < m; i++)
            total += adapt(&c, pieces[i][0], pieces[i][1], pieces[i][2], coarse[i], tol / m, 0);
    }
    ref_evals_total += c.evals;
    return total;
}

static double light_G(const light *L, const double x[3], const double nx[3])
{
    return samp_polygon_G((const double (*)[3])L->v, L->n, x, nx);
}

/* ---- random configurations ----------------------------------------------- */

enum { FAM_ABOVE, FAM_STRADDLE, FAM_GRAZING, FAM_NEAR, FAM_FAR, FAM_COUNT };
static const char *const fam_name[FAM_COUNT] = {
    "above horizon, facing", "straddling the horizon", "grazing (near horizon plane)",
    "near (dist 0.05-0.5 size)", "far (dist 3-1e4 size)"};

/* Counts vertices strictly above / below x's horizon. */
static void horizon_counts(const light *L, const double x[3], const double nx[3], int *above,
                           int *below)
{
    *above = *below = 0;
    for (int i = 0; i < L->n; i++) {
        double r[3] = {L->v[i][0] - x[0], L->v[i][1] - x[1], L->v[i][2] - x[2]};
        double d = dot(r, nx);
        *above += d > 0.0;
        *below += d < 0.0;
    }
}

/* Builds a configuration of family fam; returns 0 to ask for another draw. */
static int make_config(rng *r, int fam, int shape, light *L, double x[3], double nx[3])
{
    shape2d s;
    random_shape(r, shape, &s);
    for (int k = 0; k < 3; k++) x[k] = rnd_in(r, -2.0, 2.0);
    rnd_dir(r, nx);
    double size = rnd_log(r, 0.05, 20.0), dir[3], c[3], nl[3], dist = 0.0;
    switch (fam) {
    case FAM_ABOVE: rnd_dir_band(r, nx, 0.3, 1.0, dir); dist = size * rnd_in(r, 1.5, 6.0); break;
    case FAM_STRADDLE: rnd_dir_band(r, nx, -0.3, 0.3, dir); dist = size * rnd_in(r, 0.6, 3.0); break;
    case FAM_NEAR: rnd_dir_band(r, nx, -0.3, 1.0, dir); dist = size * rnd_in(r, 0.05, 0.5); break;
    case FAM_FAR: rnd_dir_band(r, nx, -0.1, 1.0, dir); dist = size * rnd_log(r, 3.0, 1e4); break;
    case FAM_GRAZING: break;
    }
    if (fam == FAM_GRAZING) {
        /* Light plane within ~1° of x's horizon plane, at height 1e-3..1e-1 size,
         * beside x; it may dip under the horizon. */
        double lat[3];
        rnd_dir_band(r, nx, 0.0, 0.0, lat);
        double eps = size * rnd_log(r, 1e-3, 0.1), off = size * rnd_in(r, 1.2, 4.0);
        for (int k = 0; k < 3; k++) c[k] = x[k] + off * lat[k] + eps * nx[k];
        double m[3] = {-nx[0], -nx[1], -nx[2]};
        rnd_dir_band(r, m, cos(0.02), 1.0, nl);
    } else {
        madd(x, dist, dir, c);
        double back[3] = {-dir[0], -dir[1], -dir[2]};
        rnd_dir_band(r, back, 0.15, 1.0, nl); /* tilted up to ~81°, facing x */
    }
    place_light(r, &s, size, c, nl, L);
    /* Keep only configurations where x is in front of the light. */
    double xc[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
    if (!(dot(xc, nl) > 1e-3 * size)) return 0;
    int above, below;
    horizon_counts(L, x, nx, &above, &below);
    if (above == 0) return 0;
    if (fam == FAM_ABOVE && below > 0) return 0;
    if (fam == FAM_STRADDLE && below == 0) return 0;
    return 1;
}

static void test_random_families(void)
{
    enum { PER_CELL = 40 };
    rng r = {0x5EED1234ABCDull};
    double maxerr[FAM_COUNT][SHAPE_COUNT] = {{0}};
    double worst = 0.0;
    ref_evals_total = 0;
    double t0 = lm_now_seconds();
    for (int fam = 0; fam < FAM_COUNT; fam++) {
        for (int shape = 0; shape < SHAPE_COUNT; shape++) {
            for (int i = 0; i < PER_CELL; i++) {
                light L;
                double x[3], nx[3];
                int tries = 0;
                while (!make_config(&r, fam, shape, &L, x, nx)) tries++;
                double ref = reference_G(&L, x, nx, 1e-11);
                double g = light_G(&L, x, nx);
                double e = rel_err(g, ref);
                CHECK_MSG(isfinite(g) && e <= 1e-6, "%s/%s #%d: G %.17g, quadrature %.17g (rel %.3g)",
                          fam_name[fam], shape_name[shape], i, g, ref, e);
                if (e > maxerr[fam][shape]) maxerr[fam][shape] = e;
                if (e > worst) worst = e;
                (void)tries;
            }
        }
    }
    printf("max relative error of samp_polygon_G vs adaptive quadrature (%d configs per cell, "
           "%ld integrand evaluations, %.2f s)\n",
           PER_CELL, ref_evals_total, lm_now_seconds() - t0);
    printf("  %-30s %10s %10s %10s\n", "family", shape_name[0], shape_name[1], shape_name[2]);
    for (int fam = 0; fam < FAM_COUNT; fam++)
        printf("  %-30s %10.2e %10.2e %10.2e\n", fam_name[fam], maxerr[fam][0], maxerr[fam][1],
               maxerr[fam][2]);
    (void)worst;
}

int main(void)
{
    test_random_families();
    return test_finish("analytic_irradiance_test");
}
