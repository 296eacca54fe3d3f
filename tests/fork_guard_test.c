/* fork_guard_test.c — lm_fork_guarded waits for threads inside the guard; a
 * child forked while another thread keeps registering exit functions (what a
 * loading shared object does, under the C library's exit-function lock) never
 * blocks; a child can take the guard and fork again. Without the guard the
 * second case hung children (the GL context made beside the scene load,
 * docs/renderer.md); built with -DFORK_UNGUARDED, plain fork() fails it within
 * a few forks. A child that forgot the lock it inherited failed the third
 * (scene_mitsuba_test hung on it: a texture read in Assimp's child). */
#define _POSIX_C_SOURCE 200809L
#include "src/base/fork_guard.h"
#include "src/base/util.h"
#include "tests/test_util.h"

#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#ifdef FORK_UNGUARDED
#define FORK() fork()
#define GUARD_ENTER() ((void)0)
#define GUARD_LEAVE() ((void)0)
#else
#define FORK() lm_fork_guarded()
#define GUARD_ENTER() lm_fork_guard_enter()
#define GUARD_LEAVE() lm_fork_guard_leave()
#endif

/* Waits up to `seconds` for the child; 1 if it exited with status 0. A child that
 * has not exited by then is killed (the test fails instead of hanging). */
static int child_exited_ok(pid_t pid, double seconds)
{
    double until = lm_now_seconds() + seconds;
    int status = 0;
    for (;;) {
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid) return WIFEXITED(status) && WEXITSTATUS(status) == 0;
        if (w < 0 || lm_now_seconds() > until) break;
        lm_sleep_seconds(0.001);
    }
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    return 0;
}

static atomic_int inside, left;

static void *hold_guard(void *user)
{
    (void)user;
    GUARD_ENTER();
    atomic_store(&inside, 1);
    lm_sleep_seconds(0.15);
    atomic_store(&left, 1);
    GUARD_LEAVE();
    return NULL;
}

/* A fork asked for while a thread is inside waits until it leaves: the child's
 * memory shows the thread had left. */
static void test_waits_for_starters(void)
{
    pthread_t t;
    CHECK(pthread_create(&t, NULL, hold_guard, NULL) == 0);
    while (!atomic_load(&inside)) lm_sleep_seconds(0.001);
    double t0 = lm_now_seconds();
    pid_t pid = FORK();
    if (pid == 0) _exit(atomic_load(&left) ? 0 : 1);
    double waited = lm_now_seconds() - t0;
    CHECK(pid > 0);
    CHECK_MSG(child_exited_ok(pid, 10), "the child was forked while a thread was inside the guard");
    CHECK_MSG(waited > 0.05, "the fork waited %.3f s for a thread that held the guard 0.15 s", waited);
    pthread_join(t, NULL);
}

static void nothing(void)
{
}

static atomic_int stop;

/* What a shared object's constructors do while it loads: exit functions
 * registered, each under the C library's lock. */
static void *register_exit_functions(void *user)
{
    (void)user;
    while (!atomic_load(&stop)) {
        GUARD_ENTER();
        for (int i = 0; i < 64; ++i) atexit(nothing);
        GUARD_LEAVE();
    }
    return NULL;
}

/* Children that register an exit function themselves (as Assimp's function
 * statics do in scene_isolate's child) all exit. */
static void test_children_never_block(void)
{
    atomic_store(&stop, 0);
    pthread_t t;
    CHECK(pthread_create(&t, NULL, register_exit_functions, NULL) == 0);
    int blocked = 0, forks = 0;
    double until = lm_now_seconds() + 2.0;
    while (lm_now_seconds() < until && !blocked) {
        pid_t pid = FORK();
        if (pid == 0) {
            atexit(nothing);
            _exit(0);
        }
        if (pid < 0) break;
        forks++;
        if (!child_exited_ok(pid, 5)) blocked++;
    }
    atomic_store(&stop, 1);
    pthread_join(t, NULL);
    CHECK_MSG(forks > 20, "only %d forks in 2 s", forks);
    CHECK_MSG(blocked == 0, "a child forked beside a thread registering exit functions blocked (%d of %d forks)",
              blocked, forks);
}

/* A child may load a library (a texture's reader opens the image module) and
 * fork again: the guard it inherited is usable. */
static void test_child_uses_guard(void)
{
    pid_t pid = FORK();
    if (pid == 0) {
        GUARD_ENTER();
        GUARD_LEAVE();
        pid_t grandchild = FORK();
        if (grandchild == 0) _exit(0);
        _exit(grandchild > 0 && child_exited_ok(grandchild, 5) ? 0 : 1);
    }
    CHECK(pid > 0);
    CHECK_MSG(child_exited_ok(pid, 10), "a forked child could not take the guard or fork again");
}

int main(void)
{
    test_child_uses_guard();
    test_waits_for_starters();
    test_children_never_block();
    return test_finish("fork_guard_test");
}
