/* converge_internal.h — what `lumesh converge` (cmd_converge.c) measures, shared
 * with its writers (converge_output.c: the CSV, the JSON and the plot). Private to
 * src/cli/. Threads: the command's main thread only. */
#ifndef LUMESH_CONVERGE_INTERNAL_H
#define LUMESH_CONVERGE_INTERNAL_H

#include "mesh/cache/cache.h"
#include "sampling/reference.h"
#include "src/cli/cli.h"
#include "src/image/compare.h"
#include "src/image/image.h"
#include "src/render/rend_frame.h"
#include "src/scene/scene.h"

#include <cjson/cJSON.h>

enum { MAX_SNAPSHOTS = 256, MAX_MESHES = 64, MAX_METHODS = 6 };

/* converged: the cache's estimate is below the JND (cache_estimate_converged), at
 * the lowest JND it refines to (rend_session_desc.jnd_floor);
 * below-jnd: it was below the scene's JND, and the worker refines on to a lower one;
 * finished: nothing left it can do at the JND it refines to, yet its estimate is
 * above that JND somewhere (below the scene's JND when it converged there before:
 * the column jnd says which);
 */
typedef enum row_state { ROW_REFINING = 0, ROW_CONVERGED, ROW_NO_SNAPSHOT, ROW_FINISHED, ROW_BELOW_JND } row_state;
extern const char *const conv_state_names[]; /* by row_state */

/* One measured image. */
typedef struct conv_row {
    double target;            /* requested time, seconds */
    double seconds;           /* when the image was taken (see the file comment) */
    row_state state;
    uint64_t tested;          /* lumesh: leaves tested */
    uint64_t samples[MAX_MESHES]; /* lumesh: light meshes, then direct, indirect, specular */
    uint32_t spp_min, spp_max;/* samples a pixel: a peer's (path tracer, VPL), or lumesh's residual's */
    uint64_t vpls;            /* VPL, BDIR: virtual point lights made so far (BDIR: candidates) */
    double vpl_seconds;       /* VPL, BDIR: of `seconds`, the time spent making them (and resampling) */
    uint64_t ism_maps;        /* -ism: imperfect shadow maps made so far */
    double ism_seconds;       /* -ism: of `seconds`, the time spent making them (GL and read-back) */
    uint64_t rays;            /* the same paths' rays */
    double residual_weight;   /* lumesh: mean James–Stein weight of the residual's blocks (rend_residual_info) */
    double residual_corrected;/* lumesh: share of the blocks the residual corrects */
    double residual_est;      /* lumesh: the corrected picture's relMSE as the residual estimates it */
    double est_delta_e;       /* lumesh: the cache's own estimate of delta_e_mean (cache_estimate, over the image) */
    double est_above_jnd;     /* lumesh: its estimated fraction of pixels above the JND */
    double est_untested;      /* lumesh: the fraction of pixels in leaves not tested yet (the estimate a guess) */
    int est_measured;         /* lumesh: the snapshot had an estimate (not the first: cache_worker_acquire);
                                 0: the three above are not written (empty in the CSV, null in the JSON) */
    double jnd;               /* lumesh: the JND the cache refined to (below the scene's once converged) */
    cmp_result m;
    char image[64];           /* file name in DIR (EXR; the PNG beside it) */
} conv_row;

typedef struct conv_run {
    const char *method;       /* "lumesh", "lumesh-single-mesh", "vpl", "bdir", "vpl-ism", "bdir-ism", "path-tracer" */
    int peer;                 /* a method of the reference renderer (ref_estimator): no cache columns */
    ref_estimator estimator;  /* a peer's */
    ref_vpl_visibility visibility; /* VPL, BDIR: shadow rays, or imperfect shadow maps (-ism) */
    conv_row rows[MAX_SNAPSHOTS];
    int count;
} conv_run;

typedef struct conv_ctx {
    const app_command *cmd;
    scene *s;
    int cam, w, h;
    const char *dir;
    img_image ref;
    float exposure;
    double times[MAX_SNAPSHOTS];
    int time_count;
    double seconds;           /* --seconds */
    int supersample;          /* --supersample: s×s samples a pixel in the measured images */
    int accumulate;           /* --accumulate: k×k jittered draws of a converged snapshot */
    int residual;             /* --residual on: path-trace the residual beside the cache (background) */
    uint32_t residual_seed;
    int tty;
    uint32_t light_count;     /* mesh columns: light_count + 3 */
    double first_image;       /* seconds from the scene loaded; < 0 until drawn */
    /* Where that time went (first_image_phases in the JSON), seconds from the
     * scene loaded; < 0 until reached: the session made (worker started, GL
     * context taken), the preview renderer made, the first snapshot taken. */
    double phase[3];
    /* Before the clock: seconds from the command's start to the reference read
     * and to the scene loaded ("load_phases"; the early GL context is made
     * meanwhile, and the load's forks wait for its start: fork_guard.h). */
    double load[2];
    double converged_at;      /* published time of the first converged snapshot; < 0: never */
    double stopped;           /* the previewer's clock: seconds it stood still while its snapshots
                                 were drawn and measured (cmd_converge.c, measuring_begin) */
    double final_seconds;     /* the previewer's clock when the last snapshot measured was published */
    cache_snapshot final;     /* statistics of the last snapshot measured (lights copied below) */
    cache_mesh_stats final_lights[MAX_MESHES];
    rend_frame_times frame_times;
    double id_seconds;
    uint64_t frames;
    int have_final;
    ref_transport transport;  /* the reference's (its lumesh:transport; model when it does not say) */
    int ref_bounces;          /* model transport: its bounce count (REF_BOUNCES_NONE: direct only) */
    ref_glossy glossy;        /* model transport: what its glossy materials reflect (lumesh:glossy; a file
                                 without it was made before the room was reflected: the lights only) */
    int bounces;              /* the previewer's (cache_desc.bounces) */
    char transport_note[384]; /* where these came from */
    int interrupted;          /* the run was stopped by Ctrl-C: what was measured is written */
    int vpl_paths, vpl_per_sample; /* --vpl-paths, --vpl-per-sample (0: ref_desc's defaults) */
    float vpl_clamp;          /* --vpl-clamp (0: the default; REF_VPL_NO_CLAMP: none) */
    glctx_platform gl_platform; /* --gl: the GL of the -ism methods' maps too */
} conv_ctx;

/* DIR/convergence.csv, .json (with the --stats object, may be NULL) and .png, each
 * through a temporary file renamed into place. */
lm_result conv_write_csv(const conv_ctx *c, const conv_run *runs, int nrun, lm_error *err);
lm_result conv_write_json(const conv_ctx *c, const char *ref_path, const conv_run *runs, int nrun,
                          const cJSON *stats, lm_error *err);
lm_result conv_write_plot(const conv_ctx *c, const conv_run *runs, int nrun, lm_error *err);

#endif
