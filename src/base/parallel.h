/* parallel.h — a loop spread over threads, for work whose iterations share
 * nothing but read-only data.
 *
 * Usage:
 *     lm_parallel_for(lm_thread_count(0), n, one, &job);   // one(&job, i) for i < n
 *
 * Threads: the caller's thread and up to threads − 1 threads started for the
 * call (joined before it returns); iterations are handed out in chunks of 16
 * from an atomic counter, so an iteration may run on any of them and in any
 * order. fn must not write anything another iteration reads or writes.
 *
 * Does NOT do: a pool kept between calls (a start costs ~20 µs a thread, nothing
 * next to the batches it is used for), reductions, cancellation, nesting limits.
 */
#ifndef LUMESH_BASE_PARALLEL_H
#define LUMESH_BASE_PARALLEL_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum { LM_MAX_THREADS = 64 };

/* Threads for `threads` asked: 0 = every online core; at most LM_MAX_THREADS. */
int lm_thread_count(int threads);

/* Calls fn(user, i) for every i < n over `threads` threads (the caller's among
 * them) and returns when all are done. If threads cannot be started, the
 * caller does it all. */
void lm_parallel_for(int threads, uint32_t n, void (*fn)(void *user, uint32_t i), void *user);

#ifdef __cplusplus
}
#endif
#endif
