#version 450 core
// Radiance passes: the interpolated value. HIGHLIGHT (the specular mesh): the
// lights' part of L_ds evaluated at the pixel's own point and view instead,
//     L_ds = value − direct + visible·Σ_ℓ L_ℓ·S_ℓ(x, ωo),
// S_ℓ the modified Phong lobe integrated over light ℓ (paper eq. 5; the cache's
// samp_polygon_phong, sampling/analytic.c, ported to float: the divergence theorem
// on the sphere, one 1-D integral per edge of the light's outline, 8-point
// Gauss–Legendre over the lobe's core). The visible fraction and the glossy part
// (value − direct) stay interpolated; a highlight's outline, which linear
// interpolation over leaves a pixel wide spreads (docs/renderer.md, "Highlights
// per pixel"), is then exact. Materials with n < HIGHLIGHT_MIN_N, and leaves
// where a light is partly or wholly hidden (v_visible < MIN_VISIBLE), keep the
// interpolated value (mesh/cache/cache.h, CACHE_HIGHLIGHT_*).
in vec3 v_value;
layout(location = 0) out vec4 o_value;
#ifdef HIGHLIGHT
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_direct;
in float v_visible;
flat in float v_exponent;
struct hl_light {
    vec4 le;     // .rgb radiance (area) or intensity (point)
    vec4 sphere; // area: bounding sphere (centre, radius); point: its position
    uvec4 loops; // .x first loop, .y loops, .z 1: a point light
};
layout(std430, binding = 1) readonly buffer HlLights { hl_light u_lights[]; };
layout(std430, binding = 2) readonly buffer HlLoops { ivec4 u_loops[]; };  // .x first point, .y points, .z sign
layout(std430, binding = 3) readonly buffer HlPoints { vec4 u_points[]; }; // .xyz
uniform uint u_light_count;
uniform vec3 u_eye;

const float PI = 3.14159265358979;
const float CORE = 5.0;         // the lobe's core, in widths 1/√n (analytic.c: PHONG_CORE)
const float SKIP_LOG = -12.5;   // −CORE²/2
const float CLIPPED = -1e30;    // loop_phong: a loop it does not integrate (a sum rounds to slightly below 0)
const vec2 GAUSS[4] = vec2[](vec2(0.96028985649753623, 0.10122853629037626), vec2(0.79666647741362674, 0.22238103445337447),
                             vec2(0.52553240991632899, 0.31370664587788729), vec2(0.18343464249564980, 0.36268378337836198));

float log1m(float q) { return q < 1e-3 ? -q * (1.0 + q * (0.5 + q * (1.0 / 3.0))) : log(1.0 - q); } // log(1 − q)
float expm1f(float x) { return abs(x) < 1e-3 ? x * (1.0 + x * (0.5 + x * (1.0 / 6.0))) : exp(x) - 1.0; }
float azimuth(float eps, float tau)
{
    float a = atan(sin(tau), abs(eps) * cos(tau));
    return eps > 0.0 ? a : eps < 0.0 ? -a : 0.0;
}

// One edge ua → ub of the clipped polygon (analytic.c, phong_edge).
void edge(vec3 ua, vec3 ub, vec3 r, vec3 ns, float n, inout float A, inout float B)
{
    vec3 c = cross(ua, ub);
    float sl = length(c);
    if (!(sl > 0.0)) return;
    vec3 m = c / sl;
    float eps = -dot(r, m), R2 = (1.0 - eps) * (1.0 + eps);
    if (0.5 * n * eps * eps > -SKIP_LOG || !(R2 > 0.0) || 0.5 * n * log1m(eps * eps) < SKIP_LOG) {
        float ra = dot(r, ua), rb = dot(r, ub);
        vec3 pa = ua - ra * r, pb = ub - rb * r;
        A -= atan(dot(r, cross(pa, pb)), dot(pa, pb));
        return;
    }
    float R = sqrt(R2), theta = atan(sl, dot(ua, ub)), ns_m = dot(ns, m);
    vec3 f = (r + eps * m) / R, g = cross(m, f);
    float ta = atan(dot(ua, g), max(dot(ua, f), 0.0)), tb = ta + theta;
    float core = CORE / sqrt(n);
    float lo = max(ta, -core), hi = min(tb, core);
    if (!(lo < hi)) {
        A += azimuth(eps, tb) - azimuth(eps, ta);
        return;
    }
    if (ta < lo) A += azimuth(eps, lo) - azimuth(eps, ta);
    if (hi < tb) A += azimuth(eps, tb) - azimuth(eps, hi);
    float cut1 = hi;
    int pieces = 1;
    if (lo < 0.0 && hi > 0.0) {
        cut1 = 0.0;
        pieces = 2;
    }
    float eps2 = eps * eps, a = 0.0, e = 0.0;
    for (int p = 0; p < pieces; p++) {
        float c0 = p == 0 ? lo : cut1, c1 = p == 0 ? cut1 : hi;
        float mid = 0.5 * (c0 + c1), half_ = 0.5 * (c1 - c0);
        for (int i = 0; i < 4; i++)     // the nodes ±GAUSS[i].x
            for (int side = -1; side <= 1; side += 2) {
                float t = mid + half_ * float(side) * GAUSS[i].x, w = GAUSS[i].y * half_;
                float st = sin(t), ct = cos(t);
                float q = st * st + eps2 * ct * ct, c2 = R2 * ct * ct;
                float em = expm1f(0.5 * n * (q < 0.5 ? log1m(q) : log(c2))); // cosⁿθ − 1
                a += w * (q > 0.0 ? -em / q : 0.5 * n);
                e += w * (1.0 + em);
            }
    }
    A += eps * a;
    B += ns_m * e;
}

