/* cache_worker_internal.h — what cache_worker.c (the thread, the display's
 * calls) and cache_worker_publish.c (filling and committing snapshots) share:
 * the worker's structure and the snapshot slots' buffers. Stays in mesh/cache/.
 *
 * Threads: struct cache_worker says per field who owns it; a snapshot_store is
 * owned by whichever side holds its slot (front: the display's, ready: under the
 * lock, back: the worker's), and publish_scratch is the worker thread's.
 */
#ifndef LUMESH_CACHE_WORKER_INTERNAL_H
#define LUMESH_CACHE_WORKER_INTERNAL_H

#include <pthread.h>
#include <stdatomic.h>

#include "mesh/cache/cache_worker.h"
#include "sampling/rt_scene.h"

enum { MAX_EDITS = 64 };

typedef struct light_edit {
    uint32_t light;
    float value[3];
} light_edit;

/* Arrays behind one published mesh (capacities in elements). */
typedef struct mesh_store {
    cache_snapshot_vertex *verts;
    uint32_t *index, *tris;
    cache_snapshot_corner *corners;   /* publish_debug only */
    cache_lobe *lobes;                /* the specular mesh only: parallel to verts */
    size_t verts_cap, index_cap, tris_cap, corners_cap, lobes_cap;
    uint32_t *whole;                  /* whole roots (cache_worker_desc.whole_roots): the bit mask ... */
    float *values;                    /* ... and the values by vertex-table id */
    size_t whole_cap, values_cap;     /* words, floats */
    mesh_qmesh_version filled;        /* the mesh and its version the arrays hold ({0, 0}: none) */
    int filled_debug;                 /* with the debug corners */
    int filled_whole;                 /* with whole roots apart */
} mesh_store;

/* One mesh's fill (cache_worker_publish.c, fill_mesh): a piece of its leaf
 * triangles, each vertex-table id's index in the mesh being published
 * (UINT32_MAX: not yet in it; set back after each mesh) and the ids published,
 * in order. */
typedef struct fill_scratch {
    mesh_qmesh_tri *buf;
    size_t buf_cap;
    uint32_t *local, *ids;
    size_t local_cap, ids_cap;
} fill_scratch;

/* The worker thread's; fill[1] is lent to the helper thread that fills the
 * direct mesh beside it, for the length of cache_publish_snapshot. */
typedef struct publish_scratch {
    fill_scratch fill[2];
} publish_scratch;

/* Leaf triangles taken from a mesh at a time when publishing: the scratch stays
 * at ~0.56 MB (68 bytes a triangle) however big the mesh (a million-triangle
 * scene's whole mesh at once held 70 MB more at the peak; docs/memory.md). It
 * was 65,536 (4.5 MB a fill, two fills): the first snapshot's first touch of
 * it and the vertex room reserved for a piece cost the 116k box's first image
 * 10-30 ms (docs/cache.md, "Pieces of 8,192 leaf triangles"). */
enum { PUBLISH_PIECE = 1 << 13 };

/* Buffers behind one snapshot; owned by whichever side holds the slot. */
typedef struct snapshot_store {
    cache_snapshot snap;
    mesh_store mesh[3];               /* direct, indirect, specular */
    mesh_store *light_mesh;           /* publish_debug only: one per light ... */
    cache_snapshot_mesh *light_snap;  /* ... and what snap.lights points to */
    uint32_t light_mesh_cap;
    cache_mesh_stats *lights;
    float *light_radiance;            /* lights_cap × RGB: what snap.light_radiance points to */
    size_t lights_cap;
} snapshot_store;

struct cache_worker {
    cache_worker_desc desc;           /* immutable after create */
    const scene *s;
    uint32_t *pixels;                 /* owned copy; the worker's (set_pixels hands over a new one) */
    pthread_t thread;
    int started, joined;            /* the display's: the thread was made; joined (retire, destroy) */
    atomic_int stop_now;              /* set by the display when cancelling (stop_thread): the worker
                                         then leaves without a snapshot of its cut-short step */
    atomic_int interrupt;             /* set by the display when cancelling or pausing, cleared when it
                                         resumes; read by the worker's refine calls between batches and
                                         rounds (cache_refine_desc.stop): a pause does not wait for a
                                         whole step (docs/renderer.md, "The first rows on time") */

