/* scene_mitsuba_bsdf.c — Mitsuba properties and BSDFs as the scene model's
 * modified Phong material (kd, ks, n).
 *
 * The scene model has one diffuse and one Phong lobe and no textures
 * (docs/scene-model.md), so most of Mitsuba's BSDFs are approximated; each
 * approximation is a note that `lumesh info` lists with the numbers used
 * (docs/scene-format.md, "Mitsuba XML", has the table):
 *   - a microfacet roughness α becomes the Phong exponent n = 2/α² − 2, the
 *     Beckmann–Phong correspondence of Walter et al. 2007 (eq. 30);
 *   - a smooth specular lobe (conductor, dielectric, plastic, coating) becomes
 *     n = SMOOTH_EXPONENT, the sharpest lobe the specular mesh resolves;
 *   - the specular reflectance of a dielectric interface is its Fresnel
 *     reflectance at normal incidence, ((η1 − η2)/(η1 + η2))²; transmission is
 *     not modelled (opaque, as OBJ glass is);
 *   - a conductor's is its normal-incidence reflectance (table below) times
 *     specularReflectance;
 *   - a texture is its mean linear colour; bump and normal maps are ignored.
 */
#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/tonemap.h"
#include "src/image/image.h"
#include "src/scene/scene_mitsuba_internal.h"

enum { MTS_NESTING_MAX = 16 };       /* BSDFs inside BSDFs (twosided(bump(coating(...)))) */
static const float SMOOTH_EXPONENT = 1000.0f;

/* ---- names, values, references ------------------------------------------ */

int mts_name_eq(const char *a, const char *b)
{
    for (;;) {
        while (*a == '_') a++;
        while (*b == '_') b++;
        if (!*a || !*b) return *a == *b;
        if (tolower((unsigned char)*a) != tolower((unsigned char)*b)) return 0;
        a++;
        b++;
    }
}

const char *mts_value(const mts_ctx *c, const mts_node *n, const char *attr)
{
    const char *v = mts_attr(n, attr);
    if (!v || v[0] != '$') return v;
    for (size_t i = 0; i < c->default_count; ++i) {
        const char *name = mts_attr(c->defaults[i], "name");
        if (name && strcmp(name, v + 1) == 0) return mts_attr(c->defaults[i], "value");
    }
    return v;
}

const mts_node *mts_prop(const mts_ctx *c, const mts_node *n, const char *name)
{
    for (const mts_node *ch = n->child; ch; ch = ch->next) {
        const char *nm = mts_value(c, ch, "name");
        if (nm && mts_name_eq(nm, name)) return ch;
    }
    return NULL;
}

static const mts_node *find_id_in(const mts_node *n, const char *id)
{
    for (; n; n = n->next) {
        const char *v = mts_attr(n, "id");
        if (v && strcmp(v, id) == 0 && strcmp(n->tag, "ref") != 0) return n;
        const mts_node *f = find_id_in(n->child, id);
        if (f) return f;
    }
    return NULL;
}

const mts_node *mts_find_id(const mts_ctx *c, const char *id) { return find_id_in(c->root->child, id); }

const mts_node *mts_deref(const mts_ctx *c, const mts_node *n)
{
    if (!n || strcmp(n->tag, "ref") != 0) return n;
    const char *id = mts_value(c, n, "id");
    return id ? mts_find_id(c, id) : NULL;
}

