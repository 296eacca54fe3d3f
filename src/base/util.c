/* util.c — result codes, error formatting, file reading and writing, path helpers. */
#define _POSIX_C_SOURCE 200809L
#include "src/base/util.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

lm_result lm_fail(lm_error *err, lm_result code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
        /* One line: a message never carries a newline (some come from libraries). */
        for (char *p = err->msg; *p; ++p)
            if (*p == '\n' || *p == '\r') *p = ' ';
    }
    return code;
}

const char *lm_result_name(lm_result r)
{
    switch (r) {
    case LM_OK: return "ok";
    case LM_ERR_INVALID_ARG: return "invalid argument";
    case LM_ERR_IO: return "input/output error";
    case LM_ERR_BAD_INPUT: return "bad input";
    case LM_ERR_NO_MEMORY: return "out of memory";
    case LM_ERR_UNSUPPORTED: return "unsupported";
    case LM_ERR_RUNTIME: return "runtime failure";
    case LM_RESULT_COUNT: break;
    }
    return "unknown result";
}

double lm_now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void lm_sleep_seconds(double seconds)
{
    if (!(seconds > 0)) return;
    struct timespec t = {(time_t)seconds, (long)((seconds - (double)(time_t)seconds) * 1e9)};
    nanosleep(&t, NULL);
}

