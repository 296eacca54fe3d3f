/* analytic_irradiance_test.c — samp_polygon_G (Lambert's edge formula clipped to
 * the horizon) against adaptive quadrature of the defining integral
 *     G = ∫_P max(0,cosθ_x)·max(0,cosθ_y)/r² dA
 * on random configurations, against closed forms (parallel square and L-shape,
 * far field), and on the degenerate inputs the header promises to survive.
 *
 * The reference shares no code with the implementation: it triangulates each
 * shape by hand, clips every triangle on its own against the horizon (only to
 * keep the integrand smooth; the clamped integrand is what is integrated), and
 * refines globally with Radon's 7-point degree-5 rule, splitting the triangle
 * whose four children disagree most with it, until the summed disagreement is
 * below the tolerance (1e-10 relative for the random families). Its values for
 * the random families are therefore good to ~1e-11; the closed forms and the
 * 1e-6 light show the implementation's own accuracy.
 *
 * Prints a table of the largest error per case family.
 */
#include "sampling/analytic.h"
#include "src/base/util.h"
#include "src/base/vecmath.h"
#include "tests/test_util.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
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

/* Global adaptive refinement: a max-heap of triangles by error estimate
 * |Q(children) − Q(triangle)|; the worst is split into its four children until
 * the summed estimate is below the tolerance. Each entry keeps the children's sum
 * (its value) and its children's own rule values are recomputed on split. */
typedef struct cell {
    double v[3][3];
    double q;    /* single-rule value */
    double s;    /* sum over the four children: the cell's value */
    double err;  /* |s − q| */
} cell;

typedef struct cell_heap {
    cell *a;
    int n, cap;
} cell_heap;

static void children_of(const cell *c, double ch[4][3][3])
{
    double m[3][3];
    for (int k = 0; k < 3; k++) {
        m[0][k] = 0.5 * (c->v[0][k] + c->v[1][k]);
        m[1][k] = 0.5 * (c->v[1][k] + c->v[2][k]);
        m[2][k] = 0.5 * (c->v[2][k] + c->v[0][k]);
    }
    const double *t[4][3] = {{c->v[0], m[0], m[2]}, {m[0], c->v[1], m[1]},
                             {m[2], m[1], c->v[2]}, {m[0], m[1], m[2]}};
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 3; j++) memcpy(ch[i][j], t[i][j], sizeof ch[i][j]);
}

static void make_cell(ref_ctx *rc, const double v[3][3], double q, cell *out)
{
    memcpy(out->v, v, sizeof out->v);
    out->q = q;
    double ch[4][3][3];
    children_of(out, ch);
    out->s = 0.0;
    for (int i = 0; i < 4; i++) out->s += radon7(rc, ch[i][0], ch[i][1], ch[i][2]);
    out->err = fabs(out->s - out->q);
}

static void heap_push(cell_heap *h, const cell *c)
{
    if (h->n == h->cap) {
        size_t c = lm_grow_capacity((size_t)h->cap, (size_t)h->n + 1, 256, INT_MAX);
        int grown = c && lm_realloc_array(&h->a, (size_t)h->cap, c, sizeof *h->a);
        CHECK(grown);
        if (!grown) exit(1);
        h->cap = (int)c;
    }
    int i = h->n++;
    h->a[i] = *c;
    while (i > 0 && h->a[(i - 1) / 2].err < h->a[i].err) {
        cell t = h->a[i];
        h->a[i] = h->a[(i - 1) / 2];
        h->a[(i - 1) / 2] = t;
        i = (i - 1) / 2;
    }
}

