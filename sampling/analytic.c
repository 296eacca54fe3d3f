/* analytic.c — closed-form geometric term of a polygonal light (see analytic.h). */
#include "sampling/analytic.h"

#include <float.h>
#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

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

/* ---- the modified Phong lobe over a polygon (samp_polygon_phong) ------------- */

/* Polygons are integrated in pieces of at most this many vertices (a fan of
 * pieces sharing vertex 0: the diagonals between pieces cancel). Two clips can
 * at most quadruple a non-convex piece. */
enum { PHONG_PIECE = 16, PHONG_CLIPPED = 4 * PHONG_PIECE + 4 };

/* 8-point Gauss–Legendre on [-1, 1]: the positive nodes and their weights. */
enum { PHONG_NODES = 8 };
static const double phong_gl[PHONG_NODES / 2][2] = {
    {0.96028985649753623168, 0.10122853629037625915}, {0.79666647741362673959, 0.22238103445337447054},
    {0.52553240991632898582, 0.31370664587788728734}, {0.18343464249564980494, 0.36268378337836198297}};


/* Sutherland–Hodgman against d·pn ≥ 0 (a plane through x); returns the count. */
static int phong_clip(const double (*in)[3], int n, const double pn[3], double (*out)[3])
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        const double *a = in[i], *b = in[i + 1 < n ? i + 1 : 0];
        double da = dot3(a, pn), db = dot3(b, pn);
        if (da >= 0.0) {
            for (int k = 0; k < 3; k++) out[m][k] = a[k];
            m++;
        }
        if ((da >= 0.0) != (db >= 0.0)) {
            double t = da / (da - db);
            for (int k = 0; k < 3; k++) out[m][k] = a[k] + t * (b[k] - a[k]);
            m++;
        }
    }
    return m;
}

/* Half-width of the lobe's core, in lobe widths 1/√n: beyond it cosⁿθ <
 * e^(-PHONG_CORE²/2) = 3.7e-6 of its value at the closest point, so the lobe
 * terms are dropped there (relative error below ~3e-7, a Gaussian's tail). An
 * edge whose whole great circle stays outside the core of r (R^n = cosⁿ of its
 * closest approach below e^PHONG_SKIP_LOG, the same 3.7e-6) has no lobe term
 * at all: A_e is its azimuth and E_e is 0 (error below R^n·π). */
#define PHONG_CORE 5.0
#define PHONG_SKIP_LOG (-0.5 * PHONG_CORE * PHONG_CORE)

/* ∫ ε/q dτ = atan(tan τ/ε) (cos τ > 0), signed like ε; 0 when ε = 0. */
static double phong_azimuth(double eps, double tau)
{
    double a = atan2(sin(tau), fabs(eps) * cos(tau));
    return eps > 0.0 ? a : eps < 0.0 ? -a : 0.0;
}

/* One edge ua → ub (unit directions, both in the lobe's hemisphere r·u ≥ 0) of
 * the clipped polygon: adds its A_e = ∫(1 − cosⁿθ)dφ (θ from r, φ the azimuth
 * about r, signed so a polygon around r gives 2π) to *A and (ns·m)·E_e,
 * E_e = ∫cosⁿθ ds (arc length), to *B, m the edge plane's outward normal.
 * Along the great circle, cosθ = R·cos τ (τ from the point closest to r) and
 * 1 − cos²θ = q = sin²τ + ε²cos²τ, ε = −r·m, R² = 1 − ε², dφ = ε/q dτ, so
 *     A_e = ∫ ε·Ψ(q) dτ,  Ψ(q) = (1 − (1 − q)^(n/2))/q,    E_e = ∫ (1 − q)^(n/2) dτ.
 * Ψ is entire in q (no pole where the edge passes through r: Ψ(0) = n/2), so in
 * the lobe's core, |τ| ≤ PHONG_CORE/√n, both are smooth and 8-point
 * Gauss–Legendre on each side of τ = 0 integrates them (≲1e-7 relative,
 * measured); outside the core the lobe is negligible, E_e gets nothing and A_e
 * the azimuth ∫ε/q dτ, in closed form. An edge whose whole great circle is
 * outside the core costs only that. */
