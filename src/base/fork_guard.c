/* fork_guard.c — a reader-writer lock between library start-up and fork()
 * (fork_guard.h). */
#define _POSIX_C_SOURCE 200809L /* fork, pthread_rwlock */
#include "src/base/fork_guard.h"

#include <errno.h>
#include <pthread.h>
#include <unistd.h>

/* Shared by every thread: the starters hold it for reading, a fork for writing. */
static pthread_rwlock_t g_fork_lock = PTHREAD_RWLOCK_INITIALIZER;

void lm_fork_guard_enter(void)
{
    pthread_rwlock_rdlock(&g_fork_lock);
}

void lm_fork_guard_leave(void)
{
    pthread_rwlock_unlock(&g_fork_lock);
}

pid_t lm_fork_guarded(void)
{
    pthread_rwlock_wrlock(&g_fork_lock);
    pid_t pid = fork();
    int saved = errno;
    if (pid != 0) {
        pthread_rwlock_unlock(&g_fork_lock); /* the parent (or no child): let the starters in again */
    } else {
        /* The child has the lock write-held by a thread it does not have (its one
         * thread has another id), and may load a library itself (a texture's reader:
         * the image module). It is the only thread here: a new lock is safe. */
        pthread_rwlock_t fresh = PTHREAD_RWLOCK_INITIALIZER;
        g_fork_lock = fresh;
    }
    errno = saved;
    return pid;
}
