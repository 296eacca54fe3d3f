/* view_script_test — the viewer's script parser (line numbers in errors, every
 * command, comments) and its camera moves (orbit keeps the distance and turns
 * the right way, stops short of the pole; zoom; frame-all fits the box; pan and
 * fly move eye and target together by the amounts asked; look keeps the eye and
 * the distance and turns the right way). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/view/view_camera.h"
#include "src/view/view_script.h"
#include "tests/test_util.h"

static void test_script(void)
{
    char path[1024];
    test_write_file("view_script_ok.txt",
                    "# a comment\n\nwait 0.5\nframes 3  # trailing comment\norbit -10 5\nzoom 0.9\n"
                    "screenshot out.png\nkey plus\nkey escape\nquit\n",
                    path, sizeof path);
    view_cmd *c = NULL;
    size_t n = 0;
    lm_error err;
    CHECK_MSG(view_script_load(path, &c, &n, &err) == LM_OK, "%s", err.msg);
    CHECK(n == 8);
    if (n == 8) {
        CHECK(c[0].kind == VIEW_CMD_WAIT && c[0].a == 0.5 && c[0].line == 3);
        CHECK(c[1].kind == VIEW_CMD_FRAMES && c[1].a == 3);
        CHECK(c[2].kind == VIEW_CMD_ORBIT && c[2].a == -10 && c[2].b == 5);
        CHECK(c[3].kind == VIEW_CMD_ZOOM && fabs(c[3].a - 0.9) < 1e-12);
        CHECK(c[4].kind == VIEW_CMD_SCREENSHOT && strcmp(c[4].path, "out.png") == 0);
        CHECK(c[5].kind == VIEW_CMD_KEY && c[5].action == VIEW_ACTION_EXPOSURE_UP);
        CHECK(c[6].kind == VIEW_CMD_KEY && c[6].action == VIEW_ACTION_QUIT);
        CHECK(c[7].kind == VIEW_CMD_QUIT && c[7].line == 10);
    }
    free(c);
    test_write_file("view_script_light.txt", "light 1 0.5\nnext-snapshot 30\nkey bracketright\nkey 3\nkey l\npeer-picture 12.5\n", path,
                    sizeof path);
    CHECK_MSG(view_script_load(path, &c, &n, &err) == LM_OK, "%s", err.msg);
    CHECK(n == 6);
    if (n == 6) {
        CHECK(c[0].kind == VIEW_CMD_LIGHT && c[0].a == 1 && c[0].b == 0.5);
        CHECK(c[1].kind == VIEW_CMD_NEXT_SNAPSHOT && c[1].a == 30);
        CHECK(c[2].kind == VIEW_CMD_KEY && c[2].action == VIEW_ACTION_LIGHT_UP);
        CHECK(c[3].kind == VIEW_CMD_KEY && c[3].action == VIEW_ACTION_TOGGLE_INDIRECT);
        CHECK(c[4].kind == VIEW_CMD_KEY && c[4].action == VIEW_ACTION_LIGHT_NEXT);
        CHECK(c[5].kind == VIEW_CMD_PEER_PICTURE && c[5].a == 12.5);
    }
    free(c);
    test_write_file("view_script_moves.txt", "pan 0.1 -0.2\nfly 1 2 3\nlook 5 -5\ncamera 2\nkey c\nkey f12\n"
                    "light-color 0 1 0.5 0.25\nkey k\nkey o\nkey v\nkey r\nwindow-shot w.png\n", path,
                    sizeof path);
    CHECK_MSG(view_script_load(path, &c, &n, &err) == LM_OK, "%s", err.msg);
    CHECK(n == 12);
    if (n == 12) {
        CHECK(c[0].kind == VIEW_CMD_PAN && c[0].a == 0.1 && c[0].b == -0.2);
        CHECK(c[1].kind == VIEW_CMD_FLY && c[1].a == 1 && c[1].b == 2 && c[1].c == 3);
        CHECK(c[2].kind == VIEW_CMD_LOOK && c[2].a == 5 && c[2].b == -5);
        CHECK(c[3].kind == VIEW_CMD_CAMERA && c[3].a == 2);
        CHECK(c[4].kind == VIEW_CMD_KEY && c[4].action == VIEW_ACTION_CAMERA_NEXT);
        CHECK(c[5].kind == VIEW_CMD_KEY && c[5].action == VIEW_ACTION_SCREENSHOT);
        CHECK(c[6].kind == VIEW_CMD_LIGHT_COLOR && c[6].a == 0 && c[6].rgb[0] == 1.0f && c[6].rgb[1] == 0.5f &&
              c[6].rgb[2] == 0.25f);
        CHECK(c[7].kind == VIEW_CMD_KEY && c[7].action == VIEW_ACTION_LIGHT_COLOR);
        CHECK(c[8].action == VIEW_ACTION_OVERLAY_NEXT && c[9].action == VIEW_ACTION_OVERLAY_KIND &&
              c[10].action == VIEW_ACTION_RELOAD);
        CHECK(c[11].kind == VIEW_CMD_WINDOW_SHOT && strcmp(c[11].path, "w.png") == 0);
    }
    free(c);
    const char *bad[] = {"wait\n",      "frames 2.5\n", "orbit 1\n",     "zoom 0\n",         "key x\n",
                         "jump 3\n",    "quit now\n",   "light 0\n",     "light 0.5 1\n",    "light 0 -1\n",
                         "next-snapshot\n", "pan 1\n",     "fly 1 2\n",   "look x y\n",      "camera 1.5\n",
                         "camera -1\n",    "key s\n",       "light-color 0 1 1\n", "light-color 0 1 -1 1\n",
                         "window-shot\n",  "peer-picture\n", "peer-picture -1\n"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        char text[64];
        snprintf(text, sizeof text, "wait 1\n%s", bad[i]);
        test_write_file("view_script_bad.txt", text, path, sizeof path);
        CHECK_MSG(view_script_load(path, &c, &n, &err) == LM_ERR_BAD_INPUT, "'%s' was accepted", bad[i]);
        CHECK_MSG(strstr(err.msg, ":2: ") != NULL, "no line number in '%s'", err.msg);
    }
}

static double dist(const scene_camera *c)
{
    double d = 0;
    for (int i = 0; i < 3; ++i) d += ((double)c->position[i] - c->target[i]) * ((double)c->position[i] - c->target[i]);
    return sqrt(d);
}

static void test_camera(void)
{
    scene_camera cam = {.position = {0, 0, 5}, .target = {0, 0, 0}, .up = {0, 1, 0}, .fov_y_deg = 40};
    view_camera_orbit(&cam, 90, 0);
    /* Looking down -z, right is +x: a quarter turn to the right ends on +x. */
    CHECK_NEAR(cam.position[0], 5, 1e-5);
    CHECK_NEAR(cam.position[2], 0, 1e-5);
    view_camera_orbit(&cam, 0, 30);
    CHECK(cam.position[1] > 2.4f); /* up by 30°: 5·sin 30° = 2.5 */
    CHECK_NEAR(dist(&cam), 5, 1e-5);
    view_camera_orbit(&cam, 0, 80); /* past the pole: stops 1° short of it */
    CHECK_NEAR(cam.position[1], 5 * cos(3.14159265358979 / 180), 1e-4);
    CHECK_NEAR(dist(&cam), 5, 1e-5);
    view_camera_orbit(&cam, 0, -89); /* back down to the equator */
    CHECK_NEAR(cam.position[1], 0, 1e-4);
    view_camera_zoom(&cam, 0.5f);
    CHECK_NEAR(dist(&cam), 2.5, 1e-5);
    float bmin[3] = {-1, -1, -1}, bmax[3] = {3, 1, 1};
    view_camera_frame_all(&cam, bmin, bmax, 16.0f / 9.0f);
    CHECK_NEAR(cam.target[0], 1, 1e-6);
    /* The bounding sphere (radius √6) fits the vertical field of view. */
    CHECK(dist(&cam) * sin(20 * 3.14159265358979 / 180) >= sqrt(6.0));

    /* Pan: a whole view height up, at distance 5 with a 40° field: 2·5·tan 20°. */
    scene_camera p = {.position = {0, 0, 5}, .target = {0, 0, 0}, .up = {0, 1, 0}, .fov_y_deg = 40};
    view_camera_pan(&p, 0.0f, 1.0f);
    double h = 10 * tan(20 * 3.14159265358979 / 180);
    CHECK_NEAR(p.position[1], h, 1e-5);
    CHECK_NEAR(p.target[1], h, 1e-5);
    view_camera_pan(&p, 0.5f, 0.0f); /* right is +x looking down -z */
    CHECK_NEAR(p.position[0], 0.5 * h, 1e-5);
    CHECK_NEAR(p.target[0], 0.5 * h, 1e-5);
    CHECK_NEAR(dist(&p), 5, 1e-5);
    /* Fly: forward is -z, right +x, up +y, in scene units. */
    scene_camera f = {.position = {0, 0, 5}, .target = {0, 0, 0}, .up = {0, 1, 0}, .fov_y_deg = 40};
    view_camera_fly(&f, 2.0f, 1.0f, -0.5f);
    CHECK_NEAR(f.position[0], 1, 1e-6);
    CHECK_NEAR(f.position[1], -0.5, 1e-6);
    CHECK_NEAR(f.position[2], 3, 1e-6);
    CHECK_NEAR(f.target[2], -2, 1e-6);
    /* Look: the eye stays; a quarter turn right looks along +x, 30° up raises the target. */
    scene_camera l = {.position = {0, 0, 5}, .target = {0, 0, 0}, .up = {0, 1, 0}, .fov_y_deg = 40};
    view_camera_look(&l, 90, 0);
    CHECK_NEAR(l.position[2], 5, 1e-6);
    CHECK_NEAR(l.target[0], 5, 1e-5);
    CHECK_NEAR(l.target[2], 5, 1e-5);
    view_camera_look(&l, 0, 30);
    CHECK_NEAR(l.target[1], 2.5, 1e-5);
    CHECK_NEAR(dist(&l), 5, 1e-5);
    view_camera_look(&l, 0, 80); /* stops 1° short of straight up */
    CHECK_NEAR(l.target[1], 5 * cos(3.14159265358979 / 180), 1e-4);
}

int main(void)
{
    test_script();
    test_camera();
    return test_finish("view_script_test");
}
