/* fork_guard.h — fork() kept apart from threads that are starting libraries.
 *
 * Usage:
 *     lm_fork_guard_enter();  ...dlopen, a driver's start (eglInitialize)...  lm_fork_guard_leave();
 *     pid_t pid = lm_fork_guarded();   // instead of fork()
 *
 * Why: a forked child has only the forking thread, and every lock as it was at
 * the fork. A thread that is loading a shared object or running its
 * constructors holds the C library's loader and exit-function locks; a child
 * forked then blocks for good at its first atexit() or dlopen(). It happened:
 * `converge` makes its GL context on a helper thread while the scene loads
 * (rend_session_early_gl), scene_isolate forks Assimp's child meanwhile, and the
 * child hung in __cxa_atexit (tests/converge_cli.cmake, 1 run in 40 on a loaded
 * machine; docs/renderer.md). A CPU-time limit cannot catch a child that sleeps
 * (scene_isolate watches for one: no CPU time and nothing sent, then a new fork).
 *
 * Threads: enter/leave on any thread, nested across threads (a reader-writer
 * lock: many starters at once); lm_fork_guarded waits until no thread is inside
 * and keeps new ones out until fork() has returned in the parent.
 *
 * In the child the guard is new (unlocked): it may load a library and fork too.
 *
 * Does NOT do: guard libraries' own threads (idle pools waiting on a condition
 * hold no C library lock; a library whose threads work during a fork is not
 * ours to fork beside), guard the allocator (glibc's malloc is fork-safe,
 * ASan's is not: a thread of ours allocating at the fork can leave the child
 * asleep), or make the child's code fork-safe: the child still runs only the
 * reader and plain C library calls (scene_isolate.c).
 */
#ifndef LUMESH_BASE_FORK_GUARD_H
#define LUMESH_BASE_FORK_GUARD_H

#include <sys/types.h>

#ifdef __cplusplus
extern "C" {
#endif

void lm_fork_guard_enter(void);
void lm_fork_guard_leave(void);
/* fork() once no thread is between enter and leave; its result, errno as fork's. */
pid_t lm_fork_guarded(void);

#ifdef __cplusplus
}
#endif

#endif
