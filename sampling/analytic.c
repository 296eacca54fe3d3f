/* analytic.c — closed-form geometric term of a polygonal light (see analytic.h). */
#include "analytic.h"

#include <float.h>
#include <math.h>

/* A clipped light whose vertices all lie within this fraction of the distance
 * from x to its first vertex is integrated by quadrature instead of the edge
 * formula (see analytic.h, "Accuracy"). Measured on random lights, relative
 * errors at this ratio: quadrature ~1e-14, edge formula ~3e-13; below it the
 * quadrature stays at ~1e-15 while the edge formula loses digits as size/distance.
 * Overridable only for measuring the two paths. */
#ifndef SAMP_ANALYTIC_SMALL_RATIO
#define SAMP_ANALYTIC_SMALL_RATIO 0.1
#endif

/* x receives nothing when its height above the light's plane is at most this many
 * ulps of the (scaled, ~1) distance to the farthest vertex: that is rounding. */
#define SAMP_ANALYTIC_PLANE_EPS (16.0 * DBL_EPSILON)

static inline double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* The clipped polygon arrives one vertex at a time, in local coordinates l
 * (the point is x + 2^e·(o + l)); each new vertex closes one edge. */
typedef enum sink_mode {
    SINK_MEASURE,    /* count the vertices and find the clipped polygon's extent */
    SINK_EDGES,      /* Lambert's edge formula */
    SINK_QUADRATURE  /* quadrature over a fan */
} sink_mode;

typedef struct clip_sink {
    sink_mode mode;
    int count;         /* vertices received */
    double o[3];       /* (v_0 − x)·2^-e */
    double nx[3];
    double first[3], prev[3];
    double extent2;    /* SINK_MEASURE: max |p − first|² */
    double sum;
} clip_sink;

/* Θ·(c·nx)/|c| for the edge a→b, c = R_a × (R_b − R_a). The edge formula's terms
 * are bounded by π whatever the input; an edge whose line passes through x has
 * c = 0 and contributes nothing (its limit is direction-dependent but it has
 * measure zero). */
