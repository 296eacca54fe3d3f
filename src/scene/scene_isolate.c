/* scene_isolate.c — a third-party reader run in a child process.
 *
 * Assimp parses files from anywhere, and fuzzing found it crashing (a texture
 * line before an MTL's first newmtl), looping forever (a broken PLY header) and
 * leaking (OBJ and glTF files) on malformed input; we cannot fix a system
 * library, and each guard in scene_guard.c answers one case only. So the import
 * runs in a forked child: it fills an empty builder, sends it through a pipe and
 * exits. Whatever the reader does wrong dies with the child and comes back as
 * one line: a crash (by its signal), a hang (a CPU-time limit, SIGXCPU), a
 * failed allocation. A child that sleeps for good (a lock copied held by the
 * fork) is noticed by the parent (no CPU time and nothing sent for 10 s),
 * killed and forked again (run_child). What it leaks is the child's. Assimp's
 * scene graph also lives only in the child, so the parent's peak memory is the
 * builder's.
 *
 * The child runs only the reader and plain C library calls (no threads, no GL,
 * no Embree), which is what fork() in a threaded process allows in practice with
 * glibc (malloc is fork-safe there), and it is forked only while no thread of
 * ours is loading a library (lm_fork_guarded: a GL context made beside the load
 * once left the child blocked in atexit for good). The child restores the default action of
 * the crash signals, so a crash ends it by its signal whatever handlers the
 * parent installed. LUMESH_IMPORT_IN_PROCESS=1 runs the reader in the process
 * instead (for a debugger), as does a failed fork().
 *
 * Wire format, in order, native byte order (the same program on both ends): the
 * result code and message; counts; the triangle arrays; materials, parts, point
 * lights, cameras (fixed-size structs); notes (length-prefixed); the
 * number-guard count.
 */
#define _POSIX_C_SOURCE 200809L /* fork, pipe, setrlimit, kill */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "src/base/fork_guard.h"
#include "src/scene/scene_internal.h"

/* CPU seconds one reader child may use: generous for a large file (Assimp reads
 * a 100 MB OBJ in well under a minute here, the 116k-triangle PLYs in 0.15 s),
 * finite for a loop, and short enough that a child spinning on a lock it was
 * copied with (below) is ended and forked again within seconds.
 * LUMESH_READER_CPU_SECONDS overrides it (bench/fuzz.sh: below libFuzzer's timeout). */
static rlim_t cpu_limit_seconds(const char *path)
{
    const char *env = getenv("LUMESH_READER_CPU_SECONDS");
    if (env && atoi(env) > 0) return (rlim_t)atoi(env);
    struct stat st;
    double mb = stat(path, &st) == 0 ? (double)st.st_size / (1 << 20) : 0.0;
    return (rlim_t)(10.0 + 2.0 * mb);
}

/* ---- the child's side: write everything, then _exit ---------------------- */

