/* util.h — result codes, error messages and small helpers shared by every module.
 *
 * Every library function that can fail returns an lm_result and, when given a
 * non-NULL lm_error, writes one line a user can act on (no trailing newline),
 * naming the file and the problem. Library code never exits and never prints
 * on its own; the command line decides what to show.
 *
 * Does NOT do: logging to stderr, allocation tracking, threading.
 */
#ifndef LUMESH_BASE_UTIL_H
#define LUMESH_BASE_UTIL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum lm_result {
    LM_OK = 0,
    LM_ERR_INVALID_ARG,  /* caller passed something meaningless (programming or usage error) */
    LM_ERR_IO,           /* a file could not be opened, read or written */
    LM_ERR_BAD_INPUT,    /* the input was read but its content is wrong */
    LM_ERR_NO_MEMORY,
    LM_ERR_UNSUPPORTED,  /* a feature this build or this machine does not have */
    LM_ERR_RUNTIME,      /* anything else that went wrong while working */
    LM_RESULT_COUNT
} lm_result;

typedef struct lm_error {
    char msg[1024];
} lm_error;

/* Formats into err->msg (if err is non-NULL) and returns code, so callers can
 * write `return lm_fail(err, LM_ERR_IO, "%s: cannot open: %s", path, why);`. */
lm_result lm_fail(lm_error *err, lm_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

const char *lm_result_name(lm_result r);

/* Monotonic wall clock in seconds. */
double lm_now_seconds(void);
/* Sleeps this many seconds (nothing for seconds <= 0; a signal may end it early). */
void lm_sleep_seconds(double seconds);

/* Reads a whole file into a NUL-terminated buffer (the NUL is not counted in
 * *size). Refuses files larger than max_bytes (0 means 1 GiB). */
lm_result lm_read_file(const char *path, size_t max_bytes, char **out_data, size_t *out_size,
                       lm_error *err);

/* Writes data[0..size) as the file target, whole or not at all: into a new
 * temporary file beside it ("<name>.tmp-<pid>-<n>.<ext>", made with O_EXCL so
 * that concurrent writers never share one), flushed to storage, then renamed
 * over it; on any error the target is as it was and the temporary file is gone.
 * The project's outputs go through it (images, statistics, CSV, the GL costs of
 * sampling/samp_record.h): never a partial file. */
lm_result lm_write_file(const char *target, const char *ext, const void *data, size_t size, lm_error *err);

/* Directory part of a path ("a/b/c.obj" -> "a/b", "c.obj" -> "."), into out. */
void lm_path_dir(const char *path, char *out, size_t out_size);
/* Joins dir and rel unless rel is absolute. Returns 0 if it did not fit. */
int lm_path_join(const char *dir, const char *rel, char *out, size_t out_size);
/* Lower-case extension without the dot ("" if none), into out. */
void lm_path_ext(const char *path, char *out, size_t out_size);

/* ---- growing arrays -------------------------------------------------------
 * The one way the project grows an array by doubling (instead of a hand-written
 * realloc loop at each site):
 *     float *v = NULL; size_t cap = 0;
 *     if (!LM_GROW(v, cap, n + 1)) return lm_fail(err, LM_ERR_NO_MEMORY, "...");
 *     v[n++] = x;
 * Several arrays that share one capacity (or a capacity kept in a narrower type)
 * take lm_grow_capacity once and lm_realloc_array per array. */

/* The capacity to grow to: cap doubled (from `first` when cap is 0; first 0 = 16)
 * until it holds `need`, but never beyond `max`; cap itself when it already holds
 * need; 0 when need > max (the caller reports the limit). */
size_t lm_grow_capacity(size_t cap, size_t need, size_t first, size_t max);

/* realloc of *ptr_to_ptr (any T **) from old_count to count elements of elem_size
 * bytes, the new elements zeroed. Returns 1; 0 when memory runs out or the size
 * passes PTRDIFF_MAX bytes, with the old block and *ptr_to_ptr unchanged. */
int lm_realloc_array(void *ptr_to_ptr, size_t old_count, size_t count, size_t elem_size);

/* Makes the array hold at least `need` elements (capacity *cap, doubled from 16):
 * 1 on success (new elements zeroed), 0 with nothing changed when memory runs out. */
int lm_grow_array(void *ptr_to_ptr, size_t *cap, size_t need, size_t elem_size);
#define LM_GROW(ptr, cap, need) lm_grow_array(&(ptr), &(cap), (need), sizeof *(ptr))

/* As lm_realloc_array and lm_grow_array, the new elements left as they are:
 * for arrays whose elements are written before they are read (appended to, or
 * filled whole). Zeroing the spare part of a doubled array touches every page
 * of it at once; on this project's measuring machine a first touch costs
 * ~5-10 µs a 4 KiB page, and a snapshot's publication zeroed several MB a
 * mesh that it then gave back unused (docs/cache.md, "The worker's memory in
 * huge pages"). Untouched, a block big enough to be mapped gets its pages
 * when they are written. */
int lm_realloc_array_raw(void *ptr_to_ptr, size_t old_count, size_t count, size_t elem_size);
int lm_grow_array_raw(void *ptr_to_ptr, size_t *cap, size_t need, size_t elem_size);
#define LM_GROW_RAW(ptr, cap, need) lm_grow_array_raw(&(ptr), &(cap), (need), sizeof *(ptr))

/* Copies at most n-1 bytes and always terminates. */
void lm_strlcpy(char *dst, const char *src, size_t n);

#ifdef __cplusplus
}
#endif
#endif
