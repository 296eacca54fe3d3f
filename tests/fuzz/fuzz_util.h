/* fuzz_util.h — what the libFuzzer harnesses share (docs/robustness.md).
 *
 * Every input is written to a file in a private directory made at start-up,
 * because the loaders under test read paths, not buffers (as `lumesh` does):
 * the harnesses exercise exactly the code a user's file meets.
 */
#ifndef LUMESH_FUZZ_UTIL_H
#define LUMESH_FUZZ_UTIL_H

#include <stddef.h>
#include <stdint.h>

/* The private directory (made on first use, under $TMPDIR or /tmp). */
const char *fuzz_dir(void);

/* Writes size bytes of data as fuzz_dir()/name and returns the full path in out.
 * 0 when the file cannot be written (the input is then skipped). */
int fuzz_write(const char *name, const uint8_t *data, size_t size, char *out, size_t out_size);

/* Writes fuzz_dir()/a.obj, a unit quad in y = 0 that scene descriptions under
 * test may name. 0 when it cannot be written. */
int fuzz_write_quad(void);

/* Loads path as `lumesh` does; a failure must be one line (else a trap: a
 * finding). */
void fuzz_load_scene(const char *path);

/* The file extension a harness tests, from $LUMESH_FUZZ_EXT, or fallback. */
const char *fuzz_ext(const char *fallback);

#endif