static int put(int fd, const void *p, size_t n)
{
    const char *c = p;
    while (n) {
        ssize_t w = write(fd, c, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return 0;
        c += w;
        n -= (size_t)w;
    }
    return 1;
}

static int put_builder(int fd, lm_result r, const lm_error *err, const scene_builder *b)
{
    uint64_t counts[6] = {(uint64_t)b->count, b->mat_count, b->part_count, b->point_count, b->cam_count,
                          b->note_count};
    int32_t code = (int32_t)r;
    int ok = put(fd, &code, sizeof code) && put(fd, err->msg, sizeof err->msg) && put(fd, counts, sizeof counts);
    if (!ok || r != LM_OK) return ok;
    ok = put(fd, b->pos, b->count * 9 * sizeof *b->pos) && put(fd, b->nrm, b->count * 9 * sizeof *b->nrm) &&
         put(fd, b->mat, b->count * sizeof *b->mat) && put(fd, b->part, b->count * sizeof *b->part) &&
         put(fd, b->mats, b->mat_count * sizeof *b->mats) && put(fd, b->parts, b->part_count * sizeof *b->parts) &&
         put(fd, b->points, b->point_count * sizeof *b->points) && put(fd, b->cams, b->cam_count * sizeof *b->cams);
    for (uint32_t i = 0; ok && i < b->note_count; ++i) {
        uint32_t len = (uint32_t)strlen(b->notes[i]);
        ok = put(fd, &len, sizeof len) && put(fd, b->notes[i], len);
    }
    return ok && put(fd, &b->numbers_too_large, sizeof b->numbers_too_large);
}

/* ---- the parent's side: read the child's builder into b ------------------ */

typedef struct wire {
    const char *at, *end;
} wire;

static int get(wire *w, void *out, size_t n)
{
    if ((size_t)(w->end - w->at) < n) return 0;
    memcpy(out, w->at, n);
    w->at += n;
    return 1;
}

/* Appends the child's builder (in w) to b: its materials and parts after b's,
 * material 0 standing for `override` when override >= 0. */
static lm_result merge(scene_builder *b, wire *w, int32_t override, const char *what, lm_error *err)
{
    int32_t code;
    lm_error child_err;
    uint64_t counts[6];
    if (!get(w, &code, sizeof code) || !get(w, child_err.msg, sizeof child_err.msg) || !get(w, counts, sizeof counts))
        return lm_fail(err, LM_ERR_RUNTIME, "%s: the reader's process ended before it answered", what);
    child_err.msg[sizeof child_err.msg - 1] = '\0';
    if (code != LM_OK) return lm_fail(err, (lm_result)code, "%s", child_err.msg);
    const uint64_t n = counts[0];
    const size_t tri_bytes = 9 * sizeof(double) + 9 * sizeof(float) + 2 * sizeof(uint32_t);
    if (n > (size_t)(w->end - w->at) / tri_bytes || counts[1] > UINT32_MAX || counts[2] > UINT32_MAX)
        return lm_fail(err, LM_ERR_RUNTIME, "%s: the reader's process sent a short answer", what);
    const char *tris = w->at;
    w->at += n * tri_bytes;
    /* With an override, the child's material 0 is the parent's override: not added again. */
    const uint32_t skip = override >= 0 ? 1 : 0;
    uint32_t mat_base = b->mat_count, part_base = b->part_count;
    lm_result r = LM_OK;
    for (uint64_t i = 0; r == LM_OK && i < counts[1]; ++i) {
        scene_material m;
        uint32_t idx;
        if (!get(w, &m, sizeof m)) return lm_fail(err, LM_ERR_RUNTIME, "%s: short answer (materials)", what);
        m.name[sizeof m.name - 1] = '\0';
        if (i >= skip) r = scene_builder_add_material(b, &m, &idx, err);
    }
    for (uint64_t i = 0; r == LM_OK && i < counts[2]; ++i) {
        scene_part p;
        uint32_t idx;
        if (!get(w, &p, sizeof p)) return lm_fail(err, LM_ERR_RUNTIME, "%s: short answer (parts)", what);
        p.name[sizeof p.name - 1] = p.source[sizeof p.source - 1] = '\0';
        r = scene_builder_add_part(b, p.name, p.source, &idx, err);
    }
    for (uint64_t i = 0; r == LM_OK && i < counts[3]; ++i) {
        scene_builder_point_light p;
        if (!get(w, &p, sizeof p)) return lm_fail(err, LM_ERR_RUNTIME, "%s: short answer (lights)", what);
        r = scene_builder_add_point_light(b, &p, err);
    }
    for (uint64_t i = 0; r == LM_OK && i < counts[4]; ++i) {
        scene_builder_camera c;
        if (!get(w, &c, sizeof c)) return lm_fail(err, LM_ERR_RUNTIME, "%s: short answer (cameras)", what);
        c.cam.name[sizeof c.cam.name - 1] = '\0';
        r = scene_builder_add_camera(b, &c, err);
    }
    for (uint64_t i = 0; r == LM_OK && i < counts[5]; ++i) {
        uint32_t len;
        char note[512];
        if (!get(w, &len, sizeof len) || len >= sizeof note || !get(w, note, len))
            return lm_fail(err, LM_ERR_RUNTIME, "%s: short answer (notes)", what);
        note[len] = '\0';
        scene_builder_note(b, "%s", note);
    }
    uint32_t too_large = 0;
    if (r == LM_OK && !get(w, &too_large, sizeof too_large))
        return lm_fail(err, LM_ERR_RUNTIME, "%s: short answer", what);
    b->numbers_too_large += too_large;
    /* The triangles last: their material and part ids are now known. */
    const char *pos = tris, *nrm = pos + n * 9 * sizeof(double), *mat = nrm + n * 9 * sizeof(float),
               *part = mat + n * sizeof(uint32_t);
    for (uint64_t i = 0; r == LM_OK && i < n; ++i) {
        double p[9];
        float nv[9];
        uint32_t m, pt;
        memcpy(p, pos + i * sizeof p, sizeof p);
        memcpy(nv, nrm + i * sizeof nv, sizeof nv);
        memcpy(&m, mat + i * sizeof m, sizeof m);
        memcpy(&pt, part + i * sizeof pt, sizeof pt);
        uint32_t material = skip && m == 0 ? (uint32_t)override : m < counts[1] ? mat_base + m - skip : UINT32_MAX;
        r = scene_builder_add_triangle(b, p, nv, material, pt < counts[2] ? part_base + pt : part_base, err);
    }
    return r;
}

/* The last non-empty line the child wrote to f (its stderr), without the
 * newline, "" when none. */
static void last_line(FILE *f, char *out, size_t size)
{
    out[0] = '\0';
    if (!f || fseek(f, 0, SEEK_SET) != 0) return;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\r\n")] = '\0';
        if (line[0]) lm_strlcpy(out, line, size);
    }
}

