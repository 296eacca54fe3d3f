/* cli.h — the `lumesh` command line: commands, exit codes, argument helpers.
 *
 * Exit codes (scripts rely on them): 0 ok, 1 usage, 2 bad input, 3 runtime failure.
 */
#ifndef LUMESH_CLI_H
#define LUMESH_CLI_H

#include "src/base/util.h"

enum {
    APP_EXIT_OK = 0,
    APP_EXIT_USAGE = 1,
    APP_EXIT_BAD_INPUT = 2,
    APP_EXIT_RUNTIME = 3
};

typedef struct app_command {
    const char *name;
    const char *summary;            /* one line for `lumesh --help` */
    const char *help;               /* full text for `lumesh NAME --help` */
    int (*run)(const struct app_command *cmd, int argc, char **argv); /* argv[0] is the command */
} app_command;

/* Maps a library result to the process exit code. */
int app_exit_for(lm_result r);

/* Prints "lumesh CMD: message" and the --help hint to stderr; returns APP_EXIT_USAGE. */
int app_usage_error(const app_command *cmd, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Prints "lumesh: message" (an lm_error line) to stderr; returns app_exit_for(r). */
int app_report(lm_result r, const lm_error *err);

int app_is_help(const char *arg);
/* Parses a whole decimal integer / finite number in [lo, hi]; returns 0 when it is not one. */
int app_parse_int(const char *s, long lo, long hi, long *out);
int app_parse_double(const char *s, double lo, double hi, double *out);

/* Option parsing shared by the commands: walks argv, fills known options,
 * collects positionals. Spec entries: name ("--width"), kind, destination. */
typedef enum app_opt_kind {
    APP_OPT_FLAG = 0,   /* int *: set to 1 */
    APP_OPT_STRING,     /* const char **: the next argument */
    APP_OPT_INT,        /* long *: the next argument, range lo..hi */
    APP_OPT_DOUBLE,     /* double *: the next argument, range lo..hi */
    APP_OPT_KIND_COUNT
} app_opt_kind;

typedef struct app_opt {
    const char *name;
    const char *alias;  /* e.g. "-o", or NULL */
    app_opt_kind kind;
    void *dest;
    double lo, hi;      /* numeric range */
    int seen;           /* set by app_parse_options */
} app_opt;

/* Returns APP_EXIT_OK, APP_EXIT_USAGE (message printed) or -1 when --help was
 * asked (help printed; caller returns APP_EXIT_OK). Positionals go to pos[]. */
int app_parse_options(const app_command *cmd, int argc, char **argv, app_opt *opts, int nopts,
                      const char **pos, int max_pos, int *npos);

/* The progress bars of render, reference and converge: `fraction` (clamped to
 * 0..1) of APP_PROGRESS_WIDTH characters as '#', the rest '.', into bar (NUL-ended). */
enum { APP_PROGRESS_WIDTH = 30 };
void app_progress_bar(double fraction, char bar[APP_PROGRESS_WIDTH + 1]);

/* Gives the heap's free pages back to the system (glibc's malloc_trim; nothing
 * elsewhere). Freed blocks below the mmap threshold (main.c: 1 MiB) stay resident
 * in the heap until then: after `render` frees its cache, ~30 MB on Water stayed
 * in the peak of what came next (docs/memory.md). Main thread, between phases. */
void app_return_freed_memory(void);

/* --sampler NAME, --gl NAME and --bounces K|auto (render, converge, view; NULL:
 * not given) into the session's sampler back end, GL platform and bounces
 * (rend_session.h), its other fields left alone: APP_EXIT_OK, or a usage error printed and APP_EXIT_USAGE. */
struct rend_session_desc;
int app_session_options(const app_command *cmd, const char *sampler, const char *gl, const char *bounces,
                        struct rend_session_desc *d);
/* "auto" → CACHE_BOUNCES_AUTO, "K" → K (1..CACHE_BOUNCES_MAX); else a usage error. */
int app_bounces_option(const app_command *cmd, const char *text, int *out);

int cmd_info(const app_command *cmd, int argc, char **argv);
int cmd_render(const app_command *cmd, int argc, char **argv);
int cmd_reference(const app_command *cmd, int argc, char **argv);
int cmd_compare(const app_command *cmd, int argc, char **argv);
int cmd_converge(const app_command *cmd, int argc, char **argv);
int cmd_view(const app_command *cmd, int argc, char **argv);

#endif
