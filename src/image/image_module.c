/* image_module.c — img_write, img_read and cmp_oiio_compare through the
 * lumesh_oiio.so module, opened on first use (image_internal.h says why).
 *
 * Where the module is looked for, in order (the first file that exists is the
 * one used, so a broken module is reported rather than skipped):
 *   1. $LUMESH_MODULE_DIR, when set;
 *   2. the running program's own folder (the build tree: build/lumesh);
 *   3. <program folder>/../lib/lumesh (an installed tree: `cmake --install`);
 *   4. the folder the module was built in (LUMESH_MODULE_BUILD_DIR: the tests
 *      and benchmarks, which live in subfolders of the build tree).
 *
 * Threads: any thread may call; the module is opened once (pthread_once) and
 * never closed, so its function table stays valid until exit.
 * Does NOT do: any image work itself, but for img_attribute and img_free.
 */
#define _POSIX_C_SOURCE 200809L /* readlink */
#include "src/image/image_internal.h"
#include "src/base/fork_guard.h"

#include <dlfcn.h>
#include <limits.h> /* PATH_MAX through linux/limits.h */
#include <linux/limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifndef LUMESH_MODULE_BUILD_DIR
#define LUMESH_MODULE_BUILD_DIR ""
#endif

static struct {
    const img_oiio_api *api; /* NULL when the module could not be opened */
    char error[768];         /* why not, one line: every folder tried, or dlerror()'s message */
} g_module;
static pthread_once_t g_module_once = PTHREAD_ONCE_INIT;

/* The candidate folders, in the order of the header; returns how many. */
static int module_folders(char dirs[4][PATH_MAX])
{
    int n = 0;
    const char *env = getenv("LUMESH_MODULE_DIR");
    if (env && env[0]) lm_strlcpy(dirs[n++], env, PATH_MAX);
    char exe[PATH_MAX];
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (len > 0) {
        exe[len] = '\0';
        lm_path_dir(exe, dirs[n], PATH_MAX);
        n += lm_path_join(dirs[n], "../lib/lumesh", dirs[n + 1], PATH_MAX) ? 2 : 1;
    }
    if (LUMESH_MODULE_BUILD_DIR[0]) lm_strlcpy(dirs[n++], LUMESH_MODULE_BUILD_DIR, PATH_MAX);
    return n;
}

static const img_oiio_api *check_api(void *lib, char *why, size_t why_size)
{
    /* POSIX dlsym returns void *; the union keeps -Wpedantic quiet. */
    union { void *p; img_oiio_entry_fn f; } entry = {dlsym(lib, IMG_OIIO_ENTRY)};
    if (!entry.p) {
        snprintf(why, why_size, "it has no entry point %s", IMG_OIIO_ENTRY);
        return NULL;
    }
    const img_oiio_api *api = entry.f();
    const unsigned sizes[4] = IMG_OIIO_API_SIZES;
    if (!api || api->version != IMG_OIIO_API_VERSION || memcmp(api->sizes, sizes, sizeof sizes) != 0) {
        snprintf(why, why_size, "it is from another build of lumesh (interface version %u, this program's %u)",
                 api ? api->version : 0u, IMG_OIIO_API_VERSION);
        return NULL;
    }
    return api;
}

static void module_open(void)
{
    char dirs[4][PATH_MAX];
    int n = module_folders(dirs);
    char tried[512] = "";
    for (int i = 0; i < n; ++i) {
        char path[PATH_MAX];
        if (!lm_path_join(dirs[i], IMG_OIIO_MODULE_FILE, path, sizeof path) || access(path, F_OK) != 0) {
            size_t used = strlen(tried);
            snprintf(tried + used, sizeof tried - used, "%s%.120s", used ? ", " : "", dirs[i]);
            continue;
        }
        lm_fork_guard_enter(); /* its constructors run under the loader's lock (fork_guard.h) */
        void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
        lm_fork_guard_leave();
        char why[512];
        const img_oiio_api *api = NULL;
        if (!lib) {
            const char *e = dlerror();
            lm_strlcpy(why, e ? e : "dlopen failed", sizeof why);
        } else {
            api = check_api(lib, why, sizeof why);
            if (!api) dlclose(lib);
        }
        if (api) {
            g_module.api = api;
        } else {
            snprintf(g_module.error, sizeof g_module.error, "the image module %.240s cannot be used: %.480s", path,
                     why);
        }
        return;
    }
    snprintf(g_module.error, sizeof g_module.error,
             "the image module %s was not found (looked in %s; set LUMESH_MODULE_DIR to its folder)",
             IMG_OIIO_MODULE_FILE, tried[0] ? tried : "no folder");
}

/* The module's table, or NULL with err set ("<what>: <why>"). */
static const img_oiio_api *module_api(const char *what, lm_error *err)
{
    pthread_once(&g_module_once, module_open);
    if (!g_module.api) lm_fail(err, LM_ERR_UNSUPPORTED, "%s: %s", what, g_module.error);
    return g_module.api;
}

lm_result img_write(const img_write_desc *desc, lm_error *err)
{
    img_format fmt = IMG_FORMAT_FROM_EXTENSION;
    size_t count = 0;
    lm_result r = img_write_check(desc, &fmt, &count, err);
    if (r != LM_OK) return r;
    if (fmt == IMG_FORMAT_PNG8) return img_png_write(desc, count, err); /* no module: image_png_write.c */
    const img_oiio_api *api = module_api(desc->path, err);
    return api ? api->write(desc, err) : LM_ERR_UNSUPPORTED;
}

lm_result img_read(const char *path, img_image *out, lm_error *err)
{
    if (out) *out = (img_image){0};
    const img_oiio_api *api = module_api(path ? path : "(no path)", err);
    return api ? api->read(path, out, err) : LM_ERR_UNSUPPORTED;
}

lm_result cmp_oiio_compare(const char *path_a, const char *path_b, cmp_oiio_result *out, lm_error *err)
{
    if (out) *out = (cmp_oiio_result){0};
    const img_oiio_api *api = module_api(path_a ? path_a : "(no path)", err);
    return api ? api->compare(path_a, path_b, out, err) : LM_ERR_UNSUPPORTED;
}

const char *img_attribute(const img_image *img, const char *name)
{
    for (int i = 0; img && name && i < img->attribute_count; ++i)
        if (strcmp(img->attributes[i][0], name) == 0) return img->attributes[i][1];
    return NULL;
}

void img_free(img_image *img)
{
    if (!img) return;
    free(img->pixels);
    free(img->channel_names);
    *img = (img_image){0};
}