static void phong_edge(const double ua[3], const double ub[3], const double r[3], const double ns[3], double n,
                       double *A, double *B)
{
    double c[3];
    cross3(ua, ub, c);
    double sl = sqrt(dot3(c, c));
    if (!(sl > 0.0)) return; /* repeated vertex: no edge */
    double m[3] = {c[0] / sl, c[1] / sl, c[2] / sl};
    double eps = -dot3(r, m), R2 = (1.0 - eps) * (1.0 + eps);
    if (n > 0.0 && (0.5 * n * eps * eps > -PHONG_SKIP_LOG || !(R2 > 0.0) ||
                    0.5 * n * log1p(-eps * eps) < PHONG_SKIP_LOG)) {
        /* Only the azimuth change about r, from the projections on r's plane
         * (the arc turns by less than π about r: it does not pass near r). */
        double ra = dot3(r, ua), rb = dot3(r, ub);
        double pa[3] = {ua[0] - ra * r[0], ua[1] - ra * r[1], ua[2] - ra * r[2]};
        double pb[3] = {ub[0] - rb * r[0], ub[1] - rb * r[1], ub[2] - rb * r[2]}, pc[3];
        cross3(pa, pb, pc);
        *A -= atan2(dot3(r, pc), dot3(pa, pb)); /* the polygon turns clockwise about r */
        return;
    }
    double R = sqrt(R2), theta = atan2(sl, dot3(ua, ub)), ns_m = dot3(ns, m);
    if (!(R > 1e-150)) { /* n = 0 on the lobe's horizon */
        *A += eps * theta;
        *B += ns_m * theta;
        return;
    }
    double f[3] = {(r[0] + eps * m[0]) / R, (r[1] + eps * m[1]) / R, (r[2] + eps * m[2]) / R}, g[3];
    cross3(m, f, g);
    double ta = atan2(dot3(ua, g), fmax(dot3(ua, f), 0.0)), tb = ta + theta;
    double core = n > 0.0 ? PHONG_CORE / sqrt(n) : INFINITY;
    double lo = fmax(ta, -core), hi = fmin(tb, core);
    if (!(lo < hi)) { /* all outside the core */
        *A += phong_azimuth(eps, tb) - phong_azimuth(eps, ta);
        return;
    }
    if (ta < lo) *A += phong_azimuth(eps, lo) - phong_azimuth(eps, ta);
    if (hi < tb) *A += phong_azimuth(eps, tb) - phong_azimuth(eps, hi);
    double cut[3] = {lo, hi, hi};
    int pieces = 1;
    if (lo < 0.0 && hi > 0.0) {
        cut[1] = 0.0;
        pieces = 2;
    }
    double eps2 = eps * eps, a = 0.0, e = 0.0;
    for (int p = 0; p < pieces; p++) {
        double mid = 0.5 * (cut[p] + cut[p + 1]), half = 0.5 * (cut[p + 1] - cut[p]);
        for (int i = 0; i < PHONG_NODES; i++) {
            const double *gl = phong_gl[i < PHONG_NODES / 2 ? i : PHONG_NODES - 1 - i];
            double x = i < PHONG_NODES / 2 ? -gl[0] : gl[0], w = gl[1] * half;
            double t = mid + half * x, st = sin(t), ct = cos(t);
            double q = st * st + eps2 * ct * ct, c2 = R2 * ct * ct; /* sin²θ, cos²θ */
            double lw = 0.5 * n * (q < 0.5 ? log1p(-q) : log(c2));
            double em = expm1(lw); /* cosⁿθ − 1 */
            a += w * (q > 0.0 ? -em / q : 0.5 * n);
            e += w * (1.0 + em);
        }
    }
    *A += eps * a;
    *B += ns_m * e;
}

/* One piece (≤ PHONG_PIECE vertices, relative to x): clipped to the lobe's
 * hemisphere and x's horizon, then its edges. */
