/* util.h — result codes, error messages and small helpers shared by every module.
 *
 * Every library function that can fail returns an lm_result and, when given a
 * non-NULL lm_error, writes one line a user can act on (no trailing newline),
 * naming the file and the problem. Library code never exits and never prints
 * on its own; the command line decides what to show.
 *
 * Does NOT do: logging to stderr, allocation tracking, threading.
 */
#ifndef LUMESH_UTIL_H
#define LUMESH_UTIL_H

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

/* Reads a whole file into a NUL-terminated buffer (the NUL is not counted in
 * *size). Refuses files larger than max_bytes (0 means 1 GiB). */
lm_result lm_read_file(const char *path, size_t max_bytes, char **out_data, size_t *out_size,
                       lm_error *err);

/* Directory part of a path ("a/b/c.obj" -> "a/b", "c.obj" -> "."), into out. */
void lm_path_dir(const char *path, char *out, size_t out_size);
/* Joins dir and rel unless rel is absolute. Returns 0 if it did not fit. */
int lm_path_join(const char *dir, const char *rel, char *out, size_t out_size);
/* Lower-case extension without the dot ("" if none), into out. */
void lm_path_ext(const char *path, char *out, size_t out_size);

/* Copies at most n-1 bytes and always terminates. */
void lm_strlcpy(char *dst, const char *src, size_t n);

#ifdef __cplusplus
}
#endif
#endif
