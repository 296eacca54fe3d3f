/* tonemap.h — the project's one tone mapping, used for PNG output, for image
 * comparison (CIELAB ΔE) and for the perceptual refinement test (paper §4.3.2).
 *
 * display = sRGB_OETF(clamp(2^exposure * linear, 0, 1)), per channel.
 * A clamp rather than a compressive curve, so that mid-tones map to display
 * values a designer can predict; emitters simply saturate to white.
 *
 * Does NOT do: colour management, white balance, auto exposure.
 */
#ifndef LUMESH_TONEMAP_H
#define LUMESH_TONEMAP_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct tm_desc {
    float exposure; /* stops; 0 = no scaling */
} tm_desc;

/* sRGB transfer function (IEC 61966-2-1), input and output in [0,1]. */
float tm_srgb_encode(float linear);
float tm_srgb_decode(float encoded);

/* Linear RGB (scene units) -> display RGB in [0,1]. Non-finite input maps to 0. */
void tm_to_display(const tm_desc *desc, const float linear[3], float display[3]);

/* Tone maps count pixels of `in_channels` floats (the first 3 are RGB) to 8-bit RGB. */
void tm_to_rgb8(const tm_desc *desc, const float *in, int in_channels, size_t count, uint8_t *out_rgb);

/* Display sRGB in [0,1] -> CIELAB (D65 white), for ΔE. */
void tm_display_to_lab(const float display[3], float lab[3]);
/* Linear RGB (scene units) -> the CIELAB of its display colour: what
 * tm_display_to_lab(tm_to_display(linear)) gives, without the sRGB encode and
 * decode between them (they cancel; what is left is the clamp to [0,1] and
 * float rounding, below 1e-4 ΔE). For the cache's many ΔE judgements. */
void tm_linear_to_lab(const tm_desc *desc, const float linear[3], float lab[3]);
/* CIE76 colour difference. */
float tm_delta_e(const float lab_a[3], const float lab_b[3]);

#ifdef __cplusplus
}
#endif
#endif
