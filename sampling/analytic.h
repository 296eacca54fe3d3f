/* analytic.h — closed-form, unoccluded geometric term G of a one-sided polygonal
 * light, in double precision (docs/sampling.md: the control variate). Used by tests as
 * ground truth and by the samplers as a control variate.
 *
 *     G(x) = ∫_P max(0,cosθ_x)·max(0,cosθ_y) / r² dA_y      (no visibility term)
 *
 * is the irradiance at x per unit emitted radiance: E = Le·G. It is dimensionless
 * (the cosine-weighted solid angle of P seen from x), 0 ≤ G ≤ π for a unit nx; an
 * infinite emitting plane in front of x gives π, a small light of area A straight
 * above x at distance d facing it gives A/d². (The form factor is G/π.)
 *
 * Method: the part of P above x's horizon is found by clipping P against the
 * plane through x with normal nx (Sutherland–Hodgman, streamed, no allocation;
 * a quad cut by the horizon becomes a pentagon), then Lambert's edge formula
 *     G = ½ Σ_edges Θ_i (γ_i·nx),  Θ_i = ∠(R_i, R_i+1),  R_i = v_i − x,
 *     γ_i = (R_i+1 × R_i) / |R_i+1 × R_i|   (the plane through x and the edge),
 * which is ≥ 0 with the vertices right-handed about the emitting normal and x in
 * front (Lambert, Photometria, 1760; in the form of Baum, Rushmeier and Winget,
 * "Improving radiosity solutions through the use of analytically determined
 * form-factors", SIGGRAPH '89, Computer Graphics 23(3):325–334, 1989; their
 * form factor is G/π). Angles are atan2(|R_i × e_i|, R_i·R_i+1) with
 * e_i = v_i+1 − v_i (never acos); edges with R_i × e_i = 0 (receiver on an
 * edge's line, repeated vertices) are skipped.
 * The vertices are taken relative to x (then v_0) in double and scaled by a
 * power of two first, so large coordinate offsets and extreme units are harmless.
 *
 * Accuracy (measured by tests/analytic_irradiance_test.c against closed forms and
 * adaptive quadrature): relative error ~1e-13 or better in ordinary configurations
 * (near, far, tilted, straddling the horizon, concave). Lambert's edge terms are of
 * size (light size / distance) while G is of size (light size / distance)², so
 * the edge formula loses digits on small or distant lights (relative error
 * ~1e-16·distance/size). A clipped light whose extent is below 1/10 of its
 * distance is therefore integrated instead by a degree-8 Gauss–Legendre rule on
 * the collapsed square over a fan of the clipped polygon (relative error ~1e-14
 * at the switch, ~1e-15 below it, e.g. for a 1e-6-sized light). When G is tiny
 * only because the light is grazing (nearly edge-on to x, or nearly in x's
 * horizon plane) the edge terms still cancel and the error is absolute, ~1e-16
 * (relative 1e-8 at G ~ 1e-8). Coordinates far from the origin cost only the
 * rounding of the input itself.
 *
 * Conventions:
 *   - The polygon is planar and simple (convex or not), n ≥ 3 vertices in order,
 *     emitting on the side of its normal by the right-hand rule of the vertex
 *     order (counter-clockwise seen from the front). The normal is Newell's.
 *   - x behind the emitting side, or within rounding (16 ulps, ~3.6e-15, of the
 *     distance to the farthest vertex) of the light's plane — including x on an
 *     edge or a vertex of the light — gives exactly 0.0 (the integrand is 0 for
 *     y ≠ x there). Just in front, G has its limit: π inside, π/2 on an edge.
 *   - The light entirely at or below x's horizon gives exactly 0.0.
 *   - nx should be unit length; it is not renormalized (G is linear in it).
 *   - Bad input (NULL, n < 3, non-finite coordinates, zero-area polygon) gives 0.0.
 *     The result is never NaN or Inf and never negative.
 *
 * Usage:
 *     const double quad[4][3] = {{0,0,1}, {0,1,1}, {1,1,1}, {1,0,1}};  // faces -z
 *     const double x[3] = {0.5, 0.5, 0}, nx[3] = {0, 0, 1};
 *     double G = samp_polygon_G(quad, 4, x, nx);     // 0.75227..., E = Le·G
 *     const double p[3] = {0.5, 0.5, 2}, nl[3] = {0, 0, -1};
 *     double Gp = samp_point_G(p, x, nx);                 // point light: E = I·Gp
 *     double Gs = samp_small_area_G(p, nl, 1.0, x, nx);   // far-field approximation
 *
 * Threads: pure functions, no state; call from anywhere.
 * Does NOT do: visibility/occlusion, two-sided or textured emitters, curved lights,
 * non-planar polygons (the side test uses the Newell plane and the value is that
 * of the boundary, without guarantees).
 *
 * samp_polygon_phong: the modified Phong lobe integrated over the same kind of
 * polygon (eq. 5 of Fournier & Péroche 2005 for a fully visible area light),
 *     S(x, ωo) = ∫_P (n+2)/(2π)·max(0, cos α)ⁿ·max(0, cosθ_x)·max(0, cosθ_y)/r² dA_y,
 * α between ωo and the mirror of the direction to y about nx (equivalently
 * between that direction and r, the mirror of ωo): the specular radiance per
 * unit ks and unit emitted radiance, L = ks·Le·S — what the reference renderer's
 * ref_phong_lobe integrates (sampling/ref_shading.c). n = 0 gives G/π.
 * Method: P (relative to x) is clipped to the lobe's hemisphere (r·u ≥ 0) and
 * x's horizon (nx·u ≥ 0), both planes through x; on the clipped spherical
 * polygon the divergence theorem on the sphere turns the integral into edge
 * integrals (Arvo, "Applications of irradiance tensors to the simulation of
 * non-Lambertian phenomena", SIGGRAPH '95, his double-axis moment):
 *     ∫ cosⁿθ·(nx·u) dω = [(nx·r)·Σ_e ∫_e (1 − cosⁿθ) dφ − Σ_e (nx·m_e)·∫_e cosⁿθ ds] / (n + 2),
 * θ the angle from r, φ the azimuth about r, s the arc length, m_e the outward
 * normal of edge e's great circle. Arvo's recurrences in n are replaced by
 * 8-point Gauss–Legendre on each side of the edge's closest point to r, over
 * the lobe's core (5/√n; the integrands are smooth there even where the edge
 * passes through r), the azimuth in closed form outside it (analytic.c,
 * phong_edge), so any real n ≥ 0 costs the same; an edge whose great circle
 * misses the core costs one atan2. Relative error ≲1e-6 for n from 0 to 10⁴
 * (tests/cache_test.c, against brute-force quadrature); ~0.2–2.5 µs per call
 * on a quad light (docs/cache.md).
 */