static void print_all(FILE *f, FILE *to)
{
    char line[512];
    if (!f || fseek(f, 0, SEEK_SET) != 0) return;
    while (fgets(line, sizeof line, f)) fputs(line, to);
}

/* Why a child that sent no complete answer ended, as the user's one line; detail:
 * the last line the reader printed, or "". */
static lm_result child_failure(int status, const char *what, const char *detail, lm_error *err)
{
    const char *sep = detail[0] ? ": " : "";
    if (WIFSIGNALED(status)) {
        int sig = WTERMSIG(status);
        if (sig == SIGXCPU || sig == SIGKILL)
            return lm_fail(err, LM_ERR_BAD_INPUT, "%s: the file reader (Assimp) ran out of time on this file", what);
        if (sig == SIGINT || sig == SIGTERM) /* Ctrl-C reaches the whole process group */
            return lm_fail(err, LM_ERR_RUNTIME, "%s: loading was interrupted", what);
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: the file reader (Assimp) crashed on this file (signal %d, %s)%s%s",
                       what, sig, strsignal(sig), sep, detail);
    }
    return lm_fail(err, LM_ERR_BAD_INPUT, "%s: the file reader (Assimp) failed on this file (exit status %d)%s%s",
                   what, WIFEXITED(status) ? WEXITSTATUS(status) : -1, sep, detail);
}

/* The child's CPU time so far, in clock ticks (utime + stime, fields 14 and 15
 * of /proc/PID/stat, counted after the command name's closing parenthesis); -1
 * when it cannot be read (no /proc: no stall is ever declared). */
