/* view_tonemap_test — the viewer's GPU tone mapping (shaders/view_tonemap.frag)
 * against tm_to_display (tonemap.c) on a ramp of linear values, at several
 * exposures, within 1/255 after the 8-bit target's rounding; non-finite input
 * shows black as on the CPU. Headless (EGL); exit 77 without any GL. */
#include <math.h>
#include <stdlib.h>

#include "src/base/tonemap.h"
#include "src/gpu/gl_context.h"
#include "src/view/view_tonemap.h"
#include "tests/test_util.h"

enum { W = 256, H = 3 };

int main(void)
{
    glctx *ctx;
    lm_error err;
    if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &ctx, &err) != LM_OK) {
        fprintf(stderr, "skipped: %s\n", err.msg);
        return 77;
    }
    const GladGLContext *gl = glctx_gl(ctx);
    /* Row 0: a ramp 0..1.5 (the clamp and the linear segment of sRGB included), per
     * channel a different third of it; row 1: tiny values (the linear segment);
     * row 2: non-finite and negative values. GL row 0 is the image's bottom row. */
    float *in = malloc(sizeof(float) * 4 * W * H);
    for (int x = 0; x < W; ++x) {
        float t = (float)x / (W - 1);
        float *a = in + 4 * x, *b = in + 4 * (W + x), *c = in + 4 * (2 * W + x);
        a[0] = 1.5f * t, a[1] = 1.5f * t * t, a[2] = 0.5f * t, a[3] = 1;
        b[0] = 0.004f * t, b[1] = 0.0031308f * t * 2, b[2] = 0.02f * t, b[3] = 1;
        c[0] = x % 3 == 0 ? NAN : (x % 3 == 1 ? INFINITY : -t), c[1] = -INFINITY, c[2] = 1e30f * t, c[3] = 1;
    }
    GLuint tex;
    gl->CreateTextures(GL_TEXTURE_2D, 1, &tex);
    gl->TextureStorage2D(tex, 1, GL_RGBA32F, W, H);
    gl->TextureSubImage2D(tex, 0, 0, 0, W, H, GL_RGBA, GL_FLOAT, in);
    view_tm *t = NULL;
    CHECK_MSG(view_tm_create(gl, &t, &err) == LM_OK, "%s", err.msg);
    uint8_t *out = malloc(3 * W * H);
    const float exposures[] = {0.0f, -1.5f, 2.0f, NAN};
    for (int e = 0; t && e < 4; ++e) {
        tm_desc tm = {.exposure = exposures[e]};
        CHECK_MSG(view_tm_read(t, tex, W, H, &tm, out, &err) == LM_OK, "%s", err.msg);
        double worst = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                float d[3];
                tm_to_display(&tm, in + 4 * (y * W + x), d);
                /* out is top row first: GL row y is image row H-1-y. */
                const uint8_t *o = out + 3 * ((H - 1 - y) * W + x);
                for (int c = 0; c < 3; ++c) worst = fmax(worst, fabs(o[c] / 255.0 - d[c]));
            }
        CHECK_MSG(worst <= 1.0 / 255.0, "exposure %g: worst difference %.5f > 1/255", exposures[e], worst);
        printf("exposure %g: worst difference %.5f (%.2f/255)\n", exposures[e], worst, worst * 255);
    }
    free(out);
    free(in);
    view_tm_destroy(t);
    gl->DeleteTextures(1, &tex);
    glctx_destroy(ctx);
    return test_finish("view_tonemap_test");
}