#ifndef LUMESH_ANALYTIC_H
#define LUMESH_ANALYTIC_H

#ifdef __cplusplus
extern "C" {
#endif

/* G(x) = ∫_P cosθ_x cosθ_y / r² dA_y over the part of P above x's horizon
 * (dot(y − x, nx) > 0) for the one-sided polygon P (verts[0..n-1], in order),
 * as described above. Irradiance = Le·G. No allocation; any n. */
double samp_polygon_G(const double (*verts)[3], int n, const double x[3], const double nx[3]);

/* Point-light limit: an isotropic point light of intensity I at p gives
 * E = I·max(0,cosθ_x)/r²; returns max(0, dot(nx, p−x)) / |p−x|³ (multiply by I).
 * p == x gives 0.0; a non-zero distance below ~1e-154 overflows to +Inf (the true
 * value exceeds DBL_MAX). */
double samp_point_G(const double p[3], const double x[3], const double nx[3]);

/* Small-area (far-field) limit of samp_polygon_G for a light of area A with unit
 * normal nl (its emitting side) at centre c: A·max(0,cosθ_x)·max(0,cosθ_y)/r²,
 * cosθ_y = dot(nl, x−c)/r. Its relative difference from samp_polygon_G is
 * O((size/r)²). c == x or area ≤ 0 gives 0.0. */
double samp_small_area_G(const double c[3], const double nl[3], double area, const double x[3],
                         const double nx[3]);

/* The specular integral S(x, ωo) above for the one-sided polygon P (any n ≥ 3
 * vertices, the order and side conventions of samp_polygon_G). nx and wo (towards
 * the viewer) need not be unit length. Specular radiance: L = ks·Le·S.
 * Bad input, x behind P or in its plane, exponent < 0 or not finite: 0.0.
 * No allocation; never NaN, Inf or negative. */
double samp_polygon_phong(const double (*verts)[3], int n, const double x[3], const double nx[3], const double wo[3],
                          double exponent);

#ifdef __cplusplus
}
#endif
#endif
