/* rend_debug_test — the debug overlays (rend_debug.h; the paper's Fig. 4b/4c) and
 * the worker's debug publication (cache_worker_desc.publish_debug):
 *   synthetic, no GL: a grid of leaves on one scene triangle, half of the ID image
 *   showing another triangle in front:
 *     - every wire pixel has the leaves' triangle in its 3×3 neighbourhood, none lies
 *       in the hidden half, and the hidden half would have had wires;
 *     - fan diagonals (CACHE_CORNER_LEAF_EDGE clear) are not drawn;
 *     - points drawn + hidden = distinct sampled vertex ids; unsampled ones never;
 *     - rend_debug_project puts the target at the image centre; bad arguments fail;
 *   GL (exit 77 without a context): a plane under a quad light with a blocker,
 *   refined by the worker with the ID pass's pixel counts:
 *     - the light mesh is published with V in [0, 1]; without publish_debug
 *       nothing extra is published and the direct mesh is the same, bit for bit;
 *     - distinct sampled corner ids = the mesh's vertices_sampled, for the light
 *       and direct meshes, and = points drawn + hidden;
 *     - every fan diagonal has its reversed twin in the same scene triangle;
 *     - plane leaves behind the blocker are not drawn (but would be without it);
 *     - light leaves per pixel: penumbra against fully lit, measured and printed;
 *     - rend_debug_write_images writes the expected files.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "mesh/cache/cache_worker.h"
#include "src/gpu/gl_context.h"
#include "src/render/rend_debug.h"
#include "src/render/rend_id.h"
#include "tests/test_util.h"

/* Pixels of out that differ from the dimmed background (the overlay's pixels). */
static uint8_t *overlay_mask(const rend_debug_desc *d, const uint8_t *out)
{
    const rend_debug_desc dd = rend_debug_defaults(d);
    size_t n = (size_t)d->width * (size_t)d->height;
    uint8_t *m = calloc(n, 1);
    for (size_t i = 0; m && i < n; ++i)
        for (int k = 0; k < 3; ++k) {
            float bg = d->background ? dd.dim * (float)d->background[3 * i + (size_t)k] : 0.0f;
            if (out[3 * i + (size_t)k] != (uint8_t)(bg + 0.5f)) m[i] = 1;
        }
    return m;
}

/* Non-zero when a pixel of the 3×3 neighbourhood shows a triangle t < nwant with want[t]. */
static int near_id(const rend_debug_desc *d, const uint32_t *ids, int x, int y, const uint8_t *want, uint32_t nwant)
{
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= d->width || yy >= d->height) continue;
            uint32_t id = ids[(size_t)yy * (size_t)d->width + (size_t)xx];
            if (id && id <= nwant && want[id - 1]) return 1;
        }
    return 0;
}

/* Distinct vertex ids among the corners flagged sampled. */
static uint32_t distinct_sampled(const cache_snapshot_mesh *m)
{
    uint32_t maxid = 0;
    for (size_t i = 0; i < 3 * (size_t)m->triangle_count; ++i)
        if (m->corners[i].vertex > maxid) maxid = m->corners[i].vertex;
    uint8_t *seen = calloc((size_t)maxid + 1, 1);
    uint32_t n = 0;
    for (size_t i = 0; seen && i < 3 * (size_t)m->triangle_count; ++i)
        if ((m->corners[i].flags & CACHE_CORNER_SAMPLED) && !seen[m->corners[i].vertex]) {
            seen[m->corners[i].vertex] = 1;
            n++;
        }
    free(seen);
    return n;
}

/* ---- synthetic -------------------------------------------------------------------------- */

enum { GN = 17 }; /* grid vertices per side, over [-4, 4]² at z = 0 */

