/* view_script.c — parsing the viewer's script (view_script.h). */
#define _POSIX_C_SOURCE 200809L /* strtok_r */
#include "src/view/view_script.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

view_action view_action_from_key_name(const char *name)
{
    static const struct {
        const char *name;
        view_action action;
    } keys[] = {
        {"escape", VIEW_ACTION_QUIT},         {"q", VIEW_ACTION_QUIT},
        {"p", VIEW_ACTION_PAUSE},             {"plus", VIEW_ACTION_EXPOSURE_UP},
        {"minus", VIEW_ACTION_EXPOSURE_DOWN}, {"f12", VIEW_ACTION_SCREENSHOT},
        {"f", VIEW_ACTION_FRAME_ALL},         {"l", VIEW_ACTION_LIGHT_NEXT},
        {"c", VIEW_ACTION_CAMERA_NEXT},       {"o", VIEW_ACTION_OVERLAY_NEXT},
        {"v", VIEW_ACTION_OVERLAY_KIND},      {"r", VIEW_ACTION_RELOAD},
        {"k", VIEW_ACTION_LIGHT_COLOR},       {"b", VIEW_ACTION_BOUNCES},
        {"bracketright", VIEW_ACTION_LIGHT_UP}, {"bracketleft", VIEW_ACTION_LIGHT_DOWN},
        {"1", VIEW_ACTION_TOGGLE_DIRECT},     {"2", VIEW_ACTION_TOGGLE_SPECULAR},
        {"3", VIEW_ACTION_TOGGLE_INDIRECT},   {"4", VIEW_ACTION_TOGGLE_EMISSION},
        {"h", VIEW_ACTION_HELP},              {"i", VIEW_ACTION_INDIRECT},
    };
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; ++i)
        if (strcmp(name, keys[i].name) == 0) return keys[i].action;
    return VIEW_ACTION_NONE;
}

/* A whole finite number in [lo, hi]. */
static int number(const char *s, double lo, double hi, double *out)
{
    if (!s) return 0;
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end || !isfinite(v) || v < lo || v > hi) return 0;
    *out = v;
    return 1;
}

