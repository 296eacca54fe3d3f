/* vecmath.h — tiny inline 3-vector helpers (float and double).
 * Header-only on purpose: these are called in inner loops. */
#ifndef LUMESH_VECMATH_H
#define LUMESH_VECMATH_H

#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct lm_vec3 { float x, y, z; } lm_vec3;
typedef struct lm_dvec3 { double x, y, z; } lm_dvec3;

static inline lm_vec3 v3(float x, float y, float z) { lm_vec3 r = {x, y, z}; return r; }
static inline lm_vec3 v3_load(const float *p) { return v3(p[0], p[1], p[2]); }
static inline void v3_store(float *p, lm_vec3 a) { p[0] = a.x; p[1] = a.y; p[2] = a.z; }
static inline lm_vec3 v3_add(lm_vec3 a, lm_vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline lm_vec3 v3_sub(lm_vec3 a, lm_vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline lm_vec3 v3_scale(lm_vec3 a, float s) { return v3(a.x * s, a.y * s, a.z * s); }
static inline float v3_dot(lm_vec3 a, lm_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline lm_vec3 v3_cross(lm_vec3 a, lm_vec3 b) {
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float v3_length(lm_vec3 a) { return sqrtf(v3_dot(a, a)); }
static inline lm_vec3 v3_normalize(lm_vec3 a) {
    float l = v3_length(a);
    return l > 0.0f ? v3_scale(a, 1.0f / l) : v3(0.0f, 0.0f, 0.0f);
}
static inline int v3_isfinite(lm_vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

static inline lm_dvec3 dv3(double x, double y, double z) { lm_dvec3 r = {x, y, z}; return r; }
static inline lm_dvec3 dv3_from(lm_vec3 a) { return dv3(a.x, a.y, a.z); }
static inline lm_dvec3 dv3_load(const float *p) { return dv3(p[0], p[1], p[2]); }
static inline lm_dvec3 dv3_load_d(const double *p) { return dv3(p[0], p[1], p[2]); }
static inline lm_dvec3 dv3_add(lm_dvec3 a, lm_dvec3 b) { return dv3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline lm_dvec3 dv3_sub(lm_dvec3 a, lm_dvec3 b) { return dv3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline lm_dvec3 dv3_scale(lm_dvec3 a, double s) { return dv3(a.x * s, a.y * s, a.z * s); }
static inline double dv3_dot(lm_dvec3 a, lm_dvec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline lm_dvec3 dv3_cross(lm_dvec3 a, lm_dvec3 b) {
    return dv3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double dv3_length(lm_dvec3 a) { return sqrt(dv3_dot(a, a)); }
static inline lm_dvec3 dv3_normalize(lm_dvec3 a) {
    double l = dv3_length(a);
    return l > 0.0 ? dv3_scale(a, 1.0 / l) : dv3(0.0, 0.0, 0.0);
}

#endif