static void phong_piece(const double (*d)[3], int cnt, const double r[3], const double ns[3], double n, double *A,
                        double *B)
{
    double c1[PHONG_CLIPPED][3], c2[PHONG_CLIPPED][3];
    int m1 = phong_clip(d, cnt, r, c1);
    if (m1 < 3) return;
    int m2 = phong_clip((const double (*)[3])c1, m1, ns, c2);
    if (m2 < 3) return;
    for (int i = 0; i < m2; i++) {
        double l = sqrt(dot3(c2[i], c2[i]));
        if (!(l > 0.0)) return; /* x on the polygon: nothing (it is behind or in its plane) */
        for (int k = 0; k < 3; k++) c2[i][k] /= l;
    }
    for (int i = 0; i < m2; i++) phong_edge(c2[i], c2[i + 1 < m2 ? i + 1 : 0], r, ns, n, A, B);
}

double samp_polygon_phong(const double (*verts)[3], int n, const double x[3], const double nx[3], const double wo[3],
                          double exponent)
{
    if (!verts || !x || !nx || !wo || n < 3 || !(exponent >= 0.0) || !(exponent < INFINITY)) return 0.0;
    double ln = sqrt(dot3(nx, nx)), lo = sqrt(dot3(wo, wo));
    if (!(ln > 0.0) || !(lo > 0.0) || !isfinite(ln) || !isfinite(lo)) return 0.0;
    double ns[3] = {nx[0] / ln, nx[1] / ln, nx[2] / ln}, w[3] = {wo[0] / lo, wo[1] / lo, wo[2] / lo};
    double wn = dot3(w, ns), r[3] = {2.0 * wn * ns[0] - w[0], 2.0 * wn * ns[1] - w[1], 2.0 * wn * ns[2] - w[2]};
    double lr = sqrt(dot3(r, r));
    for (int k = 0; k < 3; k++) r[k] /= lr;

    /* The side test of samp_polygon_G: Newell normal and mean vertex relative to
     * x, scaled by the largest coordinate. */
    double big = 0.0;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            double dk = verts[i][k] - x[k];
            if (!isfinite(dk)) return 0.0;
            big = fmax(big, fabs(dk));
        }
    if (!(big > 0.0)) return 0.0;
    double inv = 1.0 / big, nrm[3] = {0, 0, 0}, mean[3] = {0, 0, 0}, prev[3], cur[3], cc[3];
    for (int k = 0; k < 3; k++) prev[k] = (verts[n - 1][k] - x[k]) * inv;
    for (int i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) cur[k] = (verts[i][k] - x[k]) * inv;
        cross3(prev, cur, cc);
        for (int k = 0; k < 3; k++) {
            nrm[k] += cc[k];
            mean[k] += cur[k] / n;
            prev[k] = cur[k];
        }
    }
    double area2 = sqrt(dot3(nrm, nrm));
    if (!(area2 > 0.0) || !(-dot3(nrm, mean) / area2 > SAMP_ANALYTIC_PLANE_EPS)) return 0.0;

    double A = 0.0, B = 0.0, d[PHONG_PIECE][3];
    for (int first = 1; first + 1 < n;) {
        int last = first + PHONG_PIECE - 2 < n - 1 ? first + PHONG_PIECE - 2 : n - 1, cnt = 0;
        for (int k = 0; k < 3; k++) d[cnt][k] = (verts[0][k] - x[k]) * inv;
        cnt++;
        for (int i = first; i <= last; i++, cnt++)
            for (int k = 0; k < 3; k++) d[cnt][k] = (verts[i][k] - x[k]) * inv;
        phong_piece((const double (*)[3])d, cnt, r, ns, exponent, &A, &B);
        first = last;
    }
    /* ∫cosⁿα·cosθ_x dω = (dot(ns, r)·ΣA_e − Σ(ns·m_e)E_e)/(n + 2) over the clipped
     * polygon; times the lobe's (n + 2)/(2π). */
    double v = (dot3(ns, r) * A - B) / (2.0 * M_PI);
    return v > 0.0 && v < INFINITY ? v : 0.0;
}
