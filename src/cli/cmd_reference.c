/* cmd_reference.c — `lumesh reference`: the progressive Embree path tracer
 * (sampling/reference.h) on the command line: stopping rules, a progress bar on a
 * terminal, Ctrl-C that still writes the complete samples, and the EXR with the
 * image and its per-pixel standard error. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sampling/ref_shading.h"
#include "sampling/reference.h"
#include "src/cli/cli.h"
#include "src/image/image.h"
#include "src/scene/scene.h"

/* Written by the SIGINT handler, read by the render loop and the workers. */
static volatile sig_atomic_t interrupted = 0;

static void on_sigint(int sig)
{
    (void)sig;
    if (interrupted) _exit(130); /* a second Ctrl-C: leave at once, write nothing */
    interrupted = 1;
}

static void progress(const ref_renderer *r, double fraction, int final)
{
    ref_stats st;
    ref_get_stats(r, &st);
    char bar[APP_PROGRESS_WIDTH + 1];
    app_progress_bar(fraction, bar);
    fprintf(stderr, "\rreference [%s] %u spp  %.1f s  %.2f Mrays/s  rel. std. error %.3f%%   ", bar,
            st.min_samples, st.seconds, st.seconds > 0 ? st.rays / st.seconds * 1e-6 : 0.0,
            100.0 * st.mean_rel_stderr);
    if (final) fputc('\n', stderr);
    fflush(stderr);
}

/* A previous reference to pool this run's samples with (--add): read and checked
 * before any sampling, so that an hour's run cannot end in a mismatch. */
typedef struct prior_ref {
    img_image img;
    int ch[7]; /* R, G, B, stderr.R/G/B, samples */
    char seeds[IMG_ATTRIBUTE_CAP];
} prior_ref;

static const char *const k_ref_channels[7] = {"R", "G", "B", "stderr.R", "stderr.G", "stderr.B", "samples"};

/* The attributes a reference made with rd carries (and a pooled one must share). */
static void ref_attributes(const ref_desc *rd, char bounces[16], const char *out[3])
{
    snprintf(bounces, 16, "%d", rd->bounces == REF_BOUNCES_NONE ? 0 : rd->bounces == 0 ? 1 : rd->bounces);
    out[0] = rd->transport == REF_TRANSPORT_FULL ? "full" : "model";
    out[1] = rd->transport == REF_TRANSPORT_FULL ? "all" : bounces;
    /* lumesh:glossy: what glossy materials reflect (the model transport's
     * ref_desc.glossy; the full transport reflects everything). A file
     * without it was made before the model reflected the room. */
    out[2] = rd->transport == REF_TRANSPORT_MODEL && rd->glossy == REF_GLOSSY_DIRECT ? "direct" : "indirect";
}

static lm_result read_prior(const char *path, const ref_desc *rd, int w, int h, prior_ref *pr, lm_error *err)
{
    lm_result res = img_read(path, &pr->img, err);
    if (res != LM_OK) return res;
    const img_image *im = &pr->img;
    if (im->width != w || im->height != h)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s is %dx%d, this reference %dx%d: --add pools only the same size",
                       path, im->width, im->height, w, h);
    for (int k = 0; k < 7; ++k) {
        pr->ch[k] = -1;
        for (int c = 0; c < im->channels; ++c)
            if (strcmp(im->channel_names[c], k_ref_channels[k]) == 0) pr->ch[k] = c;
        if (pr->ch[k] < 0)
            return lm_fail(err, LM_ERR_BAD_INPUT, "%s has no channel %s: not made by `lumesh reference`", path,
                           k_ref_channels[k]);
    }
    char bounces[16];
    const char *want[3];
    ref_attributes(rd, bounces, want);
    static const char *const names[3] = {"lumesh:transport", "lumesh:bounces", "lumesh:glossy"};
    for (int k = 0; k < 3; ++k) {
        const char *have = img_attribute(im, names[k]);
        if (!have || strcmp(have, want[k]) != 0)
            return lm_fail(err, LM_ERR_BAD_INPUT, "%s was made with %s %s, this reference with %s: --add pools only "
                           "references of the same transport", path, names[k], have ? have : "(none)", want[k]);
    }
    /* A file from before the list (or one whose list overflowed) holds seeds
     * nobody can check: "unrecorded" stays in the list for good. */
    const char *seeds = img_attribute(im, "lumesh:seeds");
    snprintf(pr->seeds, sizeof pr->seeds, "%s", seeds ? seeds : "unrecorded");
    char mine[16];
    snprintf(mine, sizeof mine, "%u", rd->seed);
    for (const char *at = pr->seeds; *at;) { /* a seed already in: the same samples again, nothing new */
        size_t len = strcspn(at, ",");
        if (len == strlen(mine) && strncmp(at, mine, len) == 0)
            return lm_fail(err, LM_ERR_BAD_INPUT, "%s already holds the samples of seed %s: give another --seed", path,
                           mine);
        at += len + (at[len] == ',');
    }
    return LM_OK;
}