static void synthetic(void)
{
    const int W = 64, H = 64;
    scene_camera cam = {.position = {0, 0, 5}, .target = {0, 0, 0}, .up = {0, 1, 0}, .fov_y_deg = 60};
    uint32_t *ids = malloc((size_t)W * H * sizeof *ids);
    uint8_t *bg = malloc((size_t)W * H * 3), *out = malloc((size_t)W * H * 3);
    /* Left half: scene triangle 3 (the leaves'); right half: triangle 9 in front. */
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) ids[y * W + x] = x < W / 2 ? 4 : 10;
    memset(bg, 200, (size_t)W * H * 3);
    const uint32_t ntri = 2 * (GN - 1) * (GN - 1);
    cache_snapshot_vertex *v = calloc(3 * (size_t)ntri, sizeof *v);
    cache_snapshot_corner *c = calloc(3 * (size_t)ntri, sizeof *c);
    uint32_t *tri = calloc(ntri, sizeof *tri), *index = calloc(3 * (size_t)ntri, sizeof *index);
    for (uint32_t i = 0; i < 3 * ntri; ++i) index[i] = i; /* each corner its own vertex */
    /* Each cell: two triangles (a, b, d) and (b, e, d) sharing the diagonal b-d,
     * which is a fan diagonal (flag clear). Vertices with odd id are unsampled. */
    uint32_t t = 0;
    for (int j = 0; j + 1 < GN; ++j)
        for (int i = 0; i + 1 < GN; ++i) {
            const uint32_t a = (uint32_t)(j * GN + i), b = a + 1, d = a + GN, e = d + 1;
            const uint32_t vs[2][3] = {{a, b, d}, {b, e, d}};
            for (int h = 0; h < 2; ++h, ++t) {
                tri[t] = 3;
                for (int k = 0; k < 3; ++k) {
                    uint32_t id = vs[h][k];
                    cache_snapshot_vertex *p = &v[3 * t + (uint32_t)k];
                    p->position[0] = -4.0f + 0.5f * (float)(id % GN);
                    p->position[1] = -4.0f + 0.5f * (float)(id / GN);
                    c[3 * t + (uint32_t)k].vertex = id;
                    c[3 * t + (uint32_t)k].flags = (id % 2 ? 0 : CACHE_CORNER_SAMPLED) | CACHE_CORNER_LEAF_EDGE;
                }
            }
            c[3 * (t - 2) + 1].flags &= ~(uint32_t)CACHE_CORNER_LEAF_EDGE; /* b -> d */
            c[3 * (t - 1) + 2].flags &= ~(uint32_t)CACHE_CORNER_LEAF_EDGE; /* d -> b */
        }
    cache_snapshot_mesh m = {.vertices = v, .index = index, .tri = tri, .corners = c, .triangle_count = ntri,
                             .vertex_count = 3 * ntri};
    rend_debug_desc d = {.camera = &cam, .width = W, .height = H, .ids = ids, .background = bg};
    lm_error err;
    rend_debug_counts n;

    double px, py;
    CHECK(rend_debug_project(&d, (const float[3]){0, 0, 0}, &px, &py) == 1);
    CHECK_NEAR(px, 32.0, 1e-4);
    CHECK_NEAR(py, 32.0, 1e-4);
    CHECK(rend_debug_project(&d, (const float[3]){0, 1, 0}, &px, &py) == 1 && py < 32.0); /* up is up */
    CHECK(rend_debug_project(&d, (const float[3]){0, 0, 9}, &px, &py) == 0);             /* behind the eye */

    uint8_t want[16] = {0};
    want[3] = 1;
    CHECK(rend_debug_leaves(&d, &m, out, &n, &err) == LM_OK);
    uint8_t *mask = overlay_mask(&d, out);
    uint64_t left = 0, right = 0, bad = 0;
    for (int y = 0; mask && y < H; ++y)
        for (int x = 0; x < W; ++x) {
            if (!mask[y * W + x]) continue;
            if (!near_id(&d, ids, x, y, want, 16)) bad++;
            if (x <= W / 2) left++;
            else right++;
        }
    CHECK_MSG(bad == 0 && right == 0 && left > 200, "wire pixels: %llu on the visible half, %llu hidden, %llu with no "
              "leaf triangle near", (unsigned long long)left, (unsigned long long)right, (unsigned long long)bad);
    CHECK(n.wire_pixels == left + right);
    /* Distinct leaf-boundary segments: horizontal and vertical grid edges. */
    CHECK(n.segments == 2u * GN * (GN - 1));
    CHECK(n.segments_drawn > 0 && n.segments_drawn < n.segments);
    /* Diagonals: the pixel on a cell's b-d diagonal halfway is not drawn. Cell with a
     * at (-2, -2) (left half): b = (-1.5, -2), d = (-2, -1.5), middle (-1.75, -1.75). */
    CHECK(rend_debug_project(&d, (const float[3]){-1.75f, -1.75f, 0}, &px, &py) == 1);
    CHECK(mask && !mask[(int)py * W + (int)px]);
    CHECK(rend_debug_project(&d, (const float[3]){-1.75f, -2.0f, 0}, &px, &py) == 1); /* on edge a-b */
    CHECK(mask && mask[(int)py * W + (int)px]);
    free(mask);
    /* Without the occluder the right half gets wires too: the test above is not vacuous. */
    for (int i = 0; i < W * H; ++i) ids[i] = 4;
    rend_debug_counts all;
    CHECK(rend_debug_leaves(&d, &m, out, &all, &err) == LM_OK);
    CHECK(all.wire_pixels > n.wire_pixels + 200);
    CHECK(all.segments_drawn > n.segments_drawn);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) ids[y * W + x] = x < W / 2 ? 4 : 10;

    /* Samples: even ids (each once, whatever the corners sharing it). */
    CHECK(rend_debug_samples(&d, &m, out, &n, &err) == LM_OK);
    CHECK(n.points_drawn + n.points_hidden == distinct_sampled(&m));
    CHECK(distinct_sampled(&m) == (GN * GN + 1) / 2);
    CHECK(n.points_drawn > 0 && n.points_hidden > 0);
    mask = overlay_mask(&d, out);
    uint32_t unsampled_lit = 0, sampled_visible_lit = 0, sampled_visible = 0;
    for (uint32_t id = 0; mask && id < GN * GN; ++id) {
        float p[3] = {-4.0f + 0.5f * (float)(id % GN), -4.0f + 0.5f * (float)(id / GN), 0};
        if (!rend_debug_project(&d, p, &px, &py) || px < 1 || py < 1 || px >= W - 1 || py >= H - 1) continue;
        int on = mask[(int)py * W + (int)px];
        if (id % 2) {
            /* an unsampled vertex: its pixel may only be lit by a sampled neighbour's dot, 3 px away */
            unsampled_lit += (uint32_t)on;
        } else if (px < W / 2 - 1) {
            sampled_visible++;
            sampled_visible_lit += (uint32_t)on;
        }
    }
    CHECK_MSG(unsampled_lit == 0, "%u unsampled vertices drawn", unsampled_lit);
    CHECK(sampled_visible > 10 && sampled_visible_lit == sampled_visible);
    CHECK(n.point_pixels > 0);
    free(mask);
    /* A bigger dot covers more pixels; colours apply. */
    rend_debug_desc d2 = d;
    d2.dot_radius = 2;
    d2.point_color = 0x00FF00FFu;
    rend_debug_counts n2;
    CHECK(rend_debug_samples(&d2, &m, out, &n2, &err) == LM_OK);
    CHECK(n2.point_pixels > n.point_pixels && n2.points_drawn == n.points_drawn);
    int green = 0;
    for (int i = 0; i < W * H; ++i) green += out[3 * i] == 0 && out[3 * i + 1] == 255 && out[3 * i + 2] == 0;
    CHECK((uint64_t)green == n2.point_pixels);

    /* Errors. */
    cache_snapshot_mesh bare = m;
    bare.corners = NULL;
    CHECK(rend_debug_leaves(&d, &bare, out, &n, &err) == LM_ERR_INVALID_ARG && strstr(err.msg, "publish_debug"));
    CHECK(rend_debug_samples(&d, &bare, out, &n, &err) == LM_ERR_INVALID_ARG);
    cache_snapshot_mesh empty = {0};
    CHECK(rend_debug_leaves(&d, &empty, out, &n, &err) == LM_OK && n.wire_pixels == 0 && out[0] == 80);
    rend_debug_desc bad_d = d;
    bad_d.width = 0;
    CHECK(rend_debug_leaves(&bad_d, &m, out, &n, &err) == LM_ERR_INVALID_ARG);
    bad_d = d;
    bad_d.ids = NULL;
    CHECK(rend_debug_samples(&bad_d, &m, out, &n, &err) == LM_ERR_INVALID_ARG);
    bad_d = d;
    bad_d.dim = 2.0f;
    CHECK(rend_debug_samples(&bad_d, &m, out, &n, &err) == LM_ERR_INVALID_ARG);
    CHECK(rend_debug_leaves(&d, NULL, out, &n, &err) == LM_ERR_INVALID_ARG);

    free(v), free(c), free(tri), free(index), free(ids), free(bg), free(out);
}