static double edge_term(const clip_sink *s, const double a[3], const double b[3])
{
    double ra[3] = {s->o[0] + a[0], s->o[1] + a[1], s->o[2] + a[2]};
    double rb[3] = {s->o[0] + b[0], s->o[1] + b[1], s->o[2] + b[2]};
    /* R_a × (l_b − l_a): the edge vector comes from the local coordinates, so a
     * short edge far from x keeps its relative precision. */
    double e[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double c[3];
    cross3(ra, e, c);
    double len = sqrt(dot3(c, c));
    if (!(len > 0.0)) return 0.0;
    double theta = atan2(len, dot3(ra, rb));
    return theta * (dot3(c, s->nx) / len);
}

/* ∫ (y·nx)·h/|y|⁴ dA over the triangle (a, b, c) (local coordinates), where
 * h·dA is taken from the triangle's own plane: h·J = −R_a·((b − a) × (c − a)),
 * the triple product, so no normal is involved (a light whose vertices were
 * rounded off its plane gives the same value as the boundary formula, as any
 * surface spanning the boundary does). Degree-8 Gauss–Legendre product rule on
 * the collapsed square: y = a + u(b − a) + uv(c − b), dA = u·J du dv. */
static double triangle_quad(const clip_sink *s, const double a[3], const double b[3],
                            const double c[3])
{
    static const double node[5] = {0.046910077030668003601, 0.23076534494715845448, 0.5,
                                   0.76923465505284154552, 0.9530899229693319964};
    static const double weight[5] = {0.11846344252809454376, 0.23931433524968323402,
                                     0.28444444444444444444, 0.23931433524968323402,
                                     0.11846344252809454376};
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double bc[3] = {c[0] - b[0], c[1] - b[1], c[2] - b[2]};
    double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double base[3] = {s->o[0] + a[0], s->o[1] + a[1], s->o[2] + a[2]};
    double n[3];
    cross3(ab, ac, n);
    double hjac = -dot3(base, n);
    if (hjac == 0.0) return 0.0;
    double total = 0.0;
    for (int i = 0; i < 5; i++) {
        double u = node[i], inner = 0.0;
        for (int j = 0; j < 5; j++) {
            double uv = u * node[j];
            double y[3] = {base[0] + u * ab[0] + uv * bc[0], base[1] + u * ab[1] + uv * bc[1],
                           base[2] + u * ab[2] + uv * bc[2]};
            double r2 = dot3(y, y);
            inner += weight[j] * dot3(y, s->nx) / (r2 * r2);
        }
        total += weight[i] * u * inner;
    }
    return total * hjac;
}

static void sink_vertex(clip_sink *s, const double p[3])
{
    if (s->count == 0) {
        for (int k = 0; k < 3; k++) s->first[k] = p[k];
    } else if (s->mode == SINK_MEASURE) {
        double d[3] = {p[0] - s->first[0], p[1] - s->first[1], p[2] - s->first[2]};
        if (dot3(d, d) > s->extent2) s->extent2 = dot3(d, d);
    } else if (s->mode == SINK_QUADRATURE) {
        if (s->count >= 2) s->sum += triangle_quad(s, s->first, s->prev, p);
    } else {
        s->sum += edge_term(s, s->prev, p);
    }
    for (int k = 0; k < 3; k++) s->prev[k] = p[k];
    s->count++;
}

static void sink_close(clip_sink *s)
{
    if (s->mode == SINK_EDGES && s->count >= 3) s->sum += edge_term(s, s->prev, s->first);
}

/* The vertices in local coordinates (v_i − v_0)·2^-e, where 2^-e brings the
 * largest coordinate of v_i − x into [0.5, 1); the multiplication by a normal
 * power of two is exact (ldexp when 2^-e is not a normal double). Polygons of
 * up to LOCAL_CACHE vertices are converted once, larger ones on every use. */
enum { LOCAL_CACHE = 32 };
typedef struct local_poly {
    const double (*verts)[3];
    int n, e;
    double factor; /* 2^-e, or 0 for ldexp */
    int cached;
    double l[LOCAL_CACHE][3];
} local_poly;

static inline double unscale(const local_poly *p, double v)
{
    return p->factor != 0.0 ? v * p->factor : ldexp(v, -p->e);
}

static inline void local_vertex(const local_poly *p, int i, double out[3])
{
    if (p->cached) {
        for (int k = 0; k < 3; k++) out[k] = p->l[i][k];
    } else {
        for (int k = 0; k < 3; k++) out[k] = unscale(p, p->verts[i][k] - p->verts[0][k]);
    }
}

/* Sutherland–Hodgman against d(y) = (y − x)·nx > 0, streaming the output
 * vertices (local coordinates) into s. At most 2n vertices come out (a concave
 * polygon may be cut into pieces joined by edges along the horizon, which cancel). */
static void clip_to_horizon(const local_poly *poly, clip_sink *s)
{
    double od = dot3(s->o, s->nx); /* the same sums as the caller's, bit for bit */
    double la[3], lb[3];
    local_vertex(poly, 0, la);
    double da = od + dot3(la, s->nx);
    for (int i = 0, n = poly->n; i < n; i++) {
        local_vertex(poly, i + 1 < n ? i + 1 : 0, lb);
        double db = od + dot3(lb, s->nx);
        if (da > 0.0) sink_vertex(s, la);
        if ((da > 0.0) != (db > 0.0)) {
            /* One of da, db is > 0 and the other ≤ 0, so da − db is non-zero
             * and has da's sign: 0 < t ≤ 1. */
            double t = da / (da - db), p[3];
            for (int k = 0; k < 3; k++) p[k] = la[k] + t * (lb[k] - la[k]);
            sink_vertex(s, p);
        }
        for (int k = 0; k < 3; k++) la[k] = lb[k];
        da = db;
    }
}

double samp_polygon_G(const double (*verts)[3], int n, const double x[3], const double nx[3])
{
    if (!verts || !x || !nx || n < 3) return 0.0;
    if (!(isfinite(nx[0]) && isfinite(nx[1]) && isfinite(nx[2]))) return 0.0;

    /* Scale: G is invariant under scaling about x, so bring the largest
     * coordinate of v_i − x into [0.5, 1) by an exact power of two. */
    double m = 0.0;
    for (int i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            double d = verts[i][k] - x[k], l = verts[i][k] - verts[0][k];
            if (!isfinite(d) || !isfinite(l)) return 0.0;
            if (fabs(d) > m) m = fabs(d);
        }
    }
    if (!(m > 0.0)) return 0.0;
    local_poly poly;
    poly.verts = verts;
    poly.n = n;
    poly.cached = 0;
    (void)frexp(m, &poly.e);
    poly.factor = poly.e > -1020 && poly.e < 1020 ? ldexp(1.0, -poly.e) : 0.0;
    if (n <= LOCAL_CACHE) {
        for (int i = 0; i < n; i++) local_vertex(&poly, i, poly.l[i]);
        poly.cached = 1;
    }

    clip_sink s = {0};
    for (int k = 0; k < 3; k++) {
        s.o[k] = unscale(&poly, verts[0][k] - x[k]);
        s.nx[k] = nx[k];
    }

    /* Newell normal (twice the vector area) from the local coordinates, which
     * are exact differences for nearby vertices; the mean vertex for the plane;
     * the extent from v_0 and whether every vertex is above the horizon. */
    double nrm[3] = {0.0, 0.0, 0.0}, mean[3] = {0.0, 0.0, 0.0};
    double far2 = dot3(s.o, s.o), extent2 = 0.0, od = dot3(s.o, s.nx);
    int all_above = od > 0.0;
    double li[3], lj[3], c[3];
    local_vertex(&poly, 1, li);
    for (int i = 1; i < n; i++) {
        double r[3] = {s.o[0] + li[0], s.o[1] + li[1], s.o[2] + li[2]};
        for (int k = 0; k < 3; k++) mean[k] += li[k];
        if (dot3(r, r) > far2) far2 = dot3(r, r);
        if (dot3(li, li) > extent2) extent2 = dot3(li, li);
        all_above &= od + dot3(li, s.nx) > 0.0;
        if (i + 1 < n) {
            local_vertex(&poly, i + 1, lj);
            cross3(li, lj, c);
            for (int k = 0; k < 3; k++) {
                nrm[k] += c[k];
                li[k] = lj[k];
            }
        }
    }
    double area2 = sqrt(dot3(nrm, nrm));
    if (!(area2 > 0.0)) return 0.0;
    for (int k = 0; k < 3; k++) mean[k] /= n;
    double h = -(dot3(nrm, s.o) + dot3(nrm, mean)) / area2;
    /* Behind the emitting side, or in the light's plane up to rounding. */
    if (!(h > SAMP_ANALYTIC_PLANE_EPS * sqrt(far2))) return 0.0;

    /* A clipped polygon small against its distance goes to the quadrature. When
     * every vertex is above the horizon the clipped polygon is P itself, starting
     * at v_0; otherwise (also a sliver of a large light just above the horizon)
     * the clipped polygon is measured first. */
    double d2 = dot3(s.o, s.o);
    if (!all_above) {
        s.mode = SINK_MEASURE;
        clip_to_horizon(&poly, &s);
        if (s.count < 3) return 0.0;
        double r0[3] = {s.o[0] + s.first[0], s.o[1] + s.first[1], s.o[2] + s.first[2]};
        d2 = dot3(r0, r0);
        extent2 = s.extent2;
    }
    const double ratio2 = SAMP_ANALYTIC_SMALL_RATIO * SAMP_ANALYTIC_SMALL_RATIO;
    s.mode = extent2 < ratio2 * d2 ? SINK_QUADRATURE : SINK_EDGES;
    s.count = 0;
    clip_to_horizon(&poly, &s);
    if (s.count < 3) return 0.0;
    sink_close(&s);

    double g = s.mode == SINK_QUADRATURE ? s.sum : -0.5 * s.sum;
    return g > 0.0 && g < INFINITY ? g : 0.0;
}