static cell heap_pop(cell_heap *h)
{
    cell top = h->a[0];
    h->a[0] = h->a[--h->n];
    int i = 0;
    for (;;) {
        int l = 2 * i + 1, r = l + 1, m = i;
        if (l < h->n && h->a[l].err > h->a[m].err) m = l;
        if (r < h->n && h->a[r].err > h->a[m].err) m = r;
        if (m == i) break;
        cell t = h->a[i];
        h->a[i] = h->a[m];
        h->a[m] = t;
        i = m;
    }
    return top;
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

/* ∫ over L of the clamped integrand seen from (x, nx), to a relative error
 * estimate ≤ rel_tol (the estimate is conservative: it bounds the error of the
 * coarser of two levels, and the finer one is returned). */
static double reference_G(const light *L, const double x[3], const double nx[3], double rel_tol)
{
    /* Work with the light at the origin: cell areas and midpoints of a small
     * light far from the origin would lose digits to its offset. */
    light loc = *L;
    double xl[3];
    for (int k = 0; k < 3; k++) xl[k] = x[k] - L->v[0][k];
    for (int i = 0; i < L->n; i++)
        for (int k = 0; k < 3; k++) loc.v[i][k] = L->v[i][k] - L->v[0][k];
    ref_ctx c;
    memset(&c, 0, sizeof c);
    memcpy(c.x, xl, sizeof c.x);
    memcpy(c.nx, nx, sizeof c.nx);
    memcpy(c.nl, L->nl, sizeof c.nl);
    double pieces[2 * MAXT][3][3];
    int m = clipped_pieces(&loc, xl, nx, pieces);
    cell_heap h = {0};
    for (int i = 0; i < m; i++) {
        cell cl;
        make_cell(&c, (const double (*)[3])pieces[i], radon7(&c, pieces[i][0], pieces[i][1], pieces[i][2]), &cl);
        heap_push(&h, &cl);
    }
    /* Running sums; re-added from scratch now and then against drift. */
    double sum = 0.0, err = 0.0;
    int converged = h.n == 0;
    for (int iter = 0; h.n > 0 && iter < 200000; iter++) {
        if (iter % 1024 == 0) {
            sum = err = 0.0;
            for (int i = 0; i < h.n; i++) sum += h.a[i].s, err += h.a[i].err;
        }
        if (err <= rel_tol * fabs(sum)) {
            converged = 1;
            break;
        }
        cell worst = heap_pop(&h);
        sum -= worst.s;
        err -= worst.err;
        double ch[4][3][3];
        children_of(&worst, ch);
        for (int i = 0; i < 4; i++) {
            cell cl;
            make_cell(&c, (const double (*)[3])ch[i], radon7(&c, ch[i][0], ch[i][1], ch[i][2]), &cl);
            heap_push(&h, &cl);
            sum += cl.s;
            err += cl.err;
        }
    }
    double total = 0.0;
    for (int i = 0; i < h.n; i++) total += h.a[i].s;
    CHECK_MSG(converged, "reference quadrature did not reach %g (at %g)", rel_tol, total);
    free(h.a);
    ref_evals_total += c.evals;
    return total;
}

static double light_G(const light *L, const double x[3], const double nx[3])
{
    return samp_polygon_G((const double (*)[3])L->v, L->n, x, nx);
}

/* A light from explicit vertices: Newell normal; fan triangulation unless a
 * triangulation is given. */
static void light_from(light *L, const double (*v)[3], int n, const int (*tri)[3], int ntri)
{
    memset(L, 0, sizeof *L);
    L->n = n;
    memcpy(L->v, v, (size_t)n * sizeof L->v[0]);
    for (int i = 0; i < n; i++) {
        double c[3];
        cross(v[i], v[(i + 1) % n], c);
        for (int k = 0; k < 3; k++) L->nl[k] += c[k];
    }
    L->area = 0.5 * sqrt(dot(L->nl, L->nl));
    normalize(L->nl);
    if (tri) {
        L->ntri = ntri;
        memcpy(L->tri, tri, (size_t)ntri * sizeof tri[0]);
    } else {
        L->ntri = n - 2;
        for (int i = 0; i < n - 2; i++) L->tri[i][0] = 0, L->tri[i][1] = i + 1, L->tri[i][2] = i + 2;
    }
}

/* ---- the table ------------------------------------------------------------ */

typedef struct table_row {
    const char *name;
    int count;
    double maxerr;
    const char *kind; /* "rel" or "abs" */
} table_row;

enum { ROWS_MAX = 24 };
typedef struct table {
    table_row row[ROWS_MAX];
    int n;
} table;

static void table_add(table *t, const char *name, const char *kind, double err)
{
    int i = 0;
    while (i < t->n && strcmp(t->row[i].name, name) != 0) i++;
    if (i == t->n) {
        if (t->n == ROWS_MAX) return;
        t->row[i].name = name;
        t->row[i].kind = kind;
        t->n++;
    }
    t->row[i].count++;
    if (!(err <= t->row[i].maxerr)) t->row[i].maxerr = err;
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

/* Builds a configuration of family fam; returns 0 to ask for another draw. The
 * light's centre is within 1 of the origin, so its vertices carry no more
 * rounding than its size allows, whatever the distance to x. */
static int make_config(rng *r, int fam, int shape, light *L, double x[3], double nx[3])
{
    shape2d s;
    random_shape(r, shape, &s);
    double c[3], nl[3], dir[3], size = rnd_log(r, 0.05, 20.0), dist = 0.0;
    for (int k = 0; k < 3; k++) c[k] = rnd_in(r, -1.0, 1.0);
    rnd_dir(r, nx);
    switch (fam) {
    case FAM_ABOVE: rnd_dir_band(r, nx, 0.3, 1.0, dir); dist = size * rnd_in(r, 1.5, 6.0); break;
    case FAM_STRADDLE: rnd_dir_band(r, nx, -0.3, 0.3, dir); dist = size * rnd_in(r, 0.6, 3.0); break;
    case FAM_NEAR: rnd_dir_band(r, nx, -0.3, 1.0, dir); dist = size * rnd_in(r, 0.05, 0.5); break;
    case FAM_FAR: rnd_dir_band(r, nx, -0.1, 1.0, dir); dist = size * rnd_log(r, 3.0, 1e4); break;
    default: break;
    }
    if (fam == FAM_GRAZING) {
        /* Light plane within ~1° of x's horizon plane, 1e-3..1e-1 size above it,
         * beside x; it may dip under the horizon. */
        double lat[3], m[3] = {-nx[0], -nx[1], -nx[2]};
        rnd_dir_band(r, nx, 0.0, 0.0, lat);
        double eps = size * rnd_log(r, 1e-3, 0.1), off = size * rnd_in(r, 1.2, 4.0);
        for (int k = 0; k < 3; k++) x[k] = c[k] - off * lat[k] - eps * nx[k];
        rnd_dir_band(r, m, cos(0.02), 1.0, nl);
    } else {
        madd(c, -dist, dir, x);
        double back[3] = {-dir[0], -dir[1], -dir[2]};
        rnd_dir_band(r, back, 0.15, 1.0, nl); /* tilted up to ~81°, facing x */
    }
    place_light(r, &s, size, c, nl, L);
    double xc[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
    if (!(dot(xc, nl) > 1e-3 * size)) return 0; /* x in front of the light */
    int above, below;
    horizon_counts(L, x, nx, &above, &below);
    if (above == 0) return 0;
    if (fam == FAM_ABOVE && below > 0) return 0;
    if (fam == FAM_STRADDLE && below == 0) return 0;
    return 1;
}

static void draw_config(rng *r, int fam, int shape, light *L, double x[3], double nx[3])
{
    while (!make_config(r, fam, shape, L, x, nx)) {
    }
}

/* Configurations per family and shape. x close to the light makes the
 * reference quadrature expensive (a graded mesh around the foot point), so the
 * near family has fewer; this keeps the test near 1 s under ASan at -O0. */
static int per_cell(int fam) { return fam == FAM_NEAR ? 4 : 10; }

static void test_random_families(table *t)
{
    rng r = {0x5EED1234ABCDull};
    double maxerr[FAM_COUNT][SHAPE_COUNT] = {{0}};
    for (int fam = 0; fam < FAM_COUNT; fam++) {
        for (int shape = 0; shape < SHAPE_COUNT; shape++) {
            for (int i = 0; i < per_cell(fam); i++) {
                light L;
                double x[3], nx[3];
                draw_config(&r, fam, shape, &L, x, nx);
                double ref = reference_G(&L, x, nx, 1e-10);
                double g = light_G(&L, x, nx);
                double e = rel_err(g, ref);
                CHECK_MSG(isfinite(g) && e <= 1e-6 && g <= M_PI,
                          "%s/%s #%d: G %.17g, quadrature %.17g (rel %.3g)", fam_name[fam],
                          shape_name[shape], i, g, ref, e);
                if (e > maxerr[fam][shape]) maxerr[fam][shape] = e;
            }
        }
    }
    printf("max relative error vs adaptive quadrature (random configurations, %d per cell, "
           "%d for the near family):\n", per_cell(FAM_ABOVE), per_cell(FAM_NEAR));
    printf("  %-30s %10s %10s %10s\n", "family", shape_name[0], shape_name[1], shape_name[2]);
    for (int fam = 0; fam < FAM_COUNT; fam++) {
        printf("  %-30s %10.2e %10.2e %10.2e\n", fam_name[fam], maxerr[fam][0], maxerr[fam][1],
               maxerr[fam][2]);
        for (int s = 0; s < SHAPE_COUNT; s++) table_add(t, "random, all families", "rel", maxerr[fam][s]);
    }
    int total = 0;
    for (int fam = 0; fam < FAM_COUNT; fam++) total += SHAPE_COUNT * per_cell(fam);
    t->row[t->n - 1].count = total;
}

/* Everything translated by ~1e5 gives the un-translated result. */
static void test_offset(table *t)
{
    rng r = {0x0FF5E7ull};
    const double T[3] = {1.0e5, -7.3e4, 2.9e4};
    for (int i = 0; i < 60; i++) {
        light L, M;
        double x[3], nx[3], xt[3];
        draw_config(&r, i % FAM_COUNT, i % SHAPE_COUNT, &L, x, nx);
        M = L;
        for (int k = 0; k < 3; k++) {
            xt[k] = x[k] + T[k];
            for (int v = 0; v < L.n; v++) M.v[v][k] = L.v[v][k] + T[k];
        }
        double g = light_G(&L, x, nx), gt = light_G(&M, xt, nx);
        double e = rel_err(gt, g);
        CHECK_MSG(e <= 1e-6, "offset #%d: %.17g vs %.17g (rel %.3g)", i, gt, g, e);
        table_add(t, "offset by 1e5 vs un-offset", "rel", e);
    }
}

/* G is invariant under scaling about any point; extreme units are harmless. */
static void test_scale(table *t)
{
    rng r = {0x5CA1Eull};
    const double scales[4] = {1e-150, 3e-300, 1e150, 7e300};
    for (int i = 0; i < 24; i++) {
        light L, M;
        double x[3], nx[3], xs[3];
        draw_config(&r, i % 2 ? FAM_ABOVE : FAM_STRADDLE, i % SHAPE_COUNT, &L, x, nx);
        double sc = scales[i % 4];
        /* Keep the coordinates finite: the configurations span up to ~200. */
        if (sc > 1e300) sc /= 1e3;
        M = L;
        for (int k = 0; k < 3; k++) {
            xs[k] = x[k] * sc;
            for (int v = 0; v < L.n; v++) M.v[v][k] = L.v[v][k] * sc;
        }
        double g = light_G(&L, x, nx), gs = light_G(&M, xs, nx);
        double e = rel_err(gs, g);
        CHECK_MSG(e <= 1e-9, "scale %g #%d: %.17g vs %.17g", sc, i, gs, g);
        table_add(t, "scaled by 1e-300..1e300", "rel", e);
    }
}

/* ---- closed forms ---------------------------------------------------------- */

/* Rectangle [0,a]x[0,b] (a, b ≥ 0) parallel to the receiver's plane at height h,
 * receiver below its corner and facing it: the point-to-parallel-rectangle
 * form factor times π. */
static double corner_G(double a, double b, double h)
{
    double ra = sqrt(a * a + h * h), rb = sqrt(b * b + h * h);
    return 0.5 * (a / ra * atan(b / ra) + b / rb * atan(a / rb));
}
static double signed_corner_G(double a, double b, double h)
{
    double s = (a < 0.0 ? -1.0 : 1.0) * (b < 0.0 ? -1.0 : 1.0);
    return s * corner_G(fabs(a), fabs(b), h);
}
/* Rectangle [x0,x1]x[y0,y1] at height h, receiver at the origin facing up. */
static double rect_G(double x0, double x1, double y0, double y1, double h)
{
    return signed_corner_G(x1, y1, h) - signed_corner_G(x0, y1, h) - signed_corner_G(x1, y0, h) +
           signed_corner_G(x0, y0, h);
}

/* Square of half-size a at height h centred above x, facing down. */
static double square_at(double a, double h)
{
    const double v[4][3] = {{-a, -a, h}, {-a, a, h}, {a, a, h}, {a, -a, h}};
    const double x[3] = {0.0, 0.0, 0.0}, nx[3] = {0.0, 0.0, 1.0};
    return samp_polygon_G(v, 4, x, nx);
}

static void test_square_closed_form(table *t)
{
    const double ah[] = {1e-6, 1e-4, 1e-2, 0.1, 0.5, 1.0, 2.0, 10.0, 1e3};
    for (unsigned i = 0; i < sizeof ah / sizeof ah[0]; i++) {
        double q = ah[i] / sqrt(ah[i] * ah[i] + 1.0);
        double want = 4.0 * q * atan(q), e = rel_err(square_at(ah[i], 1.0), want);
        CHECK_MSG(e <= 1e-12, "square a/h %g: rel %.3g", ah[i], e);
        table_add(t, "square, closed form", "rel", e);
    }
    /* Across the switch between the edge formula and the quadrature (the
     * square's extent is 0.1 of the distance at a/h = 0.0354). */
    for (int i = 0; i <= 40; i++) {
        double a = 0.02 + 0.03 * i / 40.0, q = a / sqrt(a * a + 1.0);
        double e = rel_err(square_at(a, 1.0), 4.0 * q * atan(q));
        CHECK_MSG(e <= 1e-13, "square a/h %g (switch): rel %.3g", a, e);
        table_add(t, "square, across quadrature switch", "rel", e);
    }
    /* An infinite plane light gives π; the documented example. */
    CHECK_NEAR(square_at(1e8, 1.0), M_PI, 1e-7);
    CHECK_NEAR(square_at(0.5, 1.0), 4.0 * sqrt(0.2) * atan(sqrt(0.2)), 1e-15);
    /* A tiny disc-like light straight above: A/d². */
    CHECK(rel_err(square_at(1e-4, 3.0), 4e-8 / 9.0) <= 1e-8);
}

/* Concave L-hexagon parallel above the receiver, by superposition of rectangles,
 * with the receiver's foot inside, outside, in the notch and under a vertex. */
static void test_L_closed_form(table *t)
{
    /* L = [0,2]x[0,1] ∪ [0,1]x[1,2], listed clockwise seen from above so that
     * it faces down (-z) towards the receiver. */
    const double P[6][2] = {{0, 0}, {0, 2}, {1, 2}, {1, 1}, {2, 1}, {2, 0}};
    const double feet[][2] = {{0.5, 0.5}, {1.5, 1.5}, {1.2, 0.3}, {3.0, -1.0}, {1.0, 1.0},
                              {-0.7, 2.5}, {0.25, 1.75}};
    const double hs[] = {0.05, 0.4, 1.0, 3.0};
    for (unsigned f = 0; f < sizeof feet / sizeof feet[0]; f++) {
        for (unsigned j = 0; j < sizeof hs / sizeof hs[0]; j++) {
            double v[6][3], px = feet[f][0], py = feet[f][1], h = hs[j];
            for (int i = 0; i < 6; i++) set3(v[i], P[i][0] - px, P[i][1] - py, h);
            const double x[3] = {0.0, 0.0, 0.0}, nx[3] = {0.0, 0.0, 1.0};
            double want = rect_G(-px, 2.0 - px, -py, 1.0 - py, h) + rect_G(-px, 1.0 - px, 1.0 - py, 2.0 - py, h);
            double got = samp_polygon_G((const double (*)[3])v, 6, x, nx);
            double e = rel_err(got, want);
            CHECK_MSG(e <= 1e-12, "L foot (%g,%g) h %g: %.17g vs %.17g", px, py, h, got, want);
            table_add(t, "concave L, closed form", "rel", e);
        }
    }
}

/* ---- limits: small lights, far lights, point lights ----------------------- */

static void test_small_and_far(table *t)
{
    rng r = {0x7149ull};
    for (int i = 0; i < 60; i++) {
        /* A 1e-6-sized light 0.1..10 away, or a unit light 1e4..1e6 away, fully
         * above the horizon and facing x. */
        int tiny = i % 2 == 0;
        shape2d s;
        random_shape(&r, i % SHAPE_COUNT, &s);
        double size = tiny ? 1e-6 : 1.0, dist = tiny ? rnd_log(&r, 0.1, 10.0) : rnd_log(&r, 1e4, 1e6);
        double c[3], nx[3], dir[3], nl[3], x[3];
        /* The tiny light sits at the origin: at 1 from it, its vertices would
         * be rounded to 1e-10 of its size, tilting it by as much. */
        for (int k = 0; k < 3; k++) c[k] = tiny ? 0.0 : rnd_in(&r, -1.0, 1.0);
        rnd_dir(&r, nx);
        rnd_dir_band(&r, nx, 0.1, 1.0, dir);
        double back[3] = {-dir[0], -dir[1], -dir[2]};
        rnd_dir_band(&r, back, 0.1, 1.0, nl);
        madd(c, -dist, dir, x);
        light L;
        place_light(&r, &s, size, c, nl, &L);
        double g = light_G(&L, x, nx);
        double ga = samp_small_area_G(L.centroid, L.nl, L.area, x, nx);
        double e = rel_err(g, ga);
        CHECK_MSG(e <= 1e-6, "%s light #%d: G %.17g, small-area %.17g (rel %.3g)",
                  tiny ? "1e-6" : "far", i, g, ga, e);
        table_add(t, tiny ? "1e-6 light vs samp_small_area_G" : "far light vs samp_small_area_G",
                  "rel", e);
        if (tiny) {
            /* Against the quadrature too: the difference to the small-area
             * formula above is O((size/r)²), this one is rounding only. */
            double ref = reference_G(&L, x, nx, 1e-13);
            CHECK_MSG(rel_err(g, ref) <= 1e-12, "1e-6 light #%d: G %.17g, quadrature %.17g", i, g, ref);
            table_add(t, "1e-6 light vs adaptive quadrature", "rel", rel_err(g, ref));
        }
    }
}

static void test_point_and_small_area(void)
{
    const double o[3] = {0, 0, 0}, up[3] = {0, 0, 1}, down[3] = {0, 0, -1};
    const double p1[3] = {0, 0, 2}, p2[3] = {3, 0, 4}, p3[3] = {0, 0, -2}, p4[3] = {0, 0, 1e-100};
    CHECK_NEAR(samp_point_G(p1, o, up), 0.25, 1e-16);
    CHECK_NEAR(samp_point_G(p2, o, up), 4.0 / 125.0, 1e-17);
    CHECK(samp_point_G(p3, o, up) == 0.0);     /* below the horizon */
    CHECK(samp_point_G(o, o, up) == 0.0);      /* p == x */
    CHECK(rel_err(samp_point_G(p4, o, up), 1e200) <= 1e-15);
    const double pside[3] = {1, 0, 0};
    CHECK(samp_point_G(pside, o, up) == 0.0); /* on the horizon */
    /* small area: A·cosθx·cosθy/r² */
    CHECK_NEAR(samp_small_area_G(p1, down, 2.0, o, up), 0.5, 1e-16);
    CHECK(samp_small_area_G(p1, up, 2.0, o, up) == 0.0);   /* x behind the light */
    CHECK(samp_small_area_G(p3, up, 2.0, o, up) == 0.0);   /* light below the horizon */
    CHECK(samp_small_area_G(p1, down, 0.0, o, up) == 0.0);
    CHECK(samp_small_area_G(p1, down, -1.0, o, up) == 0.0);
    CHECK(samp_small_area_G(o, down, 1.0, o, up) == 0.0);
    double nl[3] = {-0.6, 0.0, -0.8};
    /* = A·point_G·cosθy, cosθy = nl·(x − c)/r */
    double cy = -dot(nl, p2) / 5.0;
    CHECK(rel_err(samp_small_area_G(p2, nl, 0.3, o, up), 0.3 * samp_point_G(p2, o, up) * cy) <= 1e-15);
}

/* ---- exact zeros and degenerate input ------------------------------------ */

static void test_exact_zeros(void)
{
    rng r = {0x2E40ull};
    int below_zero = 1, behind_zero = 1;
    for (int i = 0; i < 60; i++) {
        light L;
        double x[3], nx[3];
        draw_config(&r, i % FAM_COUNT, i % SHAPE_COUNT, &L, x, nx);
        /* With nx reversed, a light that was entirely above x's horizon is
         * entirely at or below the new one. */
        double flip[3] = {-nx[0], -nx[1], -nx[2]};
        int above, below;
        horizon_counts(&L, x, nx, &above, &below);
        if (below == 0) below_zero &= light_G(&L, x, flip) == 0.0;
        /* Vertex order reversed: x is now behind the emitting side. */
        light R = L;
        for (int v = 0; v < L.n; v++) memcpy(R.v[v], L.v[L.n - 1 - v], sizeof R.v[v]);
        behind_zero &= light_G(&R, x, nx) == 0.0;
        CHECK(light_G(&L, x, nx) > 0.0);
    }
    CHECK_MSG(below_zero, "a light entirely below the horizon must give exactly 0");
    CHECK_MSG(behind_zero, "a receiver behind the emitting side must give exactly 0");

    /* Light touching the horizon at one vertex, rest below: 0. Light in the
     * horizon plane (coplanar with x): 0. */
    const double x[3] = {0, 0, 0}, up[3] = {0, 0, 1};
    const double touch[3][3] = {{1, 0, 0}, {2, -1, -1}, {2, 1, -1}};
    const double touch_r[3][3] = {{1, 0, 0}, {2, 1, -1}, {2, -1, -1}};
    CHECK(samp_polygon_G(touch, 3, x, up) == 0.0);
    CHECK(samp_polygon_G(touch_r, 3, x, up) == 0.0);
    const double flat[4][3] = {{1, -1, 0}, {1, 1, 0}, {3, 1, 0}, {3, -1, 0}};
    const double down[3] = {0, 0, -1}, side[3] = {-1, 0, 0};
    CHECK(samp_polygon_G(flat, 4, x, up) == 0.0);
    CHECK(samp_polygon_G(flat, 4, x, down) == 0.0);
    CHECK(samp_polygon_G(flat, 4, x, side) == 0.0);
}

/* Receiver in the light's plane, on an edge, on a vertex; and just in front. */
static void test_receiver_on_light(void)
{
    /* Axis-aligned unit square at z = 0 facing +z (exactly representable). */
    const double sq[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    const double pts[][3] = {{0.3, 0.4, 0}, {1, 0.3, 0}, {1, 1, 0}, {0, 0, 0}, {2, 0, 0}, {0.5, 0, 0}};
    const double nxs[][3] = {{0, 0, 1}, {0, 0, -1}, {0.6, 0, 0.8}, {1, 0, 0}, {0, -0.8, 0.6}};
    for (unsigned i = 0; i < sizeof pts / sizeof pts[0]; i++)
        for (unsigned j = 0; j < sizeof nxs / sizeof nxs[0]; j++)
            CHECK_MSG(samp_polygon_G(sq, 4, pts[i], nxs[j]) == 0.0, "in-plane point %u, normal %u", i, j);

    /* A tilted light with inexact coordinates: x on an edge (interpolated), on
     * a vertex, inside; any receiver normal. Finite, and 0 (in-plane). */
    rng r = {0xED6Eull};
    for (int i = 0; i < 40; i++) {
        shape2d s;
        random_shape(&r, SHAPE_QUAD, &s);
        double c[3], nl[3], nx[3], x[3];
        for (int k = 0; k < 3; k++) c[k] = rnd_in(&r, -3.0, 3.0);
        rnd_dir(&r, nl);
        rnd_dir(&r, nx);
        light L;
        place_light(&r, &s, rnd_log(&r, 0.1, 10.0), c, nl, &L);
        double t = rnd(&r);
        int e0 = i % 4, e1 = (e0 + 1) % 4;
        for (int k = 0; k < 3; k++) x[k] = L.v[e0][k] + t * (L.v[e1][k] - L.v[e0][k]);
        double g_edge = light_G(&L, x, nx), g_vert = light_G(&L, L.v[e1], nx);
        double g_in = light_G(&L, L.centroid, nx);
        CHECK_MSG(isfinite(g_edge) && g_edge >= 0.0 && g_edge <= M_PI, "on edge: %g", g_edge);
        CHECK_MSG(isfinite(g_vert) && g_vert >= 0.0 && g_vert <= M_PI, "on vertex: %g", g_vert);
        CHECK_MSG(isfinite(g_in) && g_in >= 0.0 && g_in <= M_PI, "inside: %g", g_in);
        CHECK_MSG(g_edge == 0.0 && g_vert == 0.0 && g_in == 0.0,
                  "in-plane receiver #%d: edge %g vertex %g inside %g", i, g_edge, g_vert, g_in);
    }

    /* Just in front, facing the light: G → π inside, π/2 on an edge, π/4 at a
     * right-angled corner, as the height goes to 0. */
    const double face[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    const double nx[3] = {0, 0, -1};
    const double d = 1e-9;
    const double in[3] = {0.5, 0.5, d}, ed[3] = {0.5, 0.0, d}, co[3] = {1.0, 1.0, d};
    CHECK_NEAR(samp_polygon_G(face, 4, in, nx), M_PI, 1e-7);
    CHECK_NEAR(samp_polygon_G(face, 4, ed, nx), M_PI / 2.0, 1e-7);
    CHECK_NEAR(samp_polygon_G(face, 4, co, nx), M_PI / 4.0, 1e-7);
    const double d2 = 1e-13;
    const double in2[3] = {0.5, 0.5, d2}, ed2[3] = {0.5, 0.0, d2}, co2[3] = {0.0, 0.0, d2};
    CHECK_NEAR(samp_polygon_G(face, 4, in2, nx), M_PI, 1e-12);
    CHECK_NEAR(samp_polygon_G(face, 4, ed2, nx), M_PI / 2.0, 1e-12);
    CHECK_NEAR(samp_polygon_G(face, 4, co2, nx), M_PI / 4.0, 1e-12);
    /* Within rounding of the plane (documented: ~1e-15 of the distance to the
     * farthest vertex) the receiver is in the plane: exactly 0, never garbage. */
    const double in3[3] = {0.5, 0.5, 1e-300}, co3[3] = {0.0, 0.0, 1e-17};
    CHECK(samp_polygon_G(face, 4, in3, nx) == 0.0);
    CHECK(samp_polygon_G(face, 4, co3, nx) == 0.0);
}

static void test_degenerate_input(void)
{
    const double x[3] = {0.2, 0.3, 0}, up[3] = {0, 0, 1};
    const double q[4][3] = {{0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}};
    const double qdup[6][3] = {{0, 0, 1}, {0, 1, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}, {0, 0, 1}};
    double g = samp_polygon_G(q, 4, x, up);
    CHECK(g > 0.0);
    /* Repeated vertices (zero-length edges) change nothing. */
    CHECK(rel_err(samp_polygon_G(qdup, 6, x, up), g) <= 1e-14);
    /* Bad arguments. */
    CHECK(samp_polygon_G(NULL, 4, x, up) == 0.0);
    CHECK(samp_polygon_G(q, 2, x, up) == 0.0);
    CHECK(samp_polygon_G(q, 0, x, up) == 0.0);
    CHECK(samp_polygon_G(q, -3, x, up) == 0.0);
    CHECK(samp_polygon_G(q, 4, NULL, up) == 0.0);
    CHECK(samp_polygon_G(q, 4, x, NULL) == 0.0);
    const double zero[3] = {0, 0, 0}, nanv[3] = {0, NAN, 1};
    CHECK(samp_polygon_G(q, 4, x, zero) == 0.0);
    CHECK(samp_polygon_G(q, 4, x, nanv) == 0.0);
    CHECK(samp_polygon_G(q, 4, nanv, up) == 0.0);
    const double qnan[4][3] = {{0, 0, 1}, {0, 1, 1}, {1, INFINITY, 1}, {1, 0, 1}};
    CHECK(samp_polygon_G(qnan, 4, x, up) == 0.0);
    const double huge[3][3] = {{-1e308, 0, 1}, {1e308, 1, 1}, {0, -1e308, 1}};
    double gh = samp_polygon_G(huge, 3, x, up);
    CHECK(isfinite(gh) && gh >= 0.0 && gh <= M_PI);
    /* Zero area: collinear, all at one point, all at x. */
    const double line[3][3] = {{0, 0, 1}, {1, 1, 1}, {2, 2, 1}};
    const double point[3][3] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
    const double atx[3][3] = {{0.2, 0.3, 0}, {0.2, 0.3, 0}, {0.2, 0.3, 0}};
    CHECK(samp_polygon_G(line, 3, x, up) == 0.0);
    CHECK(samp_polygon_G(point, 3, x, up) == 0.0);
    CHECK(samp_polygon_G(atx, 3, x, up) == 0.0);
    /* Non-planar quad (outside the contract): receivers on an edge's line, on
     * an edge, at a vertex exercise the |R_i × R_i+1| = 0 skip. Finite. */
    const double bent[4][3] = {{0, 0, 0}, {0, 1, 0}, {1, 1, 0.01}, {1, 0, 0}};
    const double on[][3] = {{0, 2, 0}, {0, -1, 0}, {0, 0.5, 0}, {0, 0, 0}, {0, 1, 0}, {1.0 / 3.0, 0, 0}};
    const double nxs[][3] = {{0, 0, 1}, {0, 0, -1}, {0.6, 0, 0.8}, {0, 0.6, -0.8}};
    for (unsigned i = 0; i < sizeof on / sizeof on[0]; i++) {
        for (unsigned j = 0; j < sizeof nxs / sizeof nxs[0]; j++) {
            double gb = samp_polygon_G(bent, 4, on[i], nxs[j]);
            CHECK_MSG(isfinite(gb) && gb >= 0.0 && gb <= M_PI, "bent quad %u/%u: %g", i, j, gb);
        }
    }
}

/* ---- horizon clipping ---------------------------------------------------- */

static void test_clipping(table *t)
{
    /* Square above x cut by a tilted horizon that removes one corner: the
     * visible part is a pentagon. */
    const double sq[4][3] = {{-1, -1, 1}, {-1, 1, 1}, {1, 1, 1}, {1, -1, 1}}; /* faces -z */
    const double x[3] = {0, 0, 0};
    double nx[3] = {-1, -1, 0.6};
    normalize(nx);
    light L;
    light_from(&L, sq, 4, NULL, 0);
    double g = samp_polygon_G(sq, 4, x, nx), ref = reference_G(&L, x, nx, 1e-11);
    double e = rel_err(g, ref);
    CHECK_MSG(e <= 1e-9, "quad → pentagon: %.17g vs %.17g", g, ref);
    table_add(t, "horizon cuts quad to pentagon", "rel", e);
    /* The same pentagon given explicitly (two vertices on the horizon). Horizon
     * y1 + y2 = 0.6 at z = 1 cuts the edges from (1,1) to (1,-1) and (-1,1). */
    const double pent[5][3] = {{-1, -1, 1}, {-1, 1, 1}, {-0.4, 1, 1}, {1, -0.4, 1}, {1, -1, 1}};
    double gp = samp_polygon_G(pent, 5, x, nx);
    CHECK_MSG(rel_err(gp, g) <= 1e-13, "explicit pentagon %.17g vs clipped quad %.17g", gp, g);
    table_add(t, "horizon cuts quad to pentagon", "rel", rel_err(gp, g));
    /* Triangle with one vertex exactly on the horizon (zero-length clip edge),
     * facing the receiver at the origin. */
    const double tri[3][3] = {{1, 0, 0}, {2, -1, 1}, {2, 1, 1}};
    const double nxz[3] = {0, 0, 1}, xt[3] = {0, 0, 0};
    light T;
    light_from(&T, tri, 3, NULL, 0);
    CHECK(T.nl[0] < 0.0); /* emits towards -x, i.e. towards xt */
    g = light_G(&T, xt, nxz), ref = reference_G(&T, xt, nxz, 1e-11);
    CHECK_MSG(g > 0.0 && rel_err(g, ref) <= 1e-9, "vertex on horizon: %.17g vs %.17g", g, ref);
    table_add(t, "horizon cuts quad to pentagon", "rel", rel_err(g, ref));

    /* Concave L cut by the horizon into two pieces (joined by edges along the
     * horizon that must cancel). Its arms at x = [0,0.5] and [1.5,2] stand above
     * z = 0.2, the connecting bar below. */
    const double Lv[8][3] = {{0, 0, 1}, {0, 2, 1}, {0.5, 2, 1}, {0.5, 0.5, 1},
                             {1.5, 0.5, 1}, {1.5, 2, 1}, {2, 2, 1}, {2, 0, 1}};
    const int Lt[6][3] = {{0, 1, 2}, {0, 2, 3}, {0, 3, 7}, {3, 4, 7}, {4, 6, 7}, {4, 5, 6}};
    light U;
    light_from(&U, Lv, 8, Lt, 6);
    double xu[3] = {1.0, -0.5, 0.0}, nu[3] = {0.0, 1.0, -1.5}; /* horizon: y > 1 at z = 1 */
    normalize(nu);
    int above, below;
    horizon_counts(&U, xu, nu, &above, &below);
    CHECK(above == 4 && below == 4);
    g = light_G(&U, xu, nu), ref = reference_G(&U, xu, nu, 1e-11);
    CHECK_MSG(g > 0.0 && rel_err(g, ref) <= 1e-9, "U cut in two: %.17g vs %.17g", g, ref);
    table_add(t, "horizon cuts U-octagon in two", "rel", rel_err(g, ref));
}

/* Light parallel to x's horizon plane, just above it, beside x: G ~ ε². The
 * edge terms cancel, so the error here is absolute (~1e-16), not relative. */
static void test_grazing(table *t)
{
    const double nx[3] = {0, 0, 1}, x[3] = {0, 0, 0};
    const double eps[] = {1e-2, 1e-4, 1e-6, 1e-9, 1e-12};
    for (unsigned i = 0; i < sizeof eps / sizeof eps[0]; i++) {
        /* Quad beside x facing down. */
        const double v[4][3] = {{1, -1, eps[i]}, {2.5, -0.5, eps[i]}, {3, 1, eps[i]}, {1.2, 0.8, eps[i]}};
        double w[4][3];
        for (int k = 0; k < 4; k++) memcpy(w[k], v[3 - k], sizeof w[k]);
        light L;
        light_from(&L, w, 4, NULL, 0);
        CHECK(L.nl[2] < 0.0);
        double g = light_G(&L, x, nx), ref = reference_G(&L, x, nx, 1e-11);
        CHECK_MSG(isfinite(g) && g >= 0.0 && fabs(g - ref) <= 1e-15 + 1e-6 * ref,
                  "grazing eps %g: %.17g vs %.17g", eps[i], g, ref);
        table_add(t, "grazing eps 1e-2..1e-12 (absolute)", "abs", fabs(g - ref));
        if (eps[i] >= 1e-4) table_add(t, "grazing eps >= 1e-4", "rel", rel_err(g, ref));
        /* Tilted so that it dips below the horizon. */
        w[0][2] = w[1][2] = -eps[i];
        light_from(&L, w, 4, NULL, 0);
        double xc[3] = {-L.v[0][0], -L.v[0][1], -L.v[0][2]};
        if (dot(xc, L.nl) > 0.0) {
            g = light_G(&L, x, nx), ref = reference_G(&L, x, nx, 1e-11);
            CHECK_MSG(isfinite(g) && g >= 0.0 && fabs(g - ref) <= 1e-15 + 1e-6 * ref,
                      "grazing tilted eps %g: %.17g vs %.17g", eps[i], g, ref);
            table_add(t, "grazing eps 1e-2..1e-12 (absolute)", "abs", fabs(g - ref));
        }
    }
}

int main(void)
{
    table t;
    memset(&t, 0, sizeof t);
    double t0 = lm_now_seconds();
    test_random_families(&t);
    test_offset(&t);
    test_scale(&t);
    test_square_closed_form(&t);
    test_L_closed_form(&t);
    test_small_and_far(&t);
    test_point_and_small_area();
    test_exact_zeros();
    test_receiver_on_light();
    test_degenerate_input();
    test_clipping(&t);
    test_grazing(&t);
    printf("summary (max error per case family):\n");
    printf("  %-38s %6s %10s\n", "case", "count", "max err");
    for (int i = 0; i < t.n; i++)
        printf("  %-38s %6d %10.2e %s\n", t.row[i].name, t.row[i].count, t.row[i].maxerr, t.row[i].kind);
    printf("reference quadrature: %ld integrand evaluations; total %.2f s\n", ref_evals_total,
           lm_now_seconds() - t0);
    return test_finish("analytic_irradiance_test");
}