/* The transport goes into the file's header (lumesh:transport, lumesh:bounces):
 * `converge` takes the same transport for its path tracer and the same bounce
 * count for the previewer from it; lumesh:seeds lists the seeds whose samples it
 * holds (--add). With prior, the two are pooled pixel by pixel: means weighted by
 * their samples, standard errors combined as those of independent means,
 * se² = (n_a²·se_a² + n_b²·se_b²) / (n_a + n_b)². *rel_stderr gets the file's
 * mean relative standard error, with SE(Y) taken as the channels' weighted sum
 * (their noise fully correlated, so never understated). */
static lm_result write_result(const ref_renderer *r, const ref_desc *rd, const prior_ref *prior, const char *path,
                              double *rel_stderr, lm_error *err)
{
    int w, h;
    ref_get_size(r, &w, &h);
    size_t n = (size_t)w * (size_t)h;
    float *rgb = malloc(n * 3 * sizeof *rgb), *se = malloc(n * 3 * sizeof *se);
    float *spp = malloc(n * sizeof *spp), *px = malloc(n * 7 * sizeof *px);
    lm_result res = LM_OK;
    if (!rgb || !se || !spp || !px) {
        res = lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory assembling the image", path);
    } else {
        ref_get_image(r, rgb, se, spp);
        double rel = 0.0;
        size_t counted = 0;
        for (size_t i = 0; i < n; ++i) {
            double na = spp[i], nb = 0.0;
            const float *q = prior ? prior->img.pixels + i * (size_t)prior->img.channels : NULL;
            if (q && isfinite(q[prior->ch[6]]) && q[prior->ch[6]] > 0.0f) nb = q[prior->ch[6]];
            const double sum = na + nb > 0.0 ? na + nb : 1.0;
            for (int k = 0; k < 3; ++k) {
                double m = rgb[3 * i + (size_t)k], e = se[3 * i + (size_t)k];
                if (nb > 0.0) {
                    const double mb = q[prior->ch[k]], eb = q[prior->ch[3 + k]];
                    m = (na * m + nb * mb) / sum;
                    e = sqrt(na * na * e * e + nb * nb * eb * eb) / sum;
                }
                px[7 * i + (size_t)k] = (float)m;
                px[7 * i + 3 + (size_t)k] = (float)e;
            }
            px[7 * i + 6] = (float)(na + nb);
            /* ref_get_stats' measure, with SE(Y) the luminance of the channels' errors */
            const double y = ref_luminance(px + 7 * i), se_y = ref_luminance(px + 7 * i + 3);
            if (isfinite(se_y)) {
                rel += se_y / sqrt(y * y + 0.01);
                counted++;
            }
        }
        *rel_stderr = counted ? rel / (double)counted : INFINITY;
        char bounces[16], seeds[IMG_ATTRIBUTE_CAP];
        const char *a[3];
        ref_attributes(rd, bounces, a);
        int len = snprintf(seeds, sizeof seeds, "%s%s%u", prior ? prior->seeds : "", prior ? "," : "", rd->seed);
        if (len < 0 || (size_t)len >= sizeof seeds) snprintf(seeds, sizeof seeds, "unrecorded"); /* too many to list */
        const char *attrs[] = {"lumesh:transport", a[0], "lumesh:bounces", a[1], "lumesh:glossy", a[2],
                               "lumesh:seeds", seeds, NULL};
        img_write_desc d = {.path = path, .width = w, .height = h, .channels = 7, .pixels = px,
                            .channel_names = k_ref_channels, .attributes = attrs};
        res = img_write(&d, err);
    }
    free(rgb);
    free(se);
    free(spp);
    free(px);
    return res;
}

