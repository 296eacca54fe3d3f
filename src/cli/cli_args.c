/* cli_args.c — argument parsing and error reporting shared by the commands. */
#include <errno.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache.h"
#include "src/cli/cli.h"
#include "src/render/rend_session.h"

int app_exit_for(lm_result r)
{
    switch (r) {
    case LM_OK: return APP_EXIT_OK;
    case LM_ERR_INVALID_ARG: return APP_EXIT_USAGE;
    case LM_ERR_IO:
    case LM_ERR_BAD_INPUT: return APP_EXIT_BAD_INPUT;
    default: return APP_EXIT_RUNTIME;
    }
}

int app_usage_error(const app_command *cmd, const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "lumesh %s: ", cmd->name);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\nTry 'lumesh %s --help'.\n", cmd->name);
    return APP_EXIT_USAGE;
}

int app_report(lm_result r, const lm_error *err)
{
    fprintf(stderr, "lumesh: %s\n", err->msg[0] ? err->msg : lm_result_name(r));
    return app_exit_for(r);
}

int app_is_help(const char *arg)
{
    return strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0;
}

int app_parse_int(const char *s, long lo, long hi, long *out)
{
    if (!s || !*s) return 0;
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || v < lo || v > hi) return 0;
    *out = v;
    return 1;
}

int app_parse_double(const char *s, double lo, double hi, double *out)
{
    if (!s || !*s) return 0;
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || *end || !isfinite(v) || v < lo || v > hi) return 0;
    *out = v;
    return 1;
}

int app_parse_options(const app_command *cmd, int argc, char **argv, app_opt *opts, int nopts,
                      const char **pos, int max_pos, int *npos)
{
    *npos = 0;
    int only_positional = 0;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (!only_positional && app_is_help(a)) {
            fputs(cmd->help, stdout);
            return -1;
        }
        if (!only_positional && strcmp(a, "--") == 0) {
            only_positional = 1;
            continue;
        }
        if (!only_positional && a[0] == '-' && a[1] != '\0') {
            app_opt *o = NULL;
            for (int k = 0; k < nopts; ++k)
                if (strcmp(a, opts[k].name) == 0 || (opts[k].alias && strcmp(a, opts[k].alias) == 0))
                    o = &opts[k];
            if (!o) return app_usage_error(cmd, "unknown option '%s'", a);
            if (o->seen) return app_usage_error(cmd, "option %s given twice", o->name);
            o->seen = 1;
            if (o->kind == APP_OPT_FLAG) {
                *(int *)o->dest = 1;
                continue;
            }
            if (i + 1 >= argc) return app_usage_error(cmd, "option %s needs a value", o->name);
            const char *v = argv[++i];
            if (o->kind == APP_OPT_STRING) {
                *(const char **)o->dest = v;
            } else if (o->kind == APP_OPT_INT) {
                if (!app_parse_int(v, (long)o->lo, (long)o->hi, (long *)o->dest))
                    return app_usage_error(cmd, "%s wants a whole number from %.0f to %.0f, not '%s'",
                                           o->name, o->lo, o->hi, v);
            } else {
                if (!app_parse_double(v, o->lo, o->hi, (double *)o->dest))
                    return app_usage_error(cmd, "%s wants a number from %g to %g, not '%s'", o->name,
                                           o->lo, o->hi, v);
            }
            continue;
        }
        if (*npos >= max_pos) return app_usage_error(cmd, "unexpected argument '%s'", a);
        pos[(*npos)++] = a;
    }
    return APP_EXIT_OK;
}

int app_bounces_option(const app_command *cmd, const char *text, int *out)
{
    if (strcmp(text, "auto") == 0) {
        *out = CACHE_BOUNCES_AUTO;
        return APP_EXIT_OK;
    }
    char *end = NULL;
    long k = strtol(text, &end, 10);
    if (end == text || *end || k < 1 || k > CACHE_BOUNCES_MAX)
        return app_usage_error(cmd, "--bounces is 1..%d or auto, not '%s'", CACHE_BOUNCES_MAX, text);
    *out = (int)k;
    return APP_EXIT_OK;
}

int app_session_options(const app_command *cmd, const char *sampler, const char *gl, const char *bounces,
                        rend_session_desc *d)
{
    if (bounces) {
        int rc = app_bounces_option(cmd, bounces, &d->bounces);
        if (rc != APP_EXIT_OK) return rc;
    }
    if (sampler && !samp_backend_from_name(sampler, &d->sampler.backend))
        return app_usage_error(cmd, "--sampler must be gl, embree or auto, not '%s'", sampler);
    if (gl && !glctx_platform_from_name(gl, &d->gl_platform))
        return app_usage_error(cmd, "--gl must be egl or osmesa, not '%s'", gl);
    return APP_EXIT_OK;
}

void app_return_freed_memory(void)
{
#ifdef __GLIBC__
    malloc_trim(0);
#endif
}

void app_progress_bar(double fraction, char bar[APP_PROGRESS_WIDTH + 1])
{
    double f = fraction > 1.0 ? 1.0 : fraction > 0.0 ? fraction : 0.0;
    int filled = (int)(f * APP_PROGRESS_WIDTH + 0.5);
    for (int i = 0; i < APP_PROGRESS_WIDTH; ++i) bar[i] = i < filled ? '#' : '.';
    bar[APP_PROGRESS_WIDTH] = '\0';
}