lm_result mts_error(const mts_ctx *c, const mts_node *n, lm_error *err, const char *fmt, ...)
{
    char what[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return lm_fail(err, LM_ERR_BAD_INPUT, "%s:%d: <%s>: %s", c->path, n ? n->line : 0, n ? n->tag : "scene",
                   what);
}

int mts_parse_numbers(const char *s, double *out, int max)
{
    int count = 0;
    for (;;) {
        while (*s == ' ' || *s == ',' || *s == '\t' || *s == '\n' || *s == '\r') s++;
        if (!*s) return count;
        if (count == max) return -1;
        char *end;
        double v = strtod(s, &end);
        if (end == s || !isfinite(v)) return -1;
        out[count++] = v;
        s = end;
    }
}

lm_result mts_get_float(const mts_ctx *c, const mts_node *n, const char *name, double def, double *out,
                        lm_error *err)
{
    *out = def;
    const mts_node *p = mts_prop(c, n, name);
    if (!p) return LM_OK;
    const char *v = mts_value(c, p, "value");
    double d = 0.0;
    if (!v || mts_parse_numbers(v, &d, 1) != 1)
        return mts_error(c, p, err, "'%s' needs value=\"<number>\"", name);
    *out = d;
    return LM_OK;
}

const char *mts_get_string(const mts_ctx *c, const mts_node *n, const char *name, const char *def)
{
    const mts_node *p = mts_prop(c, n, name);
    const char *v = p ? mts_value(c, p, "value") : NULL;
    return v ? v : def;
}

int mts_get_bool(const mts_ctx *c, const mts_node *n, const char *name, int def)
{
    const char *v = mts_get_string(c, n, name, NULL);
    if (!v) return def;
    return strcmp(v, "true") == 0 || strcmp(v, "1") == 0;
}

/* ---- colours -------------------------------------------------------------- */

/* A spectrum given as "λ:v, λ:v, ...": the mean over three bands, blue
 * 400–500 nm, green 500–600 nm, red 600–700 nm, of the piecewise linear curve. */
static int sampled_spectrum(const char *s, float out[3])
{
    double lambda[256], value[256];
    int n = 0;
    while (*s) {
        while (*s == ' ' || *s == ',' || *s == '\t' || *s == '\n' || *s == '\r') s++;
        if (!*s) break;
        if (n == 256) return 0;
        char *end;
        lambda[n] = strtod(s, &end);
        if (end == s || *end != ':') return 0;
        s = end + 1;
        value[n] = strtod(s, &end);
        if (end == s || !isfinite(lambda[n]) || !isfinite(value[n])) return 0;
        if (n > 0 && !(lambda[n] > lambda[n - 1])) return 0;
        s = end;
        n++;
    }
    if (n == 0) return 0;
    for (int band = 0; band < 3; ++band) {
        double lo = 600.0 - 100.0 * band, sum = 0.0; /* out[0] red 600..700, [2] blue 400..500 */
        for (int k = 0; k < 100; ++k) {
            double l = lo + k + 0.5, v;
            if (l <= lambda[0]) {
                v = value[0];
            } else if (l >= lambda[n - 1]) {
                v = value[n - 1];
            } else {
                int j = 1;
                while (lambda[j] < l) j++;
                double t = (l - lambda[j - 1]) / (lambda[j] - lambda[j - 1]);
                v = value[j - 1] + t * (value[j] - value[j - 1]);
            }
            sum += v;
        }
        out[band] = (float)(sum / 100.0);
    }
    return 1;
}

/* "#rrggbb" (sRGB-encoded), or 1 or 3 numbers. srgb: the numbers are encoded too. */
static int parse_rgb(const char *v, int srgb, float out[3])
{
    if (v[0] == '#') {
        unsigned r, g, b;
        if (strlen(v) != 7 || sscanf(v + 1, "%2x%2x%2x", &r, &g, &b) != 3) return 0;
        unsigned in[3] = {r, g, b};
        for (int k = 0; k < 3; ++k) out[k] = tm_srgb_decode((float)in[k] / 255.0f);
        return 1;
    }
    double d[3];
    int n = mts_parse_numbers(v, d, 3);
    if (n != 1 && n != 3) return 0;
    for (int k = 0; k < 3; ++k) {
        float x = (float)d[n == 1 ? 0 : k];
        out[k] = srgb ? tm_srgb_decode(x) : x;
    }
    return 1;
}

/* The mean linear colour of an image file (in a child process, as third-party
 * readers are run: scene_isolate). 8-bit formats are sRGB-encoded unless the
 * texture gives a gamma (Mitsuba's rule); EXR, HDR and PFM are linear. */
typedef struct texture_args {
    const char *path;
    double gamma;             /* 0: by format; -1: sRGB; > 0: power */
} texture_args;

static lm_result read_texture_mean(scene_builder *b, void *user, int32_t unused, lm_error *err)
{
    (void)unused;
    const texture_args *a = user;
    img_image img;
    memset(&img, 0, sizeof img);
    lm_result r = img_read(a->path, &img, err);
    if (r != LM_OK) return r;
    char ext[16];
    lm_path_ext(a->path, ext, sizeof ext);
    double gamma = a->gamma;
    if (gamma == 0.0)
        gamma = (strcmp(ext, "exr") == 0 || strcmp(ext, "hdr") == 0 || strcmp(ext, "pfm") == 0) ? 1.0 : -1.0;
    double sum[3] = {0, 0, 0};
    size_t count = (size_t)img.width * (size_t)img.height;
    for (size_t i = 0; i < count; ++i)
        for (int k = 0; k < 3; ++k) {
            float v = img.pixels[i * (size_t)img.channels + (size_t)(img.channels >= 3 ? k : 0)];
            if (!isfinite(v) || v < 0.0f) v = 0.0f;
            sum[k] += gamma < 0.0 ? tm_srgb_decode(fminf(v, 1.0f)) : pow(v, gamma);
        }
    scene_material m = scene_material_default("texture");
    for (int k = 0; k < 3; ++k) m.kd[k] = count ? (float)(sum[k] / (double)count) : 0.0f;
    img_free(&img);
    uint32_t index;
    return scene_builder_add_material(b, &m, &index, err);
}

static lm_result bitmap_mean(mts_ctx *c, const mts_node *tex, float out[3], lm_error *err)
{
    const char *file = mts_get_string(c, tex, "filename", NULL);
    if (!file || !file[0]) return mts_error(c, tex, err, "a bitmap texture needs a filename");
    char full[SCENE_PATH_MAX];
    if (!lm_path_join(c->dir, file, full, sizeof full)) return mts_error(c, tex, err, "file path too long");
    for (size_t i = 0; i < c->texture_count; ++i)
        if (strcmp(c->textures[i].path, full) == 0) {
            memcpy(out, c->textures[i].mean, 3 * sizeof(float));
            return LM_OK;
        }
    texture_args args = {full, 0.0};
    lm_result r = mts_get_float(c, tex, "gamma", 0.0, &args.gamma, err);
    if (r != LM_OK) return r;
    if (args.gamma < 0.0) args.gamma = -1.0;
    scene_builder one;
    memset(&one, 0, sizeof one);
    one.source = full;
    r = scene_isolate(&one, full, -1, read_texture_mean, &args, err);
    if (r == LM_OK && one.mat_count == 1) {
        memcpy(out, one.mats[0].kd, 3 * sizeof(float));
    } else if (r == LM_OK) {
        r = mts_error(c, tex, err, "%s: the image reader returned nothing", full);
    } else if (err) { /* say which texture led there */
        char inner[sizeof err->msg];
        memcpy(inner, err->msg, sizeof inner);
        r = mts_error(c, tex, err, "texture: %s", inner);
    }
    scene_builder_free(&one);
    if (r != LM_OK) return r;
    if (LM_GROW(c->textures, c->texture_cap, c->texture_count + 1)) {
        lm_strlcpy(c->textures[c->texture_count].path, full, sizeof c->textures[0].path);
        memcpy(c->textures[c->texture_count].mean, out, 3 * sizeof(float));
        c->texture_count++;
    }
    return LM_OK;
}

static lm_result texture_mean(mts_ctx *c, const mts_node *tex, int depth, float out[3], lm_error *err);

/* A colour-valued element: a spectrum, rgb or srgb element, or a texture. */
static lm_result color_of(mts_ctx *c, const mts_node *p, int depth, float out[3], int *textured, lm_error *err)
{
    const char *name = mts_value(c, p, "name");
    if (!name) name = p->tag;
    if (strcmp(p->tag, "texture") == 0) {
        if (textured) *textured = 1;
        return texture_mean(c, p, depth, out, err);
    }
    const char *v = mts_value(c, p, "value");
    if (strcmp(p->tag, "rgb") == 0 || strcmp(p->tag, "srgb") == 0 || strcmp(p->tag, "color") == 0) {
        if (!v || !parse_rgb(v, strcmp(p->tag, "srgb") == 0, out))
            return mts_error(c, p, err, "'%s': expected value=\"r g b\", one number or \"#rrggbb\"", name);
        return LM_OK;
    }
    if (strcmp(p->tag, "spectrum") == 0) {
        if (!v) return mts_error(c, p, err, "'%s': a spectrum from a file is not read; give value=", name);
        if (parse_rgb(v, 0, out)) return LM_OK; /* one value, or three (Mitsuba's RGB mode) */
        if (sampled_spectrum(v, out)) {
            scene_builder_note(c->b, "%s:%d: spectrum '%s' averaged over 600-700, 500-600 and 400-500 nm "
                                     "as red, green and blue",
                               c->path, p->line, name);
            return LM_OK;
        }
        return mts_error(c, p, err, "'%s': expected one number, three, or wavelength:value pairs", name);
    }
    if (strcmp(p->tag, "float") == 0 || strcmp(p->tag, "integer") == 0) {
        double d = 0.0;
        if (!v || mts_parse_numbers(v, &d, 1) != 1) return mts_error(c, p, err, "'%s': expected a number", name);
        out[0] = out[1] = out[2] = (float)d;
        return LM_OK;
    }
    if (strcmp(p->tag, "blackbody") == 0)
        return mts_error(c, p, err, "'%s': blackbody spectra are not supported; give an rgb value", name);
    return mts_error(c, p, err, "'%s': expected a colour (spectrum, rgb, srgb or texture)", name);
}

static lm_result texture_mean(mts_ctx *c, const mts_node *tex, int depth, float out[3], lm_error *err)
{
    if (depth > MTS_NESTING_MAX) return mts_error(c, tex, err, "textures nested more than %d deep", MTS_NESTING_MAX);
    const char *type = mts_value(c, tex, "type");
    if (!type) return mts_error(c, tex, err, "a texture needs a type");
    lm_result r;
    if (strcmp(type, "bitmap") == 0) {
        if ((r = bitmap_mean(c, tex, out, err)) != LM_OK) return r;
        scene_builder_note(c->b, "%s:%d: bitmap texture '%s' approximated by its mean colour %.3g %.3g %.3g",
                           c->path, tex->line, mts_get_string(c, tex, "filename", ""), out[0], out[1], out[2]);
        return LM_OK;
    }
    if (strcmp(type, "checkerboard") == 0) {
        static const float c0[3] = {0.4f, 0.4f, 0.4f}, c1[3] = {0.2f, 0.2f, 0.2f};
        float a[3], b[3];
        if ((r = mts_get_color(c, tex, "color0", c0, a, NULL, err)) != LM_OK) return r;
        if ((r = mts_get_color(c, tex, "color1", c1, b, NULL, err)) != LM_OK) return r;
        for (int k = 0; k < 3; ++k) out[k] = 0.5f * (a[k] + b[k]);
        return LM_OK;
    }
    if (strcmp(type, "scale") == 0) {
        double s;
        if ((r = mts_get_float(c, tex, "scale", 1.0, &s, err)) != LM_OK) return r;
        const mts_node *inner = NULL;
        for (const mts_node *ch = tex->child; ch && !inner; ch = ch->next)
            if (strcmp(ch->tag, "texture") == 0 || strcmp(ch->tag, "ref") == 0) inner = mts_deref(c, ch);
        if (!inner) return mts_error(c, tex, err, "a scale texture needs a texture inside");
        if ((r = color_of(c, inner, depth + 1, out, NULL, err)) != LM_OK) return r;
        for (int k = 0; k < 3; ++k) out[k] *= (float)s;
        return LM_OK;
    }
    scene_builder_note(c->b, "%s:%d: texture type '%s' is not read: grey 0.5 used", c->path, tex->line, type);
    out[0] = out[1] = out[2] = 0.5f;
    return LM_OK;
}

lm_result mts_get_color(mts_ctx *c, const mts_node *n, const char *name, const float def[3], float out[3],
                        int *textured, lm_error *err)
{
    if (textured) *textured = 0;
    memcpy(out, def, 3 * sizeof(float));
    const mts_node *p = mts_prop(c, n, name);
    if (!p) return LM_OK;
    const mts_node *target = mts_deref(c, p);
    if (!target) return mts_error(c, p, err, "'%s' refers to an id that no element has", name);
    return color_of(c, target, 0, out, textured, err);
}

/* ---- BSDFs ---------------------------------------------------------------- */

typedef struct phong {
    float kd[3], ks[3], n;
    char note[320];           /* what was approximated, "" when exact */
} phong;

static void add_note(phong *p, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void add_note(phong *p, const char *fmt, ...)
{
    size_t used = strlen(p->note);
    if (used + 3 >= sizeof p->note) return;
    if (used) {
        strcpy(p->note + used, "; ");
        used += 2;
    }
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(p->note + used, sizeof p->note - used, fmt, ap);
    va_end(ap);
}

/* Index of refraction: a number or one of Mitsuba's named materials. */
static lm_result get_ior(mts_ctx *c, const mts_node *bsdf, const char *name, double def, double *out, lm_error *err)
{
    static const struct { const char *name; double ior; } table[] = {
        {"vacuum", 1.0},         {"helium", 1.000036},    {"hydrogen", 1.000132},
        {"air", 1.000277},       {"carbon dioxide", 1.00045}, {"water", 1.3330},
        {"acetone", 1.36},       {"ethanol", 1.361},      {"carbon tetrachloride", 1.461},
        {"glycerol", 1.4729},    {"benzene", 1.501},      {"silicone oil", 1.52045},
        {"bromine", 1.661},      {"water ice", 1.31},     {"fused quartz", 1.458},
        {"pyrex", 1.470},        {"acrylic glass", 1.49}, {"polypropylene", 1.49},
        {"bk7", 1.5046},         {"sodium chloride", 1.544}, {"amber", 1.55},
        {"pet", 1.5750},         {"diamond", 2.419},
    };
    *out = def;
    const mts_node *p = mts_prop(c, bsdf, name);
    if (!p) return LM_OK;
    const char *v = mts_value(c, p, "value");
    if (v && strcmp(p->tag, "string") == 0) {
        for (size_t i = 0; i < sizeof table / sizeof table[0]; ++i)
            if (strcmp(table[i].name, v) == 0) {
                *out = table[i].ior;
                return LM_OK;
            }
        return mts_error(c, p, err, "'%s': unknown material '%s' (give the index as a float)", name, v);
    }
    double d = 0.0;
    if (!v || mts_parse_numbers(v, &d, 1) != 1 || !(d > 0.0))
        return mts_error(c, p, err, "'%s': expected a positive index of refraction", name);
    *out = d;
    return LM_OK;
}

/* Fresnel reflectance at normal incidence between indices a and b. */
static float fresnel0(double a, double b)
{
    double r = (a - b) / (a + b);
    return (float)(r * r);
}

/* Phong exponent for a microfacet roughness (Walter et al. 2007, eq. 30). */
static lm_result roughness_exponent(mts_ctx *c, const mts_node *bsdf, phong *p, lm_error *err)
{
    double alpha, au, av;
    lm_result r;
    if ((r = mts_get_float(c, bsdf, "alpha", 0.1, &alpha, err)) != LM_OK) return r;
    if ((r = mts_get_float(c, bsdf, "alphaU", alpha, &au, err)) != LM_OK) return r;
    if ((r = mts_get_float(c, bsdf, "alphaV", alpha, &av, err)) != LM_OK) return r;
    if (au != av) add_note(p, "anisotropic roughness %g x %g taken as its mean", au, av);
    alpha = 0.5 * (au + av);
    if (!(alpha > 0.0)) alpha = 1e-3;
    double n = 2.0 / (alpha * alpha) - 2.0;
    p->n = (float)fmin(fmax(n, 0.0), SMOOTH_EXPONENT);
    add_note(p, "roughness %g as Phong n %g", alpha, p->n);
    return LM_OK;
}

/* Normal-incidence reflectance of Mitsuba's conductor presets, linear RGB
 * (from their measured n, k; the usual table of Hoffman, SIGGRAPH 2010 course). */
static int conductor_f0(const char *name, float out[3])
{
    static const struct { const char *name; float f0[3]; } table[] = {
        {"Ag", {0.972f, 0.960f, 0.915f}}, {"Al", {0.913f, 0.922f, 0.924f}},
        {"Au", {1.000f, 0.766f, 0.336f}}, {"Cu", {0.955f, 0.638f, 0.538f}},
        {"Cr", {0.549f, 0.556f, 0.554f}}, {"Fe", {0.562f, 0.565f, 0.578f}},
        {"Ni", {0.660f, 0.609f, 0.526f}}, {"Pt", {0.673f, 0.637f, 0.585f}},
        {"Ti", {0.542f, 0.497f, 0.449f}}, {"none", {1.0f, 1.0f, 1.0f}},
    };
    for (size_t i = 0; i < sizeof table / sizeof table[0]; ++i)
        if (strcmp(table[i].name, name) == 0) {
            memcpy(out, table[i].f0, sizeof table[i].f0);
            return 1;
        }
    return 0;
}

static lm_result translate(mts_ctx *c, const mts_node *bsdf, int depth, phong *p, lm_error *err);

/* The BSDF nested in bsdf (an element or a ref), or NULL. */
static const mts_node *nested_bsdf(const mts_ctx *c, const mts_node *bsdf, const mts_node *after)
{
    for (const mts_node *ch = after ? after->next : bsdf->child; ch; ch = ch->next) {
        const mts_node *t = mts_deref(c, ch);
        if (t && strcmp(t->tag, "bsdf") == 0) return ch;
    }
    return NULL;
}

static lm_result translate_nested(mts_ctx *c, const mts_node *bsdf, int depth, phong *p, lm_error *err)
{
    const mts_node *inner = nested_bsdf(c, bsdf, NULL);
    if (!inner) return mts_error(c, bsdf, err, "'%s' needs a BSDF inside", mts_value(c, bsdf, "type"));
    return translate(c, mts_deref(c, inner), depth + 1, p, err);
}

/* blendbsdf (weight of the second) and mixturebsdf (weights): lobes mixed linearly. */
static lm_result translate_mix(mts_ctx *c, const mts_node *bsdf, const char *type, int depth, phong *p, lm_error *err)
{
    double w[8];
    int count;
    lm_result r;
    if (strcmp(type, "blendbsdf") == 0) {
        float wc[3];
        static const float half[3] = {0.5f, 0.5f, 0.5f};
        int textured;
        if ((r = mts_get_color(c, bsdf, "weight", half, wc, &textured, err)) != LM_OK) return r;
        w[1] = (wc[0] + wc[1] + wc[2]) / 3.0;
        w[0] = 1.0 - w[1];
        count = 2;
    } else {
        const char *ws = mts_get_string(c, bsdf, "weights", NULL);
        count = ws ? mts_parse_numbers(ws, w, 8) : -1;
        if (count < 1) return mts_error(c, bsdf, err, "mixturebsdf needs weights=\"w1, w2, ...\" (at most 8)");
    }
    memset(p->kd, 0, sizeof p->kd);
    memset(p->ks, 0, sizeof p->ks);
    float best_ks = -1.0f;
    const mts_node *ch = NULL;
    for (int i = 0; i < count; ++i) {
        ch = nested_bsdf(c, bsdf, ch);
        if (!ch) return mts_error(c, bsdf, err, "%s has fewer BSDFs than weights", type);
        phong q;
        memset(&q, 0, sizeof q);
        if ((r = translate(c, mts_deref(c, ch), depth + 1, &q, err)) != LM_OK) return r;
        for (int k = 0; k < 3; ++k) {
            p->kd[k] += (float)w[i] * q.kd[k];
            p->ks[k] += (float)w[i] * q.ks[k];
        }
        float ks = q.ks[0] + q.ks[1] + q.ks[2];
        if (ks > best_ks) {
            best_ks = ks;
            p->n = q.n;
        }
        if (q.note[0]) add_note(p, "%s", q.note);
    }
    add_note(p, "%s mixed linearly (one Phong lobe, n of the strongest)", type);
    return LM_OK;
}

static lm_result translate(mts_ctx *c, const mts_node *bsdf, int depth, phong *p, lm_error *err)
{
    if (!bsdf) return mts_error(c, NULL, err, "a BSDF reference names no element");
    if (depth > MTS_NESTING_MAX) return mts_error(c, bsdf, err, "BSDFs nested more than %d deep", MTS_NESTING_MAX);
    const char *type = mts_value(c, bsdf, "type");
    if (!type) return mts_error(c, bsdf, err, "a bsdf needs a type");
    static const float half[3] = {0.5f, 0.5f, 0.5f}, one[3] = {1, 1, 1}, phong_ks[3] = {0.2f, 0.2f, 0.2f};
    lm_result r;
    int textured = 0;
    if (strcmp(type, "diffuse") == 0 || strcmp(type, "roughdiffuse") == 0) {
        if ((r = mts_get_color(c, bsdf, "reflectance", half, p->kd, &textured, err)) != LM_OK) return r;
        if (strcmp(type, "roughdiffuse") == 0) add_note(p, "roughdiffuse as Lambertian");
        return LM_OK;
    }
    if (strcmp(type, "phong") == 0) { /* Mitsuba's phong is the modified Phong model itself */
        double e;
        if ((r = mts_get_color(c, bsdf, "diffuseReflectance", half, p->kd, &textured, err)) != LM_OK) return r;
        if ((r = mts_get_color(c, bsdf, "specularReflectance", phong_ks, p->ks, &textured, err)) != LM_OK) return r;
        if ((r = mts_get_float(c, bsdf, "exponent", 30.0, &e, err)) != LM_OK) return r;
        p->n = (float)e;
        return LM_OK;
    }
    if (strcmp(type, "plastic") == 0 || strcmp(type, "roughplastic") == 0) {
        double in, ext;
        float spec[3];
        if ((r = mts_get_color(c, bsdf, "diffuseReflectance", half, p->kd, &textured, err)) != LM_OK) return r;
        if ((r = mts_get_color(c, bsdf, "specularReflectance", one, spec, &textured, err)) != LM_OK) return r;
        if ((r = get_ior(c, bsdf, "intIOR", 1.49, &in, err)) != LM_OK) return r;
        if ((r = get_ior(c, bsdf, "extIOR", 1.000277, &ext, err)) != LM_OK) return r;
        float f0 = fresnel0(in, ext);
        for (int k = 0; k < 3; ++k) p->ks[k] = f0 * spec[k];
        add_note(p, "%s: specular = Fresnel at normal incidence %.3g", type, f0);
        if (type[0] == 'r') return roughness_exponent(c, bsdf, p, err);
        p->n = SMOOTH_EXPONENT;
        return LM_OK;
    }
    if (strcmp(type, "conductor") == 0 || strcmp(type, "roughconductor") == 0) {
        float spec[3], f0[3];
        if ((r = mts_get_color(c, bsdf, "specularReflectance", one, spec, &textured, err)) != LM_OK) return r;
        const char *metal = mts_get_string(c, bsdf, "material", "Cu");
        if (mts_prop(c, bsdf, "eta") || mts_prop(c, bsdf, "k")) {
            f0[0] = f0[1] = f0[2] = 0.9f;
            add_note(p, "conductor eta/k not read: reflectance 0.9");
        } else if (!conductor_f0(metal, f0)) {
            f0[0] = f0[1] = f0[2] = 0.9f;
            add_note(p, "conductor '%s' not in lumesh's table: reflectance 0.9", metal);
        }
        memset(p->kd, 0, sizeof p->kd);
        for (int k = 0; k < 3; ++k) p->ks[k] = f0[k] * spec[k];
        add_note(p, "%s %s: specular %.3g %.3g %.3g", type, metal, p->ks[0], p->ks[1], p->ks[2]);
        if (type[0] == 'r') return roughness_exponent(c, bsdf, p, err);
        p->n = SMOOTH_EXPONENT;
        return LM_OK;
    }
    if (strcmp(type, "dielectric") == 0 || strcmp(type, "roughdielectric") == 0 ||
        strcmp(type, "thindielectric") == 0) {
        double in, ext;
        if ((r = get_ior(c, bsdf, "intIOR", 1.5046, &in, err)) != LM_OK) return r;
        if ((r = get_ior(c, bsdf, "extIOR", 1.000277, &ext, err)) != LM_OK) return r;
        memset(p->kd, 0, sizeof p->kd);
        p->ks[0] = p->ks[1] = p->ks[2] = fresnel0(in, ext);
        add_note(p, "%s: opaque, no transmission; specular = Fresnel at normal incidence %.3g", type, p->ks[0]);
        if (type[0] == 'r') return roughness_exponent(c, bsdf, p, err);
        p->n = SMOOTH_EXPONENT;
        return LM_OK;
    }
    if (strcmp(type, "coating") == 0 || strcmp(type, "roughcoating") == 0) {
        double in, ext;
        if ((r = translate_nested(c, bsdf, depth, p, err)) != LM_OK) return r;
        if ((r = get_ior(c, bsdf, "intIOR", 1.5046, &in, err)) != LM_OK) return r;
        if ((r = get_ior(c, bsdf, "extIOR", 1.000277, &ext, err)) != LM_OK) return r;
        float f0 = fresnel0(in, ext);
        int had_lobe = p->ks[0] + p->ks[1] + p->ks[2] > 0.0f;
        for (int k = 0; k < 3; ++k) p->ks[k] += f0;
        add_note(p, "%s: adds specular %.3g (Fresnel at normal incidence)", type, f0);
        if (had_lobe) return LM_OK; /* one lobe: the base's exponent stays */
        if (type[0] == 'r') return roughness_exponent(c, bsdf, p, err);
        p->n = SMOOTH_EXPONENT;
        return LM_OK;
    }
    if (strcmp(type, "twosided") == 0) return translate_nested(c, bsdf, depth, p, err);
    if (strcmp(type, "bumpmap") == 0 || strcmp(type, "bump") == 0 || strcmp(type, "normalmap") == 0) {
        if ((r = translate_nested(c, bsdf, depth, p, err)) != LM_OK) return r;
        add_note(p, "%s ignored", type);
        return LM_OK;
    }
    if (strcmp(type, "mask") == 0) {
        if ((r = translate_nested(c, bsdf, depth, p, err)) != LM_OK) return r;
        add_note(p, "mask (opacity) ignored: opaque");
        return LM_OK;
    }
    if (strcmp(type, "blendbsdf") == 0 || strcmp(type, "mixturebsdf") == 0)
        return translate_mix(c, bsdf, type, depth, p, err);
    if (strcmp(type, "null") == 0) {
        add_note(p, "null BSDF: black (lumesh has no invisible surfaces)");
        return LM_OK;
    }
    /* Anything else: its diffuse part if it names one, Mitsuba's grey otherwise. */
    if ((r = mts_get_color(c, bsdf, "reflectance", half, p->kd, &textured, err)) != LM_OK) return r;
    if (!mts_prop(c, bsdf, "reflectance") &&
        (r = mts_get_color(c, bsdf, "diffuseReflectance", half, p->kd, &textured, err)) != LM_OK)
        return r;
    add_note(p, "BSDF type '%s' not modelled: diffuse %.3g %.3g %.3g", type, p->kd[0], p->kd[1], p->kd[2]);
    return LM_OK;
}

/* The builder material already made for a BSDF element (NULL: the default one). */
static int recall(const mts_ctx *c, const mts_node *bsdf, uint32_t *out_index)
{
    for (size_t i = 0; i < c->material_count; ++i)
        if (c->materials[i].bsdf == bsdf) {
            *out_index = c->materials[i].index;
            return 1;
        }
    return 0;
}

static lm_result remember(mts_ctx *c, const mts_node *bsdf, uint32_t index, lm_error *err)
{
    if (!LM_GROW(c->materials, c->material_cap, c->material_count + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory (materials)", c->path);
    c->materials[c->material_count].bsdf = bsdf;
    c->materials[c->material_count].index = index;
    c->material_count++;
    return LM_OK;
}

lm_result mts_material(mts_ctx *c, const mts_node *bsdf, uint32_t *out_index, lm_error *err)
{
    if (recall(c, bsdf, out_index)) return LM_OK;
    phong p;
    memset(&p, 0, sizeof p);
    p.n = 1.0f;
    lm_result r = translate(c, bsdf, 0, &p, err);
    if (r != LM_OK) return r;
    const char *id = mts_attr(bsdf, "id");
    char name[SCENE_NAME_MAX];
    if (id)
        lm_strlcpy(name, id, sizeof name);
    else
        snprintf(name, sizeof name, "bsdf@%d", bsdf->line);
    scene_material m = scene_material_default(name);
    memcpy(m.kd, p.kd, sizeof m.kd);
    memcpy(m.ks, p.ks, sizeof m.ks);
    m.n = p.n;
    if (p.note[0]) {
        m.notes |= SCENE_MATNOTE_APPROXIMATED;
        scene_builder_note(c->b, "material '%s' (%s:%d): %s: kd %.3g %.3g %.3g, ks %.3g %.3g %.3g, n %g", name,
                           c->path, bsdf->line, p.note, m.kd[0], m.kd[1], m.kd[2], m.ks[0], m.ks[1], m.ks[2], m.n);
    }
    if ((r = scene_builder_add_material(c->b, &m, out_index, err)) != LM_OK) return r;
    return remember(c, bsdf, *out_index, err);
}

lm_result mts_default_material(mts_ctx *c, uint32_t *out_index, lm_error *err)
{
    if (recall(c, NULL, out_index)) return LM_OK;
    scene_material m = scene_material_default("mitsuba-default");
    m.kd[0] = m.kd[1] = m.kd[2] = 0.5f;
    lm_result r = scene_builder_add_material(c->b, &m, out_index, err);
    return r == LM_OK ? remember(c, NULL, *out_index, err) : r;
}
