/* view_script.h — the viewer's script (`lumesh view --script FILE`): one command
 * per line, run in order by the display loop, so that tests can drive the window.
 *
 *     # comment; blank lines are skipped
 *     wait SECONDS         keep drawing for this long (the worker refines meanwhile)
 *     frames N             keep drawing for N more frames (none are drawn while minimised: use wait)
 *     orbit DX DY          orbit about the target, degrees (right, up), as a drag would
 *     zoom FACTOR          distance to the target times FACTOR (> 0), as the wheel would
 *     pan DX DY            move eye and target by DX, DY view heights (right, up), as a middle drag would
 *     fly F R U            move eye and target F forward, R right, U up (scene units), as W A S D would
 *     look DX DY           turn the view about the eye, degrees (right, up), as a right drag would
 *     camera N             the scene's camera N (0-based), as C cycles them
 *     screenshot PATH      PATH.png: the tone-mapped image, as shown; PATH.exr: the linear
 *                          radiance behind it (written through img_write)
 *     window-shot PATH.png the whole window as shown, HUD included
 *     resize W H           the window to W × H screen units, as a user dragging its border
 *     minimise / restore   the window minimised (a 0 × 0 framebuffer: nothing drawn) or back
 *     key NAME             as if the key were pressed: escape, q, p, plus, minus, f12
 *                          (screenshot, PNG and EXR), f, c (next camera), l (next light),
 *                          bracketright / bracketleft (its power ×2 / ×0.5),
 *                          1 2 3 4 (toggle direct diffuse, direct specular, indirect, emission), h,
 *                          o (overlay the next mesh), v (wireframe / sample points),
 *                          r (reload the scene from its file), k (the light's next colour)
 *     light INDEX SCALE    light INDEX's power set to SCALE × the scene's (>= 0), no new light samples
 *     light-color INDEX R G B  light INDEX's colour: the scene's times (R, G, B) (>= 0), no new light samples
 *     next-snapshot SECONDS  keep drawing until a snapshot newer than the one shown now is drawn
 *                          (a light edit published), at most SECONDS
 *     peer-picture SECONDS keep drawing until a peer (key i) shows a complete pass of this view, at most SECONDS
 *     peer-preview SECONDS the same, its first pass over a grid of pixels is enough
 *     quit                 as Esc (the script also ends the viewer when it runs out)
 *
 * Usage:
 *     view_cmd *cmds; size_t n;
 *     if (view_script_load("test.view", &cmds, &n, &err) != LM_OK) ...  // "FILE:LINE: ..." on bad input
 *     free(cmds);
 *
 * Does NOT do: loops, variables, mouse positions.
 */
#ifndef LUMESH_VIEW_SCRIPT_H
#define LUMESH_VIEW_SCRIPT_H

#include <stddef.h>

#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What a key (or the same script command) does in the viewer. */
typedef enum view_action {
    VIEW_ACTION_NONE = 0,
    VIEW_ACTION_QUIT,          /* Esc, Q */
    VIEW_ACTION_PAUSE,         /* P: pause / resume refinement */
    VIEW_ACTION_EXPOSURE_UP,   /* + (also =, keypad +): +0.5 stop */
    VIEW_ACTION_EXPOSURE_DOWN, /* -: −0.5 stop */
    VIEW_ACTION_SCREENSHOT,    /* F12: lumesh-view-N.png and .exr in the working directory */
    VIEW_ACTION_FRAME_ALL,     /* F */
    VIEW_ACTION_CAMERA_NEXT,   /* C: the scene's next named camera */
    VIEW_ACTION_LIGHT_NEXT,    /* L: select the next light */
    VIEW_ACTION_LIGHT_UP,      /* ]: the selected light's power ×2 */
    VIEW_ACTION_LIGHT_DOWN,    /* [: the selected light's power ×0.5 */
    VIEW_ACTION_LIGHT_COLOR,   /* K: the selected light's next colour (scene's, warm, cool, red, green) */
    VIEW_ACTION_TOGGLE_DIRECT, /* 1: direct diffuse on / off */
    VIEW_ACTION_TOGGLE_SPECULAR, /* 2: direct specular on / off */
    VIEW_ACTION_TOGGLE_INDIRECT, /* 3: indirect on / off */
    VIEW_ACTION_TOGGLE_EMISSION, /* 4: emission on / off */
    VIEW_ACTION_HELP,          /* H: the help text in the HUD on / off */
    VIEW_ACTION_OVERLAY_NEXT,  /* O: overlay the next mesh (direct, indirect, specular, each light, off) */
    VIEW_ACTION_OVERLAY_KIND,  /* V: the overlay shows sample points / the leaf wireframe */
    VIEW_ACTION_RELOAD,        /* R: the scene again from its file */
    VIEW_ACTION_BOUNCES,       /* B: the next bounce setting: auto, 1, 2, 3, 4, 8 */
    VIEW_ACTION_INDIRECT,      /* I: what shows the picture at rest: the cache, VPLs, BDIR (docs/peers.md) */
    VIEW_ACTION_COUNT
} view_action;

typedef enum view_cmd_kind {
    VIEW_CMD_NONE = 0,
    VIEW_CMD_WAIT,       /* a: seconds */
    VIEW_CMD_FRAMES,     /* a: frames */
    VIEW_CMD_ORBIT,      /* a, b: degrees right, up */
    VIEW_CMD_ZOOM,       /* a: factor */
    VIEW_CMD_SCREENSHOT, /* path */
    VIEW_CMD_KEY,        /* action */
    VIEW_CMD_QUIT,
    VIEW_CMD_LIGHT,      /* a: light index, b: scale of the scene's power */
    VIEW_CMD_NEXT_SNAPSHOT, /* a: seconds at most */
    VIEW_CMD_PAN,        /* a, b: view heights right, up */
    VIEW_CMD_FLY,        /* a, b, c: forward, right, up, scene units */
    VIEW_CMD_LOOK,       /* a, b: degrees right, up */
    VIEW_CMD_CAMERA,     /* a: camera index */
    VIEW_CMD_WINDOW_SHOT, /* path */
    VIEW_CMD_LIGHT_COLOR, /* a: light index, rgb: colour multipliers of the scene's */
    VIEW_CMD_RESIZE,     /* a, b: width, height */
    VIEW_CMD_MINIMISE,   /* a: 1 minimise, 0 restore */
    VIEW_CMD_PEER_PICTURE, /* a: seconds at most, until the picture shown is a peer's complete pass of the view */
    VIEW_CMD_PEER_PREVIEW, /* a: seconds at most, until it is a peer's picture of the view (its grid's or whole) */
    VIEW_CMD_COUNT
} view_cmd_kind;

enum { VIEW_SCRIPT_PATH_MAX = 1024, VIEW_SCRIPT_MAX_BYTES = 1 << 20 };

typedef struct view_cmd {
    view_cmd_kind kind;
    double a, b, c;
    float rgb[3];
    view_action action;
    char path[VIEW_SCRIPT_PATH_MAX];
    int line;            /* 1-based, for messages */
} view_cmd;

/* Parses the whole script up front (a typo on line 30 fails before the window
 * opens). *cmds is malloc'ed (NULL when empty); LM_ERR_BAD_INPUT names FILE:LINE. */
lm_result view_script_load(const char *path, view_cmd **cmds, size_t *count, lm_error *err);

/* "escape", "q", "p", "plus", "minus", "s", "f", "l", "bracketright", "bracketleft", "1".."4", "h"
 * -> the action; VIEW_ACTION_NONE otherwise. */
view_action view_action_from_key_name(const char *name);

#ifdef __cplusplus
}
#endif
#endif
