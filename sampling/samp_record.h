/* samp_record.h — what the GL back end costs on this machine, kept between runs
 * (issue 14: "reuse a calibration stored per machine"; docs/sampling.md, "GL's
 * costs kept per machine").
 *
 * AUTO's calibration (samp_auto.c) measures GL's cost per point, direct and
 * indirect, at the asked resolutions; the cheapest ever measured here is kept.
 * Before a deferred calibration the refinement worker compares it with what the
 * running Embree sampler costs a point on the scene at hand: where GL's cheapest
 * is slower by the worker's margin, GL cannot win, and the calibration, with its
 * GL context (~30 MB on CornellBox-Water, ~100 MB on a 116k-triangle scene) and
 * its 0.5-2 s of both cores, is not made. A direct hemicube draws the triangles
 * between a receiver and a light, an indirect one a source of a fixed size
 * (samp_auto.c, CAL_SOURCE_TRIANGLES), so the cheapest cost seen on any scene is a
 * fair floor for the next.
 *
 * Usage:
 *     samp_record rec;
 *     if (samp_record_get(&desc, &rec) && rec.indirect_us > 2.0 * embree_indirect_us) ... GL cannot win
 *     samp_record_note(&desc, gl_direct_us, gl_indirect_us);   // after a calibration; < 0: not measured
 *
 * Where: the directory $LUMESH_CACHE_DIR, else $XDG_CACHE_HOME/lumesh, else
 * $HOME/.cache/lumesh (made if missing), file "gl-costs". LUMESH_CACHE_DIR set
 * and empty: nothing is read or written (the test suite runs so, for runs that do
 * not depend on each other). Lines: "v1 PLATFORM DIRECT_RES INDIRECT_RES HOST
 * DIRECT_US INDIRECT_US", one per GL platform, resolutions and host name (a home
 * shared between machines). A note rewrites the whole file through a temporary
 * one and a rename: never a partial file; lines it cannot read are dropped.
 * Threads: any; two writers at once: the last rename wins.
 * Does NOT do: decide (cache_worker.c does), keep Embree's costs (each run measures
 * its own), notice a new GL driver (its costs are lower or higher: a lower one is
 * kept at the next calibration, a higher one never replaces the floor; remove the
 * file to start again). Failing to read or write is never an error: the
 * calibration runs as it would without the file. Units: microseconds a point.
 */
#ifndef LUMESH_SAMP_RECORD_H
#define LUMESH_SAMP_RECORD_H

#include <stddef.h>

#include "sampling/samp.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct samp_record {
    double direct_us, indirect_us; /* GL's cheapest per point measured here; < 0: never measured */
} samp_record;

/* The record for desc's GL platform and resolutions on this host: 1 found, 0 none
 * (no file, no line, switched off). */
int samp_record_get(const samp_desc *desc, samp_record *out);
/* Keeps the lower of the stored and these costs (< 0: not measured, the stored one stays). */
void samp_record_note(const samp_desc *desc, double direct_us, double indirect_us);
/* The file, or "" when switched off or no directory is known. */
void samp_record_path(char *out, size_t size);

#ifdef __cplusplus
}
#endif

#endif