/* ---- the worker and the GL ID pass ------------------------------------------------------ */

static const cache_snapshot *run_worker(cache_worker *wk, uint64_t until_tested)
{
    const cache_snapshot *snap = NULL;
    double t0 = lm_now_seconds();
    while (lm_now_seconds() - t0 < 60.0) {
        snap = cache_worker_acquire(wk);
        if (snap && (snap->failed || snap->converged || (until_tested && snap->tested >= until_tested))) break;
        for (volatile int i = 0; i < 200000; ++i) {
        }
    }
    return snap;
}

static int file_exists(const char *dir, const char *name)
{
    char p[1200];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    struct stat st;
    return stat(p, &st) == 0 && st.st_size > 0;
}

static void with_gl(const GladGLContext *gl)
{
    char obj[1024], json[1024];
    test_write_file("debug_plane.obj",
                    "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 4 3\nf 1 3 2\n"
                    "v -0.2 0.5 -0.2\nv 0.2 0.5 -0.2\nv 0.2 0.5 0.2\nv -0.2 0.5 0.2\nf 5 6 7\nf 5 7 8\n",
                    obj, sizeof obj);
    test_write_file("debug.json",
                    "{\"meshes\": [{\"file\": \"debug_plane.obj\", \"material\": \"paint\"}],"
                    " \"materials\": {\"paint\": {\"kd\": [0.6, 0.5, 0.4]}},"
                    " \"lights\": [{\"type\": \"quad\", \"corner\": [-0.5, 1, -0.5], \"edge1\": [1, 0, 0],"
                    " \"edge2\": [0, 0, 1], \"radiance\": [5, 5, 5]}],"
                    " \"cameras\": [{\"position\": [0, 1.5, 1.0], \"target\": [0, 0, 0], \"fov_y\": 70}]}",
                    json, sizeof json);
    /* Seen from above, the blocker hides a patch of the plane inside the penumbra,
     * where the light mesh is fine (and the back of the light's quad another). */
    lm_error err;
    scene *s = NULL;
    CHECK(scene_load(&(scene_load_desc){.path = json, .require_light = 1}, &s, &err) == LM_OK);
    if (!s) return;
    const int W = 160, H = 120;
    const size_t npx = (size_t)W * H;
    rend_id *ip = NULL;
    rend_id_result idr;
    CHECK(rend_id_create(gl, &(rend_id_desc){.scene = s, .width = W, .height = H}, &ip, &err) == LM_OK);
    CHECK(ip && rend_id_render(ip, &s->cameras[0], &idr, &err) == LM_OK);
    uint32_t *ids = malloc(npx * sizeof *ids);
    CHECK(ip && rend_id_read_image(ip, ids, &err) == LM_OK);

    /* Deterministic runs with and without the debug publication. */
    const uint64_t budget = 3000;
    cache_worker *wk = NULL, *plain = NULL;
    cache_worker_desc wd = {.scene = s, .sampler = {.backend = SAMP_BACKEND_EMBREE}, .pixels = idr.pixels,
                            .max_tested = budget, .publish_debug = 1};
    CHECK(cache_worker_create(&wd, &wk, &err) == LM_OK);
    wd.publish_debug = 0;
    CHECK(cache_worker_create(&wd, &plain, &err) == LM_OK);
    const cache_snapshot *snap = wk ? run_worker(wk, budget) : NULL;
    const cache_snapshot *psnap = plain ? run_worker(plain, budget) : NULL;
    CHECK(snap && !snap->failed && snap->tested == budget);
    CHECK(psnap && !psnap->failed && psnap->tested == budget);
    if (snap && psnap) {
        CHECK(psnap->lights == NULL && psnap->light_mesh_count == 0 && psnap->direct.corners == NULL &&
              psnap->indirect.corners == NULL);
        CHECK(snap->direct.triangle_count == psnap->direct.triangle_count &&
              snap->direct.vertex_count == psnap->direct.vertex_count &&
              memcmp(snap->direct.vertices, psnap->direct.vertices,
                     (size_t)snap->direct.vertex_count * sizeof *snap->direct.vertices) == 0 &&
              memcmp(snap->direct.index, psnap->direct.index,
                     3 * (size_t)snap->direct.triangle_count * sizeof *snap->direct.index) == 0);
    }
    cache_worker_destroy(plain);

    if (snap && !snap->failed && snap->light_mesh_count == 1) {
        const cache_snapshot_mesh *lm = &snap->lights[0];
        CHECK(lm->triangle_count > 0 && lm->corners && snap->direct.corners && snap->indirect.corners);
        /* V in [0, 1], the other channels 0; the blocker (facing down) has no light leaves. */
        int vbad = 0;
        for (size_t i = 0; i < lm->vertex_count; ++i) {
            const float *val = lm->vertices[i].value;
            vbad += !(val[0] >= 0.0f && val[0] <= 1.0f) || val[1] != 0.0f || val[2] != 0.0f;
        }
        CHECK(vbad == 0);
        /* Distinct sampled corners: the meshes' own count. */
        CHECK_MSG(distinct_sampled(lm) == snap->stats.lights[0].mesh.vertices_sampled, "%u against %u",
                  distinct_sampled(lm), snap->stats.lights[0].mesh.vertices_sampled);
        CHECK(distinct_sampled(&snap->direct) == snap->stats.direct.mesh.vertices_sampled);
        CHECK(distinct_sampled(&snap->indirect) == snap->stats.indirect.mesh.vertices_sampled);
        /* Every fan diagonal is shared, reversed, by another triangle of the same scene triangle. */
        int lonely = 0, diagonals = 0;
        for (size_t i = 0; i < 3 * (size_t)lm->triangle_count; ++i) {
            if (lm->corners[i].flags & CACHE_CORNER_LEAF_EDGE) continue;
            diagonals++;
            uint32_t a = lm->corners[i].vertex, b = lm->corners[i - i % 3 + (i % 3 + 1) % 3].vertex;
            int twin = 0;
            for (size_t j = 0; j < 3 * (size_t)lm->triangle_count && !twin; ++j)
                twin = lm->tri[j / 3] == lm->tri[i / 3] && !(lm->corners[j].flags & CACHE_CORNER_LEAF_EDGE) &&
                       lm->corners[j].vertex == b && lm->corners[j - j % 3 + (j % 3 + 1) % 3].vertex == a;
            lonely += !twin;
        }
        CHECK_MSG(lonely == 0, "%d of %d fan diagonals without a twin", lonely, diagonals);

        uint8_t *bg = malloc(npx * 3), *out = malloc(npx * 3);
        for (size_t i = 0; i < npx * 3; ++i) bg[i] = (uint8_t)(60 + (i * 7) % 150);
        rend_debug_desc d = {.camera = &s->cameras[0], .width = W, .height = H, .ids = ids, .background = bg};
        rend_debug_counts nl, ns;
        CHECK(rend_debug_leaves(&d, lm, out, &nl, &err) == LM_OK);
        /* Occlusion: only the plane (triangles 0, 1) has light leaves here; the blocker
         * (2, 3) and, seen from above, the light's quad (4, 5) hide part of them. No
         * wire pixel without a plane id near it. */
        const uint8_t want[2] = {1, 1};
        uint8_t *mask = overlay_mask(&d, out);
        int far = 0;
        for (int y = 0; mask && y < H; ++y)
            for (int x = 0; x < W; ++x) far += mask[y * W + x] && !near_id(&d, ids, x, y, want, 2);
        CHECK_MSG(far == 0, "%d wire pixels away from the plane", far);
        int plane_tris = 1;
        for (uint32_t t = 0; t < lm->triangle_count; ++t) plane_tris &= lm->tri[t] <= 1;
        CHECK(plane_tris);
        /* ... and with the occluders' pixels relabelled as plane, wires show inside them. */
        uint32_t *unocc = malloc(npx * sizeof *unocc);
        int blocker_px = 0, light_px = 0;
        for (size_t i = 0; i < npx; ++i) {
            unocc[i] = ids[i] >= 3 ? 1 : ids[i];
            blocker_px += ids[i] == 3 || ids[i] == 4;
            light_px += ids[i] >= 5;
        }
        rend_debug_desc du = d;
        du.ids = unocc;
        rend_debug_counts nu;
        CHECK(rend_debug_leaves(&du, lm, out, &nu, &err) == LM_OK);
        uint8_t *mask_u = overlay_mask(&du, out);
        int inside = 0;
        for (int y = 1; mask_u && y + 1 < H; ++y)
            for (int x = 1; x + 1 < W; ++x) {
                int deep = 1;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) deep &= ids[(y + dy) * W + x + dx] >= 3;
                inside += deep && mask_u[y * W + x];
            }
        printf("occluders: blocker %d px, light %d px; %d wire pixels hidden inside them\n", blocker_px, light_px,
               inside);
        CHECK_MSG(blocker_px > 100 && inside > 20, "blocker %d px, %d hidden wire pixels", blocker_px, inside);
        CHECK(nu.wire_pixels > nl.wire_pixels);
        free(mask_u);
        free(unocc);
        free(mask);

        CHECK(rend_debug_samples(&d, lm, out, &ns, &err) == LM_OK);
        CHECK(ns.points_drawn + ns.points_hidden == snap->stats.lights[0].mesh.vertices_sampled);
        CHECK(ns.points_hidden > 0 && ns.points_drawn > ns.points_hidden);

        /* Leaves per pixel: penumbra (some corner strictly between 0 and 1) against
         * fully lit (every corner V = 1), over triangles whose corners project in front. */
        double area[2] = {0, 0};
        uint32_t count[2] = {0, 0};
        for (uint32_t t = 0; t < lm->triangle_count; ++t) {
            double p[3][2];
            int front = 1, pen = 0, lit = 1;
            for (int k = 0; k < 3; ++k) {
                const cache_snapshot_vertex *cv = cache_snapshot_corner_vertex(lm, t, k);
                front &= rend_debug_project(&d, cv->position, &p[k][0], &p[k][1]);
                pen |= cv->value[0] > 0.02f && cv->value[0] < 0.98f;
                lit &= cv->value[0] >= 0.9999f;
            }
            if (!front || (!pen && !lit)) continue;
            double a = 0.5 * fabs((p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) -
                                  (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]));
            area[pen] += a;
            count[pen]++;
        }
        double dens_lit = area[0] > 0 ? count[0] / area[0] : 0, dens_pen = area[1] > 0 ? count[1] / area[1] : 0;
        printf("light mesh: %u triangles, %u sampled vertices (%u drawn, %u hidden); leaves per pixel: penumbra "
               "%.3f (%u), lit %.4f (%u): ×%.1f\n",
               lm->triangle_count, distinct_sampled(lm), ns.points_drawn, ns.points_hidden, dens_pen, count[1],
               dens_lit, count[0], dens_lit > 0 ? dens_pen / dens_lit : 0.0);
        CHECK(count[0] > 0 && count[1] > 0);
        CHECK_MSG(dens_pen > 4.0 * dens_lit, "penumbra %.4f, lit %.4f leaves per pixel", dens_pen, dens_lit);
        printf("overlays at %dx%d: leaves %.2f ms (%u of %u segments, %llu px), samples %.2f ms\n", W, H,
               nl.seconds * 1e3, nl.segments_drawn, nl.segments, (unsigned long long)nl.wire_pixels, ns.seconds * 1e3);

        /* Files. */
        char dir[1024];
        snprintf(dir, sizeof dir, "%s/rend_debug_out/sub", LUMESH_TMP_DIR);
        CHECK(rend_debug_write_images(&(rend_debug_write_desc){.draw = &d, .snap = snap, .dir = dir}, &err) == LM_OK);
        const char *names[] = {"light0-leaves.png", "light0-samples.png", "direct-leaves.png", "direct-samples.png",
                               "indirect-leaves.png", "indirect-samples.png"};
        for (int i = 0; i < 6; ++i) CHECK_MSG(file_exists(dir, names[i]), "%s/%s", dir, names[i]);
        CHECK(!file_exists(dir, "specular-leaves.png"));
        free(bg);
        free(out);
    } else {
        CHECK(snap && snap->light_mesh_count == 1);
    }
    cache_worker_destroy(wk);
    free(ids);
    rend_id_destroy(ip);
    scene_destroy(s);
}

int main(void)
{
    synthetic();
    glctx *ctx = NULL;
    lm_error err;
    if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &ctx, &err) != LM_OK) {
        int rc = test_finish("rend_debug_test (synthetic part only)");
        int skip = test_no_gl(err.msg);
        return rc ? 1 : skip;
    }
    with_gl(glctx_gl(ctx));
    glctx_destroy(ctx);
    return test_finish("rend_debug_test");
}