// ∫ (n+2)/(2π)·cosⁿα·cosθ_x dω over one loop, relative to x: analytic.c's
// samp_polygon_phong for a loop wholly above x's horizon and in the lobe's
// hemisphere. One that crosses either is not clipped here: CLIPPED, and the pixel
// keeps the interpolated value (clipping needs arrays, which llvmpipe keeps in
// memory per pixel: they doubled the pass's cost, docs/renderer.md).
float loop_phong(int first, int count, vec3 x, vec3 ns, vec3 r, float n)
{
    float big = 0.0;
    bool inside = true;
    for (int i = 0; i < count; i++) {
        vec3 p = u_points[first + i].xyz - x, d = abs(p);
        big = max(big, max(d.x, max(d.y, d.z)));
        inside = inside && dot(p, r) >= 0.0 && dot(p, ns) >= 0.0;
    }
    if (!(big > 0.0)) return 0.0;
    // The side test of samp_polygon_G: Newell normal and mean point, scaled.
    float inv = 1.0 / big;
    vec3 nrm = vec3(0.0), mean = vec3(0.0), prev = (u_points[first + count - 1].xyz - x) * inv;
    for (int i = 0; i < count; i++) {
        vec3 cur = (u_points[first + i].xyz - x) * inv;
        nrm += cross(prev, cur);
        mean += cur;
        prev = cur;
    }
    float area2 = length(nrm);
    if (!(area2 > 0.0) || !(-dot(nrm, mean) / (float(count) * area2) > 1e-6)) return 0.0;
    if (!inside) return CLIPPED;
    float A = 0.0, B = 0.0;
    vec3 ua = normalize(u_points[first + count - 1].xyz - x);
    for (int i = 0; i < count; i++) {
        vec3 ub = normalize(u_points[first + i].xyz - x);
        edge(ua, ub, r, ns, n, A, B);
        ua = ub;
    }
    return (dot(ns, r) * A - B) / (2.0 * PI);
}

vec3 highlights(vec3 x, vec3 ns, vec3 wo, float n)
{
    vec3 r = normalize(2.0 * dot(wo, ns) * ns - wo), sum = vec3(0.0);
    float core = SKIP_CORE / sqrt(n); // a light further than this from the lobe's axis is skipped
    for (uint l = 0u; l < u_light_count; ++l) {
        hl_light L = u_lights[l];
        float S = 0.0;
        if (L.loops.z != 0u) { // a point light: its lobe towards the point times G
            vec3 d = L.sphere.xyz - x;
            float r2 = dot(d, d), cx = dot(ns, d);
            if (!(cx > 0.0) || !(r2 > 0.0)) continue;
            vec3 wi = d * inversesqrt(r2), mirror = 2.0 * dot(ns, wi) * ns - wi;
            float ca = dot(mirror, wo);
            if (ca > 0.0) S = (n + 2.0) / (2.0 * PI) * pow(ca, n) * cx * inversesqrt(r2) / r2;
        } else {
            // The lobe's core misses the light's bounding sphere: S is below its
            // tail (3.7e-6 of the lobe's peak), taken as 0 as analytic.c does.
            vec3 d = L.sphere.xyz - x;
            float dist = length(d);
            if (dist > L.sphere.w) {
                float cosr = dot(r, d) / dist, ang = acos(clamp(cosr, -1.0, 1.0));
                if (ang > asin(min(L.sphere.w / dist, 1.0)) + core) continue;
            }
            for (uint k = L.loops.x; k < L.loops.x + L.loops.y; ++k) {
                float Sk = loop_phong(u_loops[k].x, u_loops[k].y, x, ns, r, n);
                if (Sk == CLIPPED) return vec3(CLIPPED); // the interpolated value
                S += float(u_loops[k].z) * Sk;
            }
            S = max(S, 0.0);
        }
        sum += L.le.rgb * S;
    }
    return sum;
}
#endif
void main()
{
#ifdef HIGHLIGHT
    // Only where the lights are wholly visible: a partly hidden light's visible
    // fraction is the one its corners' lobes see, not this pixel's.
    if (v_exponent >= HIGHLIGHT_MIN_N && u_light_count > 0u && v_visible >= MIN_VISIBLE) {
        vec3 ns = normalize(v_normal), wo = normalize(u_eye - v_pos);
        vec3 h = highlights(v_pos, ns, wo, v_exponent);
        if (h.x != CLIPPED) {
            vec3 rest = max(v_value - v_direct, vec3(0.0));
            o_value = vec4(rest + min(v_visible, 1.0) * h, 1.0);
            return;
        }
    }
#endif
    o_value = vec4(v_value, 1.0);
}