lm_result lm_read_file(const char *path, size_t max_bytes, char **out_data, size_t *out_size,
                       lm_error *err)
{
    *out_data = NULL;
    *out_size = 0;
    if (max_bytes == 0) max_bytes = (size_t)1 << 30;
    struct stat st;
    if (stat(path, &st) != 0)
        return lm_fail(err, LM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (S_ISDIR(st.st_mode))
        return lm_fail(err, LM_ERR_IO, "%s: is a directory, not a file", path);
    /* A FIFO would block the open until something writes to it, a device may
     * never end: only regular files are read. */
    if (!S_ISREG(st.st_mode))
        return lm_fail(err, LM_ERR_IO, "%s: is not a regular file (a pipe, device or socket)", path);
    FILE *f = fopen(path, "rb");
    if (!f) return lm_fail(err, LM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = S_ISREG(st.st_mode) && st.st_size > 0 ? (size_t)st.st_size + 1 : 4096;
    if (cap > max_bytes + 1) {
        fclose(f);
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: file is larger than %zu bytes", path, max_bytes);
    }
    char *buf = malloc(cap);
    size_t len = 0;
    if (!buf) {
        fclose(f);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory reading the file", path);
    }
    for (;;) {
        if (len + 1 >= cap) {
            if (cap > max_bytes) {
                free(buf);
                fclose(f);
                return lm_fail(err, LM_ERR_BAD_INPUT, "%s: file is larger than %zu bytes", path,
                               max_bytes);
            }
            if (!LM_GROW(buf, cap, len + 2)) {
                free(buf);
                fclose(f);
                return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory reading the file", path);
            }
        }
        size_t got = fread(buf + len, 1, cap - 1 - len, f);
        len += got;
        if (got == 0) break;
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        free(buf);
        return lm_fail(err, LM_ERR_IO, "%s: read error", path);
    }
    buf[len] = '\0';
    *out_data = buf;
    *out_size = len;
    return LM_OK;
}

void lm_strlcpy(char *dst, const char *src, size_t n)
{
    if (n == 0) return;
    size_t i = 0;
    for (; src && src[i] && i + 1 < n; ++i) dst[i] = src[i];
    dst[i] = '\0';
}

void lm_path_dir(const char *path, char *out, size_t out_size)
{
    const char *slash = strrchr(path, '/');
    if (!slash) {
        lm_strlcpy(out, ".", out_size);
        return;
    }
    size_t n = (size_t)(slash - path);
    if (n == 0) n = 1; /* "/file" -> "/" */
    if (n + 1 > out_size) n = out_size - 1;
    memcpy(out, path, n);
    out[n] = '\0';
}

int lm_path_join(const char *dir, const char *rel, char *out, size_t out_size)
{
    int n;
    if (rel[0] == '/' || !dir || !dir[0])
        n = snprintf(out, out_size, "%s", rel);
    else if (dir[strlen(dir) - 1] == '/')
        n = snprintf(out, out_size, "%s%s", dir, rel);
    else
        n = snprintf(out, out_size, "%s/%s", dir, rel);
    return n >= 0 && (size_t)n < out_size;
}

void lm_path_ext(const char *path, char *out, size_t out_size)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    out[0] = '\0';
    if (!dot || (slash && dot < slash) || out_size == 0) return;
    size_t i = 0;
    for (const char *p = dot + 1; *p && i + 1 < out_size; ++p, ++i)
        out[i] = (char)((*p >= 'A' && *p <= 'Z') ? *p - 'A' + 'a' : *p);
    out[i] = '\0';
}

size_t lm_grow_capacity(size_t cap, size_t need, size_t first, size_t max)
{
    if (need > max) return 0;
    if (need <= cap) return cap;
    size_t c = cap ? cap : (first ? first : 16);
    while (c < need) c = c > max / 2 ? max : 2 * c;
    return c;
}

static int realloc_array(void *ptr_to_ptr, size_t old_count, size_t count, size_t elem_size, int zero)
{
    /* No object is larger than PTRDIFF_MAX bytes (and GCC refuses a realloc that could be). */
    if (elem_size && count > (size_t)PTRDIFF_MAX / elem_size) return 0;
    void *old;
    memcpy(&old, ptr_to_ptr, sizeof old);
    size_t bytes = count * elem_size;
    void *p = realloc(old, bytes ? bytes : 1);
    if (!p) return 0;
    if (zero && count > old_count) memset((char *)p + old_count * elem_size, 0, (count - old_count) * elem_size);
    memcpy(ptr_to_ptr, &p, sizeof p);
    return 1;
}

static int grow_array(void *ptr_to_ptr, size_t *cap, size_t need, size_t elem_size, int zero)
{
    if (need <= *cap) return 1;
    size_t c = lm_grow_capacity(*cap, need, 16, (size_t)PTRDIFF_MAX / (elem_size ? elem_size : 1));
    if (!c || !realloc_array(ptr_to_ptr, *cap, c, elem_size, zero)) return 0;
    *cap = c;
    return 1;
}

int lm_realloc_array(void *ptr_to_ptr, size_t old_count, size_t count, size_t elem_size)
{
    return realloc_array(ptr_to_ptr, old_count, count, elem_size, 1);
}

int lm_realloc_array_raw(void *ptr_to_ptr, size_t old_count, size_t count, size_t elem_size)
{
    return realloc_array(ptr_to_ptr, old_count, count, elem_size, 0);
}

int lm_grow_array(void *ptr_to_ptr, size_t *cap, size_t need, size_t elem_size)
{
    return grow_array(ptr_to_ptr, cap, need, elem_size, 1);
}

int lm_grow_array_raw(void *ptr_to_ptr, size_t *cap, size_t need, size_t elem_size)
{
    return grow_array(ptr_to_ptr, cap, need, elem_size, 0);
}

/* ---- lm_write_file: a file replaced whole or not at all ------------------ */

/* Per-process counter for temporary names; with the pid and O_EXCL it makes
 * concurrent writers (threads or processes) pick distinct names. */
static atomic_ulong temp_counter;

/* Creates (O_EXCL) an empty "<dir>/<base>.tmp-<pid>-<n>.<ext>" beside target,
 * open for writing, its name in name[PATH_MAX]. A long base name is shortened
 * so that the temporary name stays within NAME_MAX even when the target's name
 * is itself near the limit. */
static lm_result make_temp(const char *target, const char *ext, char name[PATH_MAX], int *fd_out, lm_error *err)
{
    *fd_out = -1;
    name[0] = '\0';
    const char *slash = strrchr(target, '/');
    size_t dir_len = slash ? (size_t)(slash - target) + 1 : 0;
    const char *base = target + dir_len;
    int last_errno = 0;
    for (int attempt = 0; attempt < 64; ++attempt) {
        char suffix[96];
        unsigned long n = atomic_fetch_add(&temp_counter, 1);
        snprintf(suffix, sizeof suffix, ".tmp-%ld-%lu.%s", (long)getpid(), n, ext);
        size_t room = (size_t)NAME_MAX - strlen(suffix), cut = strlen(base);
        if (cut > room) {
            cut = room;
            while (cut > 0 && ((unsigned char)base[cut] & 0xC0) == 0x80) --cut; /* not inside a UTF-8 sequence */
        }
        if (dir_len + cut + strlen(suffix) >= PATH_MAX)
            return lm_fail(err, LM_ERR_IO, "%s: the path is too long for a temporary file beside it", target);
        memcpy(name, target, dir_len + cut);
        strcpy(name + dir_len + cut, suffix);
        int fd = open(name, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) {
            *fd_out = fd;
            return LM_OK;
        }
        last_errno = errno;
        if (last_errno != EEXIST) break;
    }
    return lm_fail(err, LM_ERR_IO, "%s: cannot create temporary file %s: %s", target, name, strerror(last_errno));
}

/* Writes the whole buffer, then flushes it to stable storage and closes, so
 * that every error (short write, EFBIG, ENOSPC, EIO on writeback) is seen
 * before the file replaces the target. Closes fd in every case. */
static lm_result write_all(const char *target, const char *tmp, int fd, const unsigned char *data, size_t size,
                           lm_error *err)
{
    size_t done = 0;
    while (done < size) {
        ssize_t n = write(fd, data + done, size - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            lm_result r = lm_fail(err, LM_ERR_IO, "%s: cannot write temporary file %s: %s", target, tmp,
                                  n < 0 ? strerror(errno) : "no progress");
            close(fd);
            return r;
        }
        done += (size_t)n;
    }
    if (fsync(fd) != 0 && errno != EINVAL && errno != EROFS) { /* EINVAL: cannot sync */
        lm_result r = lm_fail(err, LM_ERR_IO, "%s: cannot flush temporary file %s: %s", target, tmp, strerror(errno));
        close(fd);
        return r;
    }
    if (close(fd) != 0)
        return lm_fail(err, LM_ERR_IO, "%s: cannot close temporary file %s: %s", target, tmp, strerror(errno));
    return LM_OK;
}

lm_result lm_write_file(const char *target, const char *ext, const void *data, size_t size, lm_error *err)
{
    char tmp[PATH_MAX];
    int fd = -1;
    lm_result r = make_temp(target, ext, tmp, &fd, err);
    if (r != LM_OK) return r;
    r = write_all(target, tmp, fd, (const unsigned char *)data, size, err);
    if (r == LM_OK && rename(tmp, target) != 0)
        r = lm_fail(err, LM_ERR_IO, "%s: cannot move %s into place: %s", target, tmp, strerror(errno));
    if (r != LM_OK) unlink(tmp);
    return r;
}
