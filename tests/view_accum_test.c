/* view_accum_test — the viewer's resting picture (src/view/view_accum.c): the
 * running mean that GL blending forms, against the mean computed on the CPU.
 * Draws of different values, with linear radiance far above 1 and below 1e-3,
 * are added one by one; after each add the texture read back must be their
 * plain mean (float rounding: 1e-5 relative); n = 0 starts again; a new size
 * starts again. Headless (EGL); exit 77 without any GL. */
#include <math.h>
#include <stdlib.h>

#include "src/gpu/gl_context.h"
#include "src/view/view_accum.h"
#include "tests/test_util.h"

enum { W = 7, H = 5, DRAWS = 16 };

/* Draw i's value at pixel p, channel c: wide in range, different everywhere. */
static float value(int i, int p, int c) { return (float)((1 + (i * 7 + p * 3 + c) % 11) * pow(10.0, (p % 5) - 3)); }

int main(void)
{
    glctx *ctx;
    lm_error err;
    if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &ctx, &err) != LM_OK) return test_no_gl(err.msg);
    const GladGLContext *gl = glctx_gl(ctx);
    GLuint tex;
    gl->CreateTextures(GL_TEXTURE_2D, 1, &tex);
    gl->TextureStorage2D(tex, 1, GL_RGBA32F, W, H);
    view_accum *a = NULL;
    CHECK_MSG(view_accum_create(gl, &a, &err) == LM_OK, "%s", err.msg);
    float in[4 * W * H], mean[3 * W * H], got[3 * W * H];
    double worst = 0.0;
    for (int i = 0; a && i < DRAWS; ++i) {
        for (int p = 0; p < W * H; ++p)
            for (int c = 0; c < 4; ++c) in[4 * p + c] = c < 3 ? value(i, p, c) : 1.0f;
        gl->TextureSubImage2D(tex, 0, 0, 0, W, H, GL_RGBA, GL_FLOAT, in);
        CHECK_MSG(view_accum_add(a, tex, W, H, (uint32_t)i, &err) == LM_OK, "%s", err.msg);
        CHECK_MSG(view_accum_read(a, got, &err) == LM_OK, "%s", err.msg);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                for (int c = 0; c < 3; ++c) {
                    /* The texture's row y is the image's row H-1-y (read top row first). */
                    double want = 0.0;
                    for (int j = 0; j <= i; ++j) want += value(j, y * W + x, c);
                    want /= i + 1;
                    double g = got[3 * ((H - 1 - y) * W + x) + c];
                    worst = fmax(worst, fabs(g - want) / want);
                }
    }
    printf("%d draws added: worst relative difference from the plain mean %.3g\n", DRAWS, worst);
    CHECK_MSG(worst <= 1e-5, "the running mean is off by %.3g (relative)", worst);
    /* n = 0 starts again: the mean is the draw. */
    if (a) {
        CHECK(view_accum_add(a, tex, W, H, 0, &err) == LM_OK && view_accum_read(a, got, &err) == LM_OK);
        double d = 0.0;
        for (int p = 0; p < W * H; ++p) d = fmax(d, fabs(got[3 * ((H - 1 - p / W) * W + p % W)] - in[4 * p]));
        CHECK_MSG(d == 0.0, "n = 0 did not start again (%.3g off)", d);
        (void)mean;
    }
    view_accum_destroy(a);
    gl->DeleteTextures(1, &tex);
    glctx_destroy(ctx);
    return test_finish("view_accum_test");
}