static long long child_cpu_ticks(pid_t pid)
{
    char path[64], line[1024];
    snprintf(path, sizeof path, "/proc/%ld/stat", (long)pid);
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    size_t n = fread(line, 1, sizeof line - 1, f);
    fclose(f);
    line[n] = '\0';
    const char *p = strrchr(line, ')');
    long long utime = 0, stime = 0;
    if (!p || sscanf(p + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lld %lld", &utime, &stime) != 2) return -1;
    return utime + stime;
}

/* Wall seconds a child may sit with no CPU time and nothing sent before it is
 * taken for stalled. LUMESH_READER_STALL_SECONDS overrides it (the tests). */
static double stall_limit_seconds(void)
{
    const char *env = getenv("LUMESH_READER_STALL_SECONDS");
    double s = env ? atof(env) : 0.0;
    return s > 0.0 ? s : 10.0;
}

/* Children forked in all: for one that stalled, and for one that ran out of
 * CPU time (a file that loops does so again; a child that spun on a copied
 * lock does not). */
enum { READER_TRIES = 3, READER_TIME_TRIES = 2 };

typedef enum { CHILD_DONE, CHILD_STALLED, CHILD_OUT_OF_TIME, CHILD_NOT_FORKED } child_outcome;

/* One child: forks it, reads all it sends into *buf, reaps it. CHILD_STALLED:
 * it sat asleep (no CPU time, nothing sent) for the stall limit and was killed.
 * CHILD_OUT_OF_TIME: its CPU-time limit ended it. Why a child never finishes
 * although its file is good: fork() copies every lock as it was, and a lock
 * held at that moment by another thread (an allocator's: glibc's malloc is
 * fork-safe, ASan's in Debian 12's GCC is not) is never released in the child.
 * ASan's blocking locks leave it asleep (it happened to `view`'s reload while
 * the worker refined); its spin locks leave it spinning, using CPU time until
 * the limit (rend_session_test in CI, the load after GL work: 1 run in 6-12 with
 * a cold Mesa shader cache, whose writer thread allocates). The CPU-time limit
 * ends a reader that loops or spins, not one that sleeps. */
static child_outcome run_child(scene_builder *b, const char *what, int32_t material_override, scene_fill_fn fill,
                               void *user, int attempt, char **buf, size_t *len, size_t *cap, int *status,
                               FILE **child_err, lm_result *r, lm_error *err)
{
    int fds[2];
    if (pipe(fds) != 0) return CHILD_NOT_FORKED;
    fflush(NULL); /* nothing buffered may be written twice */
    *child_err = tmpfile(); /* what the reader prints (Assimp's assertions): the message's detail */
    pid_t pid = lm_fork_guarded(); /* not while another thread starts a library */
    if (pid < 0) {
        close(fds[0]);
        close(fds[1]);
        return CHILD_NOT_FORKED;
    }
    if (pid == 0) { /* the child: fill an empty builder (material 0: the override), send it, leave */
        close(fds[0]);
        /* A crash dies by its signal, whatever handlers the parent had (a
         * sanitizer's, libFuzzer's, the command line's): the parent reads it. */
        static const int crashes[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT, SIGXCPU, SIGINT};
        for (size_t i = 0; i < sizeof crashes / sizeof crashes[0]; ++i) signal(crashes[i], SIG_DFL);
        if (*child_err) dup2(fileno(*child_err), STDERR_FILENO); /* the user sees one line, from the parent */
        const rlim_t seconds = cpu_limit_seconds(what);
        struct rlimit cpu = {seconds, seconds + 5};
        setrlimit(RLIMIT_CPU, &cpu);
        /* Fault injection for the tests (tests/cli_tests.cmake): a reader that
         * crashes, one that spins for good, one that sleeps for good (either
         * every time, or only the first: the next child loads). */
        const char *fault = getenv("LUMESH_FAULT_INJECT");
        if (fault && strcmp(fault, "reader-crash") == 0) raise(SIGSEGV);
        if (fault && (strcmp(fault, "reader-hang") == 0 || (strcmp(fault, "reader-hang-once") == 0 && attempt == 0))) {
            struct rlimit one = {1, 2};
            setrlimit(RLIMIT_CPU, &one);
            for (volatile unsigned long spin = 0;; ++spin) {
            }
        }
        if (fault && (strcmp(fault, "reader-sleep") == 0 || (strcmp(fault, "reader-sleep-once") == 0 && attempt == 0)))
            for (;;) pause();
        scene_builder cb;
        memset(&cb, 0, sizeof cb);
        cb.source = b->source;
        lm_error cerr;
        memset(&cerr, 0, sizeof cerr);
        lm_result cr = LM_OK;
        uint32_t zero;
        if (material_override >= 0) cr = scene_builder_add_material(&cb, &b->mats[material_override], &zero, &cerr);
        if (cr == LM_OK) cr = fill(&cb, user, material_override >= 0 ? 0 : -1, &cerr);
        int ok = put_builder(fds[1], cr, &cerr, &cb);
        close(fds[1]);
        _exit(ok ? 0 : 3); /* no atexit handlers, no leak check: the child's memory goes with it */
    }
    close(fds[1]);
    const double stall = stall_limit_seconds();
    long long ticks = child_cpu_ticks(pid);
    double quiet_since = lm_now_seconds();
    child_outcome out = CHILD_DONE;
    *len = 0;
    for (;;) {
        if (*len == *cap && !LM_GROW(*buf, *cap, *len + (1 << 16))) {
            *r = lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory reading the file's triangles", what);
            kill(pid, SIGKILL);
            break;
        }
        struct pollfd pfd = {.fd = fds[0], .events = POLLIN};
        int ready = poll(&pfd, 1, 250);
        if (ready < 0 && errno == EINTR) continue;
        if (ready == 0) { /* nothing sent: is the child working? */
            long long now_ticks = child_cpu_ticks(pid);
            if (now_ticks < 0 || now_ticks != ticks) {
                ticks = now_ticks;
                quiet_since = lm_now_seconds();
            } else if (lm_now_seconds() - quiet_since >= stall) {
                kill(pid, SIGKILL);
                out = CHILD_STALLED;
                break;
            }
            continue;
        }
        ssize_t got = read(fds[0], *buf + *len, *cap - *len);
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0) break;
        *len += (size_t)got;
        quiet_since = lm_now_seconds();
    }
    close(fds[0]);
    while (waitpid(pid, status, 0) < 0 && errno == EINTR) {
    }
    if (out == CHILD_DONE && *r == LM_OK && WIFSIGNALED(*status) &&
        (WTERMSIG(*status) == SIGXCPU || WTERMSIG(*status) == SIGKILL)) /* SIGKILL: past the hard limit */
        out = CHILD_OUT_OF_TIME;
    return out;
}

lm_result scene_isolate(scene_builder *b, const char *what, int32_t material_override, scene_fill_fn fill,
                        void *user, lm_error *err)
{
    const char *inproc = getenv("LUMESH_IMPORT_IN_PROCESS");
    if (inproc && inproc[0] == '1') return fill(b, user, material_override, err);
    char *buf = NULL;
    size_t len = 0, cap = 0;
    lm_result r = LM_OK;
    int status = 0, attempt = 0;
    FILE *child_err = NULL;
    child_outcome out = CHILD_STALLED;
    for (; r == LM_OK && ((out == CHILD_STALLED && attempt < READER_TRIES) ||
                          (out == CHILD_OUT_OF_TIME && attempt < READER_TIME_TRIES));
         ++attempt) {
        if (child_err) fclose(child_err);
        child_err = NULL;
        out = run_child(b, what, material_override, fill, user, attempt, &buf, &len, &cap, &status, &child_err, &r,
                        err);
    }
    if (out == CHILD_NOT_FORKED) { /* no pipe or no fork: the reader in the process */
        free(buf);
        if (child_err) fclose(child_err);
        return fill(b, user, material_override, err);
    }
    if (r == LM_OK && out == CHILD_STALLED)
        r = lm_fail(err, LM_ERR_RUNTIME,
                    "%s: the file reader's process (Assimp) slept for %g s without using the CPU or sending "
                    "anything, %d times in a row; try again, or set LUMESH_IMPORT_IN_PROCESS=1",
                    what, stall_limit_seconds(), attempt);
    if (r == LM_OK) {
        if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
            /* Any other exit status is not the reader's: a sanitizer's report on our
             * own code in the child (ASan exits 1). LUMESH_READER_STRICT=1 (the
             * fuzzing harnesses) makes that the parent's crash, so it is found. */
            char detail[256];
            last_line(child_err, detail, sizeof detail);
            const char *strict = getenv("LUMESH_READER_STRICT");
            if (strict && strict[0] == '1' && WIFEXITED(status) && WEXITSTATUS(status) != 3) {
                print_all(child_err, stderr); /* the sanitizer's report */
                abort();
            }
            r = child_failure(status, what, detail, err);
        } else {
            wire w = {buf, buf + len};
            r = merge(b, &w, material_override, what, err);
        }
    }
    free(buf);
    if (child_err) fclose(child_err);
    return r;
}