/* One line, already split into at most 5 words. */
static lm_result parse_line(char **w, int n, const char *path, int line, view_cmd *c, lm_error *err)
{
    memset(c, 0, sizeof *c);
    c->line = line;
    const char *k = w[0];
    int ok = 1;
    if (strcmp(k, "wait") == 0) {
        c->kind = VIEW_CMD_WAIT;
        ok = n == 2 && number(w[1], 0, 1e6, &c->a);
    } else if (strcmp(k, "frames") == 0) {
        c->kind = VIEW_CMD_FRAMES;
        ok = n == 2 && number(w[1], 0, 1e9, &c->a) && c->a == floor(c->a);
    } else if (strcmp(k, "orbit") == 0) {
        c->kind = VIEW_CMD_ORBIT;
        ok = n == 3 && number(w[1], -1e4, 1e4, &c->a) && number(w[2], -1e4, 1e4, &c->b);
    } else if (strcmp(k, "zoom") == 0) {
        c->kind = VIEW_CMD_ZOOM;
        ok = n == 2 && number(w[1], 1e-6, 1e6, &c->a) && c->a > 0;
    } else if (strcmp(k, "pan") == 0) {
        c->kind = VIEW_CMD_PAN;
        ok = n == 3 && number(w[1], -1e4, 1e4, &c->a) && number(w[2], -1e4, 1e4, &c->b);
    } else if (strcmp(k, "fly") == 0) {
        c->kind = VIEW_CMD_FLY;
        ok = n == 4 && number(w[1], -1e9, 1e9, &c->a) && number(w[2], -1e9, 1e9, &c->b) &&
             number(w[3], -1e9, 1e9, &c->c);
    } else if (strcmp(k, "look") == 0) {
        c->kind = VIEW_CMD_LOOK;
        ok = n == 3 && number(w[1], -1e4, 1e4, &c->a) && number(w[2], -1e4, 1e4, &c->b);
    } else if (strcmp(k, "camera") == 0) {
        c->kind = VIEW_CMD_CAMERA;
        ok = n == 2 && number(w[1], 0, 1e6, &c->a) && c->a == floor(c->a);
    } else if (strcmp(k, "window-shot") == 0) {
        c->kind = VIEW_CMD_WINDOW_SHOT;
        ok = n == 2 && strlen(w[1]) < sizeof c->path;
        if (ok) strcpy(c->path, w[1]);
    } else if (strcmp(k, "screenshot") == 0) {
        c->kind = VIEW_CMD_SCREENSHOT;
        ok = n == 2 && strlen(w[1]) < sizeof c->path;
        if (ok) strcpy(c->path, w[1]);
    } else if (strcmp(k, "key") == 0) {
        c->kind = VIEW_CMD_KEY;
        ok = n == 2 && (c->action = view_action_from_key_name(w[1])) != VIEW_ACTION_NONE;
        if (!ok)
            return lm_fail(err, LM_ERR_BAD_INPUT,
                           "%s:%d: key wants one of escape, q, p, plus, minus, f12, f, c, l, bracketright, "
                           "bracketleft, 1, 2, 3, 4, h, o, v, r, k",
                           path, line);
    } else if (strcmp(k, "light") == 0) {
        c->kind = VIEW_CMD_LIGHT;
        ok = n == 3 && number(w[1], 0, 1e9, &c->a) && c->a == floor(c->a) && number(w[2], 0, 1e6, &c->b);
    } else if (strcmp(k, "resize") == 0) {
        c->kind = VIEW_CMD_RESIZE;
        ok = n == 3 && number(w[1], 1, 16384, &c->a) && c->a == floor(c->a) && number(w[2], 1, 16384, &c->b) &&
             c->b == floor(c->b);
    } else if (strcmp(k, "minimise") == 0 || strcmp(k, "restore") == 0) {
        c->kind = VIEW_CMD_MINIMISE;
        c->a = k[0] == 'm';
        ok = n == 1;
    } else if (strcmp(k, "light-color") == 0) {
        c->kind = VIEW_CMD_LIGHT_COLOR;
        double rgb[3] = {0, 0, 0};
        ok = n == 5 && number(w[1], 0, 1e9, &c->a) && c->a == floor(c->a) && number(w[2], 0, 1e6, &rgb[0]) &&
             number(w[3], 0, 1e6, &rgb[1]) && number(w[4], 0, 1e6, &rgb[2]);
        for (int i = 0; i < 3; ++i) c->rgb[i] = (float)rgb[i];
    } else if (strcmp(k, "next-snapshot") == 0) {
        c->kind = VIEW_CMD_NEXT_SNAPSHOT;
        ok = n == 2 && number(w[1], 0, 1e6, &c->a);
    } else if (strcmp(k, "peer-picture") == 0) {
        c->kind = VIEW_CMD_PEER_PICTURE;
        ok = n == 2 && number(w[1], 0, 1e6, &c->a);
    } else if (strcmp(k, "peer-preview") == 0) {
        c->kind = VIEW_CMD_PEER_PREVIEW;
        ok = n == 2 && number(w[1], 0, 1e6, &c->a);
    } else if (strcmp(k, "quit") == 0) {
        c->kind = VIEW_CMD_QUIT;
        ok = n == 1;
    } else {
        return lm_fail(err, LM_ERR_BAD_INPUT,
                       "%s:%d: unknown command '%s' (wait, frames, orbit, zoom, pan, fly, look, camera, screenshot, "
                       "window-shot, resize, minimise, restore, key, light, light-color, next-snapshot, peer-picture, peer-preview, quit)", path, line,
                       k);
    }
    if (!ok) {
        static const char *const usage[VIEW_CMD_COUNT] = {
            [VIEW_CMD_WAIT] = "wait SECONDS",        [VIEW_CMD_FRAMES] = "frames N",
            [VIEW_CMD_ORBIT] = "orbit DX DY",        [VIEW_CMD_ZOOM] = "zoom FACTOR (> 0)",
            [VIEW_CMD_SCREENSHOT] = "screenshot PATH", [VIEW_CMD_QUIT] = "quit",
            [VIEW_CMD_LIGHT] = "light INDEX SCALE (>= 0)", [VIEW_CMD_NEXT_SNAPSHOT] = "next-snapshot SECONDS",
            [VIEW_CMD_PEER_PICTURE] = "peer-picture SECONDS", [VIEW_CMD_PEER_PREVIEW] = "peer-preview SECONDS",
            [VIEW_CMD_PAN] = "pan DX DY",            [VIEW_CMD_FLY] = "fly FORWARD RIGHT UP",
            [VIEW_CMD_LOOK] = "look DX DY",          [VIEW_CMD_CAMERA] = "camera INDEX",
            [VIEW_CMD_WINDOW_SHOT] = "window-shot PATH.png", [VIEW_CMD_LIGHT_COLOR] = "light-color INDEX R G B (>= 0)",
            [VIEW_CMD_RESIZE] = "resize WIDTH HEIGHT",  [VIEW_CMD_MINIMISE] = "minimise (or restore), alone",
        };
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s:%d: expected '%s'", path, line, usage[c->kind]);
    }
    return LM_OK;
}

lm_result view_script_load(const char *path, view_cmd **cmds, size_t *count, lm_error *err)
{
    *cmds = NULL;
    *count = 0;
    char *text;
    size_t size;
    lm_result r = lm_read_file(path, VIEW_SCRIPT_MAX_BYTES, &text, &size, err);
    if (r != LM_OK) return r;
    size_t lines = 1;
    for (size_t i = 0; i < size; ++i) lines += text[i] == '\n';
    view_cmd *out = calloc(lines, sizeof *out);
    if (!out) {
        free(text);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory for %zu lines", path, lines);
    }
    size_t n = 0;
    int line = 0;
    char *save = NULL;
    /* strtok_r would merge empty lines and lose the numbering: split by hand. */
    for (char *p = text; r == LM_OK && p && *p;) {
        char *nl = strchr(p, '\n');
        if (nl) *nl = '\0';
        ++line;
        char *hash = strchr(p, '#');
        if (hash) *hash = '\0';
        char *w[6]; /* the longest command has five words (light-color INDEX R G B) */
        int nw = 0;
        for (char *tok = strtok_r(p, " \t\r", &save); tok && nw < 6; tok = strtok_r(NULL, " \t\r", &save))
            w[nw++] = tok;
        if (nw == 6) r = lm_fail(err, LM_ERR_BAD_INPUT, "%s:%d: too many words", path, line);
        else if (nw > 0) r = parse_line(w, nw, path, line, &out[n++], err);
        p = nl ? nl + 1 : NULL;
    }
    free(text);
    if (r != LM_OK || n == 0) {
        free(out);
        return r;
    }
    *cmds = out;
    *count = n;
    return LM_OK;
}
