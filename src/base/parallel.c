/* parallel.c — lm_parallel_for (parallel.h). */
#include "src/base/parallel.h"

#include <pthread.h>
#include <stdatomic.h>
#include <unistd.h>

int lm_thread_count(int threads)
{
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    int t = threads > 0 ? threads : (cores > 0 ? (int)cores : 1);
    return t > LM_MAX_THREADS ? LM_MAX_THREADS : t;
}

typedef struct parallel_job {
    void (*fn)(void *user, uint32_t i);
    void *user;
    uint32_t n;
    atomic_uint next; /* next chunk start; shared by the threads of one call */
} parallel_job;

enum { PARALLEL_CHUNK = 16 };

static void *parallel_worker(void *arg)
{
    parallel_job *job = arg;
    for (;;) {
        uint32_t start = atomic_fetch_add(&job->next, PARALLEL_CHUNK);
        if (start >= job->n) break;
        uint32_t end = start + PARALLEL_CHUNK < job->n ? start + PARALLEL_CHUNK : job->n;
        for (uint32_t i = start; i < end; ++i) job->fn(job->user, i);
    }
    return NULL;
}

void lm_parallel_for(int threads, uint32_t n, void (*fn)(void *user, uint32_t i), void *user)
{
    parallel_job job = {.fn = fn, .user = user, .n = n};
    atomic_init(&job.next, 0);
    int want = (int)((n + PARALLEL_CHUNK - 1) / PARALLEL_CHUNK);
    int nt = threads < want ? threads : want;
    if (nt > LM_MAX_THREADS) nt = LM_MAX_THREADS;
    pthread_t tid[LM_MAX_THREADS];
    int started = 0;
    for (int i = 1; i < nt; ++i)
        if (pthread_create(&tid[started], NULL, parallel_worker, &job) == 0) started++;
    parallel_worker(&job); /* the caller works too; if threads failed it does it all */
    for (int i = 0; i < started; ++i) pthread_join(tid[i], NULL);
}
