/* image_sum_check — for render_components.cmake: WHOLE PART... checks that the
 * linear image WHOLE is the sum of the PART images, pixel for pixel and channel
 * for channel, within float rounding (1e-4 relative, 1e-6 absolute), and that
 * every part has some light (a part that is all zero proves nothing). Exit 0
 * when all holds, 1 otherwise (each failure printed). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "src/image/image.h"

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: image_sum_check WHOLE.exr PART.exr...\n");
        return 1;
    }
    img_image whole = {0};
    lm_error err;
    if (img_read(argv[1], &whole, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    size_t n = (size_t)whole.width * (size_t)whole.height * (size_t)whole.channels;
    double *sum = calloc(n ? n : 1, sizeof *sum);
    int fails = 0;
    for (int i = 2; i < argc && sum; ++i) {
        img_image part = {0};
        if (img_read(argv[i], &part, &err) != LM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            fails++;
            continue;
        }
        if (part.width != whole.width || part.height != whole.height || part.channels != whole.channels) {
            fprintf(stderr, "%s: %dx%dx%d, the whole is %dx%dx%d\n", argv[i], part.width, part.height, part.channels,
                    whole.width, whole.height, whole.channels);
            fails++;
        } else {
            double total = 0.0;
            for (size_t k = 0; k < n; ++k) {
                sum[k] += part.pixels[k];
                total += part.pixels[k];
            }
            printf("%s: mean %.6g\n", argv[i], total / (double)n);
            if (!(total > 0.0)) {
                fprintf(stderr, "%s: no light at all\n", argv[i]);
                fails++;
            }
        }
        img_free(&part);
    }
    size_t bad = 0, worst_at = 0;
    double worst = 0.0;
    for (size_t k = 0; k < n && sum && !fails; ++k) {
        double d = fabs(sum[k] - whole.pixels[k]), tol = 1e-6 + 1e-4 * fabs(whole.pixels[k]);
        if (d > tol) bad++;
        if (d - tol > worst) worst = d - tol, worst_at = k;
    }
    if (bad) {
        fprintf(stderr, "%zu of %zu values differ from the sum of the parts (worst at value %zu: %g against %g)\n",
                bad, n, worst_at, whole.pixels[worst_at], sum[worst_at]);
        fails++;
    }
    if (!sum) fails++;
    free(sum);
    img_free(&whole);
    return fails ? 1 : 0;
}
