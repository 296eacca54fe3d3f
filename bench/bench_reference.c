/* bench_reference — speed of the reference path tracer on this machine: rays per
 * second, and the time to bring the 640x480 Cornell box
 * (../shared/scenes/cornell-box/CornellBox-Original.obj, its framing camera) to a
 * mean relative standard error of 1%, 0.3% and 0.1%, for both transports.
 * Targets not reached within the time budget are extrapolated with the 1/sqrt(t)
 * law from the last measurement and marked '~'.
 * usage: bench_reference [SECONDS_PER_TRANSPORT (default 120)] [THREADS (default all)] */
#include <stdio.h>
#include <stdlib.h>

#include "sampling/reference.h"
#include "src/scene/scene.h"

static const double targets[3] = {0.01, 0.003, 0.001};

int main(int argc, char **argv)
{
    double budget = argc > 1 ? atof(argv[1]) : 120.0;
    int threads = argc > 2 ? atoi(argv[2]) : 0;
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell-box/CornellBox-Original.obj", LUMESH_SCENES);
    scene_load_desc ld = {.path = path, .require_light = 1};
    scene *s;
    lm_error err;
    if (scene_load(&ld, &s, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    printf("CornellBox-Original.obj, 640x480, framing camera, budget %.0f s per transport\n", budget);
    printf("%-10s %9s %8s %10s %12s %12s %12s\n", "transport", "Mrays/s", "spp/s", "rays/spp", "t(1%)", "t(0.3%)",
           "t(0.1%)");
    for (int tr = 0; tr < REF_TRANSPORT_COUNT; ++tr) {
        ref_desc d = {.scene = s, .width = 640, .height = 480, .transport = (ref_transport)tr, .seed = 1,
                      .threads = threads};
        ref_renderer *r;
        if (ref_create(&d, &r, &err) != LM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            return 1;
        }
        double reached[3] = {-1, -1, -1};
        ref_stats st;
        for (;;) {
            ref_render_pass(r, NULL, 0.0);
            ref_get_stats(r, &st);
            for (int k = 0; k < 3; ++k)
                if (reached[k] < 0 && st.mean_rel_stderr <= targets[k]) reached[k] = st.seconds;
            if (reached[2] >= 0 || st.seconds >= budget) break;
        }
        char cells[3][32];
        for (int k = 0; k < 3; ++k) {
            if (reached[k] >= 0)
                snprintf(cells[k], sizeof cells[k], "%.1f s", reached[k]);
            else {
                double ratio = st.mean_rel_stderr / targets[k];
                snprintf(cells[k], sizeof cells[k], "~%.0f s", st.seconds * ratio * ratio);
            }
        }
        printf("%-10s %9.2f %8.2f %10.2f %12s %12s %12s\n", tr == REF_TRANSPORT_MODEL ? "model" : "full",
               st.rays / st.seconds * 1e-6, st.min_samples / st.seconds,
               (double)st.rays / ((double)st.min_samples * 640 * 480), cells[0], cells[1], cells[2]);
        printf("           (%u spp in %.1f s, mean relative standard error %.3f%%)\n", st.min_samples, st.seconds,
               100.0 * st.mean_rel_stderr);
        fflush(stdout);
        ref_destroy(r);
    }
    scene_destroy(s);
    return 0;
}