double samp_point_G(const double p[3], const double x[3], const double nx[3])
{
    if (!p || !x || !nx) return 0.0;
    double d[3] = {p[0] - x[0], p[1] - x[1], p[2] - x[2]};
    double m = fmax(fabs(d[0]), fmax(fabs(d[1]), fabs(d[2])));
    if (!(m > 0.0) || !(m < INFINITY)) return 0.0;
    for (int k = 0; k < 3; k++) d[k] /= m; /* |d| in [1, √3]: no under/overflow */
    double cx = dot3(nx, d);
    if (!(cx > 0.0)) return 0.0;
    double r2 = dot3(d, d);
    return cx / (r2 * sqrt(r2)) / m / m;
}

double samp_small_area_G(const double c[3], const double nl[3], double area, const double x[3],
                         const double nx[3])
{
    if (!c || !nl || !x || !nx || !(area > 0.0) || !(area < INFINITY)) return 0.0;
    double d[3] = {c[0] - x[0], c[1] - x[1], c[2] - x[2]}; /* x → light centre */
    double m = fmax(fabs(d[0]), fmax(fabs(d[1]), fabs(d[2])));
    if (!(m > 0.0) || !(m < INFINITY)) return 0.0;
    for (int k = 0; k < 3; k++) d[k] /= m;
    double cx = dot3(nx, d), cy = -dot3(nl, d);
    if (!(cx > 0.0) || !(cy > 0.0)) return 0.0;
    double r2 = dot3(d, d);
    return area / m / m * (cx * cy / (r2 * r2));
}
