/* view_image_check — for view_cli.cmake: every image given exists, reads back,
 * and is not uniform (the luminance spread over its pixels is more than a few
 * 8-bit steps); with two or more, the first two differ (the camera moved
 * between them), and their means' ratio is printed. Exit 0 when all holds, 1
 * otherwise (each failure printed). */
#include <math.h>
#include <stdio.h>

#include "src/image/image.h"

int main(int argc, char **argv)
{
    int fails = 0;
    double mean[2] = {0, 0};
    for (int i = 1; i < argc; ++i) {
        img_image im = {0};
        lm_error err;
        if (img_read(argv[i], &im, &err) != LM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            fails++;
            continue;
        }
        size_t n = (size_t)im.width * (size_t)im.height;
        double sum = 0, sum2 = 0;
        for (size_t p = 0; p < n; ++p) {
            const float *px = im.pixels + p * (size_t)im.channels;
            double y = im.channels >= 3 ? 0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2] : px[0];
            sum += y;
            sum2 += y * y;
        }
        double m = sum / (double)n, sd = sqrt(fmax(0, sum2 / (double)n - m * m));
        printf("%s: %dx%d, mean %.4f, standard deviation %.4f\n", argv[i], im.width, im.height, m, sd);
        if (!(sd > 4.0 / 255.0)) {
            fprintf(stderr, "%s: uniform (standard deviation %.4f)\n", argv[i], sd);
            fails++;
        }
        if (i <= 2) mean[i - 1] = m;
        img_free(&im);
    }
    if (argc > 2 && mean[0] > 0.0) printf("mean of the second over the first %.4f\n", mean[1] / mean[0]);
    if (argc > 2 && mean[0] == mean[1]) {
        fprintf(stderr, "%s and %s look the same (mean %.6f)\n", argv[1], argv[2], mean[0]);
        fails++;
    }
    return fails ? 1 : 0;
}
