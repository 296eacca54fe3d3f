/* headers_c_test — every public header compiles as plain C11 on its own (this
 * file is C with -Wstrict-prototypes), and the shared result codes are named. */
#include "mesh/cache/cache.h"
#include "mesh/cache/cache_snapshot.h"
#include "mesh/cache/cache_worker.h"
#include "mesh/geomesh.h"
#include "mesh/qmesh.h"
#include "mesh/vtable.h"
#include "sampling/analytic.h"
#include "sampling/reference.h"
#include "sampling/rt_scene.h"
#include "sampling/samp.h"
#include "src/base/rng.h"
#include "src/base/tonemap.h"
#include "src/base/util.h"
#include "src/base/vecmath.h"
#include "src/base/vfs.h"
#include "src/gpu/gl_context.h"
#include "src/gpu/gl_platform.h"
#include "src/gpu/gl_program.h"
#include "src/image/compare.h"
#include "src/image/image.h"
#include "src/render/rend_debug.h"
#include "src/render/rend_frame.h"
#include "src/render/rend_id.h"
#include "src/render/rend_session.h"
#include "src/scene/camera.h"
#include "src/scene/scene.h"
#include "src/view/view_camera.h"
#include "src/view/view_script.h"
#include "src/view/view_tonemap.h"

#include <string.h>

#include "tests/test_util.h"

int main(void)
{
    /* Every result code has its own name, and unknown ones say so. */
    for (int a = 0; a < LM_RESULT_COUNT; ++a) {
        CHECK(lm_result_name((lm_result)a) != NULL);
        CHECK(strcmp(lm_result_name((lm_result)a), "unknown result") != 0);
        for (int b = a + 1; b < LM_RESULT_COUNT; ++b)
            CHECK(strcmp(lm_result_name((lm_result)a), lm_result_name((lm_result)b)) != 0);
    }
    CHECK(strcmp(lm_result_name(LM_RESULT_COUNT), "unknown result") == 0);
    /* The sampler's command-line spellings round-trip. */
    for (int b = 0; b < SAMP_BACKEND_COUNT; ++b) {
        samp_backend got = SAMP_BACKEND_COUNT;
        CHECK(samp_backend_from_name(samp_backend_name((samp_backend)b), &got) && got == (samp_backend)b);
    }
    glctx_platform pl = GLCTX_DEFAULT;
    CHECK(glctx_platform_from_name("osmesa", &pl) && pl == GLCTX_OSMESA);
    CHECK(!glctx_platform_from_name("glx", &pl) && !samp_backend_from_name(NULL, &(samp_backend){0}));
    /* lm_fail formats one line and returns the code. */
    lm_error err;
    CHECK(lm_fail(&err, LM_ERR_IO, "%s: %d\nsecond", "x.obj", 7) == LM_ERR_IO);
    CHECK(strcmp(err.msg, "x.obj: 7 second") == 0);
    CHECK(lm_fail(NULL, LM_ERR_BAD_INPUT, "ignored") == LM_ERR_BAD_INPUT);
    /* Path helpers used to resolve scene-relative files. */
    char buf[256];
    lm_path_dir("a/b/c.obj", buf, sizeof buf);
    CHECK(strcmp(buf, "a/b") == 0);
    lm_path_dir("c.obj", buf, sizeof buf);
    CHECK(strcmp(buf, ".") == 0);
    lm_path_dir(VFS_DEFAULT_SCENE, buf, sizeof buf);
    CHECK(strcmp(buf, "builtin:") == 0);
    CHECK(lm_path_join("builtin:", "cornell-box.obj", buf, sizeof buf));
    CHECK(strcmp(buf, "builtin:/cornell-box.obj") == 0);
    CHECK(lm_path_join("dir", "/abs/x.obj", buf, sizeof buf) && strcmp(buf, "/abs/x.obj") == 0);
    lm_path_ext("dir.v2/Scene.OBJ", buf, sizeof buf);
    CHECK(strcmp(buf, "obj") == 0);
    lm_path_ext("dir.v2/noext", buf, sizeof buf);
    CHECK(strcmp(buf, "") == 0);
    return test_finish("headers_c_test");
}