    pthread_mutex_t lock;             /* guards every field below */
    pthread_cond_t cond;              /* signalled on any change of them */
    int cancel, paused, parked, finished;
    snapshot_store *front, *ready, *back; /* display's / latest committed / worker's own */
    int ready_new;
    light_edit edits[MAX_EDITS];
    uint32_t edit_count;
    int new_bounces;                  /* set_bounces: the count waiting (cache_desc.bounces); 0: none */
    float new_exposure;               /* set_exposure: the display's exposure waiting (stops) ... */
    int new_exposure_set;             /* ... when this is non-zero */
    uint32_t *new_pixels;             /* set_pixels: a copy waiting for the worker to take it */
    int debug_wanted;                 /* snapshots carry the debug data (desc.publish_debug, then
                                         cache_worker_set_publish_debug) */
    int republish;                    /* debug_wanted changed, or the last step was not published:
                                         publish once even when idle or paused */
    float new_eye[3];                 /* set_view: the eye that comes with new_pixels ... */
    int new_eye_set;                  /* ... when this is non-zero */
    samp_stats quick_stats;           /* the worker's: its quick start's sampler, kept for the snapshots */
    samp_stats retired[CACHE_SNAPSHOT_RETIRED]; /* the worker's: refining samplers it replaced (retire_sampler),
                                                   kept for the snapshots */
    uint32_t retired_count;
    cache_estimate estimate;          /* the worker's: the last error estimate, and when it was made */
    uint64_t first_tested;            /* the worker's: leaves tested before the first publication */
    rt_scene *rt;                     /* the worker's: the one Embree scene of its samplers (the quick
                                         start's, the refining one, a calibration's), when the client
                                         gave none in desc.sampler.rt; destroyed last */
    double first_rounds_seconds, first_publish_seconds; /* the worker's: cache_snapshot's */
    double published_end, publish_cost; /* worker thread only: when the last snapshot was committed, and
                                           what making it cost (s) */
    /* The worker's: AUTO's calibration, deferred to the first convergence; the
     * Embree sampler it replaced, kept until the calibrated one has shown its cost
     * on the cache's own samples (calibrated_check). */
    int calibrate_later;
    int start_count;                  /* the running sampler gathers with CACHE_WORKER_START_RAYS */
    char start_phrase[96];            /* AUTO: how refinement started, for the notes below */
    samp_sampler *fallback;
    double fallback_cost[2];          /* seconds per direct / indirect point of the fallback; 0: none */
    char calibration_note[512];       /* AUTO: the snapshots' sampler choice (what was decided, and why) */
    char calibrated_choice[512];      /* AUTO: the calibration's own choice, while on trial */
    double estimate_at;
    /* Whole roots (desc.whole_roots): each scene corner's vertex-table id, what
     * cache_snapshot.corner_ids points to. Made by the worker before the first
     * snapshot that has whole roots is committed (the commit's lock orders it
     * before the display's reads), never written after; freed by destroy, so it
     * outlives retire with the snapshots. */
    uint32_t *corner_ids;
    uint64_t corner_ids_serial;
};

/* ---- cache_worker_publish.c: snapshots, on the worker thread ----------------------- */

/* Fills the worker's back slot from cache c: its meshes (each kept where the slot
 * already holds it at its version), statistics, the estimate, the lights'
 * radiance, and with debug the light meshes and corner flags. */
lm_result cache_publish_snapshot(cache_worker *w, cache *c, const cache_estimate *estimate, int debug,
                                 uint64_t generation, uint64_t tested, int converged, publish_scratch *ps,
                                 lm_error *err);
/* Commits the back slot: a pointer swap with the ready one under the lock. */
void cache_publish_commit(cache_worker *w);
/* Commits a snapshot that says refinement failed, and why (msg). */
void cache_publish_failure(cache_worker *w, uint64_t generation, const char *msg);
/* Frees a slot and every array behind it (NULL: nothing). */
void cache_publish_store_free(snapshot_store *st);
/* Frees the scratch's arrays (the worker thread, when it ends). */
void cache_publish_scratch_free(publish_scratch *ps);

#endif