int cmd_reference(const app_command *cmd, int argc, char **argv)
{
    const char *out = NULL, *transport = "model", *camera = NULL, *glossy = "indirect", *add = NULL;
    double seconds = 0;
    long spp = 0, bounces = 1, seed = 0, threads = 0, width = 0, height = 0;
    app_opt opts[] = {
        {"--output", "-o", APP_OPT_STRING, &out},
        {"--spp", NULL, APP_OPT_INT, &spp, 1, 1e9},
        {"--seconds", NULL, APP_OPT_DOUBLE, &seconds, 0.001, 1e7},
        {"--transport", NULL, APP_OPT_STRING, &transport},
        {"--bounces", NULL, APP_OPT_INT, &bounces, 0, 64},
        {"--seed", NULL, APP_OPT_INT, &seed, 0, 4294967295.0},
        {"--threads", NULL, APP_OPT_INT, &threads, 1, 256},
        {"--camera", NULL, APP_OPT_STRING, &camera},
        {"--width", NULL, APP_OPT_INT, &width, 1, 32768},
        {"--height", NULL, APP_OPT_INT, &height, 1, 32768},
        {"--glossy", NULL, APP_OPT_STRING, &glossy},
        {"--add", NULL, APP_OPT_STRING, &add},
    };
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, 12, pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if (!out) return app_usage_error(cmd, "an output image is required (-o OUT.exr)");
    char ext[16];
    lm_path_ext(out, ext, sizeof ext);
    if (strcmp(ext, "exr") != 0) return app_usage_error(cmd, "the output must end in .exr");
    if (opts[1].seen == opts[2].seen) return app_usage_error(cmd, "give exactly one of --spp or --seconds");
    ref_transport tr;
    if (strcmp(transport, "model") == 0)
        tr = REF_TRANSPORT_MODEL;
    else if (strcmp(transport, "full") == 0)
        tr = REF_TRANSPORT_FULL;
    else
        return app_usage_error(cmd, "--transport is 'model' or 'full', not '%s'", transport);
    if (tr == REF_TRANSPORT_FULL && opts[4].seen)
        return app_usage_error(cmd, "--bounces applies to --transport model (full follows every bounce)");
    if (opts[8].seen != opts[9].seen) return app_usage_error(cmd, "give both --width and --height");
    if (strcmp(glossy, "indirect") != 0 && strcmp(glossy, "direct") != 0)
        return app_usage_error(cmd, "--glossy is 'indirect' or 'direct', not '%s'", glossy);
    if (tr == REF_TRANSPORT_FULL && opts[10].seen)
        return app_usage_error(cmd, "--glossy applies to --transport model (full reflects everything)");

    scene_load_desc ld = {.path = npos ? pos[0] : NULL, .require_light = 1};
    scene *s;
    lm_error err;
    lm_result res = scene_load(&ld, &s, &err);
    if (res != LM_OK) return app_report(res, &err);
    int cam = scene_find_camera(s, camera);
    if (cam < 0) {
        fprintf(stderr, "lumesh: %s: no camera named '%s'\n", s->source, camera);
        scene_destroy(s);
        return APP_EXIT_BAD_INPUT;
    }
    ref_desc rd = {.scene = s, .camera = cam, .width = (int)width, .height = (int)height,
                   .transport = tr, .bounces = bounces == 0 ? REF_BOUNCES_NONE : (int)bounces,
                   .glossy = strcmp(glossy, "direct") == 0 ? REF_GLOSSY_DIRECT : REF_GLOSSY_INDIRECT,
                   .seed = (uint32_t)seed, .threads = (int)threads};
    ref_renderer *r;
    res = ref_create(&rd, &r, &err);
    if (res != LM_OK) {
        scene_destroy(s);
        return app_report(res, &err);
    }
    prior_ref prior = {0};
    if (add) {
        int w, h;
        ref_get_size(r, &w, &h);
        res = read_prior(add, &rd, w, h, &prior, &err);
        if (res != LM_OK) {
            img_free(&prior.img);
            ref_destroy(r);
            scene_destroy(s);
            return app_report(res, &err);
        }
    }

    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_sigint;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old);
    int tty = isatty(STDERR_FILENO);
    double start = lm_now_seconds(), deadline = opts[2].seen ? start + seconds : 0.0;
    double last_draw = 0.0;
    for (long pass = 0;; ++pass) {
        /* The first pass always completes, so every pixel has a sample. */
        ref_render_pass(r, pass == 0 ? NULL : &interrupted, pass == 0 ? 0.0 : deadline);
        double now = lm_now_seconds();
        int done = interrupted || (opts[1].seen ? pass + 1 >= spp : now >= deadline);
        if (tty && (done || now - last_draw > 0.25)) {
            double f = opts[1].seen ? (double)(pass + 1) / (double)spp : (now - start) / seconds;
            progress(r, f > 1.0 ? 1.0 : f, done);
            last_draw = now;
        }
        if (done) break;
    }
    double pooled_rel = 0.0;
    res = write_result(r, &rd, add ? &prior : NULL, out, &pooled_rel, &err);
    sigaction(SIGINT, &old, NULL);
    ref_stats st;
    ref_get_stats(r, &st);
    if (res == LM_OK) {
        int w, h;
        ref_get_size(r, &w, &h);
        printf("wrote %s: %dx%d, transport %s, %u%s spp, %.2f s, %.2f Mrays/s, mean relative standard "
               "error %.3f%%%s\n",
               out, w, h, transport, st.min_samples, st.max_samples > st.min_samples ? "+" : "", st.seconds,
               st.seconds > 0 ? st.rays / st.seconds * 1e-6 : 0.0, 100.0 * st.mean_rel_stderr,
               interrupted ? " (interrupted)" : "");
        if (add)
            printf("pooled with %s (seeds %s): mean relative standard error at most %.3f%%\n", add, prior.seeds,
                   100.0 * pooled_rel);
        if (st.bad_samples)
            fprintf(stderr, "lumesh reference: %llu non-finite samples were dropped\n",
                    (unsigned long long)st.bad_samples);
    }
    img_free(&prior.img);
    ref_destroy(r);
    scene_destroy(s);
    return res == LM_OK ? APP_EXIT_OK : app_report(res, &err);
}
