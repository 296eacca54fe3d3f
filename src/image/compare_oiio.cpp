/* compare_oiio.cpp — cmp_oiio_compare, in the lumesh_oiio.so module (image_internal.h):
 * OpenImageIO's ImageBufAlgo::compare on the R, G, B of two files, as an
 * independent check on cmp_compare (compare.c).
 *
 * OpenImageIO reads the files itself (not through img_read), the three
 * channels are shuffled out with ImageBufAlgo::channels by the rule of
 * compare.h, and ImageBufAlgo::compare does the arithmetic. Every C++
 * exception stops here and becomes an lm_result.
 */
#include "src/image/compare.h"
#include "src/image/image_internal.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include <sys/stat.h>

namespace {

std::string one_line(std::string s)
{
    for (char &c : s)
        if (c == '\n' || c == '\r' || c == '\t') c = ' ';
    size_t end = s.find_last_not_of(' ');
    s.erase(end == std::string::npos ? 0 : end + 1);
    return s.empty() ? std::string("unknown OpenImageIO error") : s;
}

std::string buf_error(const OIIO::ImageBuf &buf)
{
    std::string e = buf.geterror();
    std::string g = OIIO::geterror(); /* always drain the thread's global error too */
    return one_line(e.empty() ? g : e);
}

/* The channel indices in the file's (OpenImageIO's) order. "First three"
 * follows the order img_write recorded in the lumesh:channelOrder attribute,
 * as img_read does, so both sides pick the same channels. */
void pick_rgb(const OIIO::ImageSpec &spec, int idx[3])
{
    const int n = spec.nchannels;
    int r = spec.channelindex("R"), g = spec.channelindex("G"), b = spec.channelindex("B");
    if (r >= 0 && g >= 0 && b >= 0) {
        idx[0] = r, idx[1] = g, idx[2] = b;
        return;
    }
    if (n < 3) {
        idx[0] = idx[1] = idx[2] = 0;
        return;
    }
    for (int k = 0; k < 3; ++k) idx[k] = k;
    std::string order = spec.get_string_attribute("lumesh:channelOrder");
    std::vector<std::string> names;
    for (size_t start = 0; !order.empty();) {
        size_t nl = order.find('\n', start);
        names.push_back(order.substr(start, nl == std::string::npos ? nl : nl - start));
        if (nl == std::string::npos) break;
        start = nl + 1;
    }
    if ((int)names.size() != n) return;
    int found[3];
    for (int k = 0; k < 3; ++k) {
        found[k] = spec.channelindex(names[(size_t)k]);
        if (found[k] < 0) return;
    }
    for (int k = 0; k < 3; ++k) idx[k] = found[k];
}

lm_result load_rgb(const char *path, OIIO::ImageBuf &rgb, lm_error *err)
{
    struct stat st;
    if (::stat(path, &st) != 0)
        return lm_fail(err, LM_ERR_IO, "%s: cannot open: %s", path, std::strerror(errno));
    /* ImageInput rather than ImageBuf(path): an ImageBuf made from a file name
     * goes through the process-wide ImageCache, which keeps the pixels after
     * we are done and can serve a stale copy of a file rewritten meanwhile. */
    auto in = OIIO::ImageInput::open(path);
    if (!in)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: OpenImageIO cannot read the image: %s", path,
                       one_line(OIIO::geterror()).c_str());
    OIIO::ImageSpec spec = in->spec();
    if (spec.deep)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "%s: deep images are not supported", path);
    if (spec.width <= 0 || spec.height <= 0 || spec.depth != 1 || spec.nchannels <= 0)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: image has size %dx%dx%d with %d channels", path,
                       spec.width, spec.height, spec.depth, spec.nchannels);
    spec.set_format(OIIO::TypeDesc::FLOAT);
    OIIO::ImageBuf buf(spec);
    bool ok = in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, buf.localpixels());
    std::string why = in->geterror();
    in->close();
    if (!ok)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: OpenImageIO cannot read the pixels: %s", path,
                       one_line(why.empty() ? OIIO::geterror() : why).c_str());
    int idx[3];
    pick_rgb(spec, idx);
    if (!OIIO::ImageBufAlgo::channels(rgb, buf, 3, idx))
        return lm_fail(err, LM_ERR_RUNTIME, "%s: OpenImageIO cannot pick R, G, B: %s", path,
                       buf_error(rgb).c_str());
    rgb.set_origin(0, 0, 0);
    return LM_OK;
}

lm_result compare_impl(const char *path_a, const char *path_b, cmp_oiio_result *out,
                       lm_error *err)
{
    OIIO::ImageBuf a, b;
    lm_result r = load_rgb(path_a, a, err);
    if (r == LM_OK) r = load_rgb(path_b, b, err);
    if (r != LM_OK) return r;
    const OIIO::ImageSpec &sa = a.spec(), &sb = b.spec();
    if (sa.width != sb.width || sa.height != sb.height)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s is %dx%d but the reference %s is %dx%d", path_a,
                       sa.width, sa.height, path_b, sb.width, sb.height);
    /* CompareResults::error is also set when any value "fails" the threshold
     * (a NaN difference always does), so only an error message means the
     * comparison itself did not happen. */
    const float no_threshold = std::numeric_limits<float>::max();
    OIIO::ImageBufAlgo::CompareResults cr =
        OIIO::ImageBufAlgo::compare(a, b, no_threshold, no_threshold);
    std::string why = OIIO::geterror();
    if (cr.error && !why.empty())
        return lm_fail(err, LM_ERR_RUNTIME, "%s: OpenImageIO cannot compare it with %s: %s",
                       path_a, path_b, one_line(why).c_str());
    out->width = sa.width;
    out->height = sa.height;
    out->mean_error = cr.meanerror;
    out->rms_error = cr.rms_error;
    out->psnr = cr.PSNR;
    out->max_error = cr.maxerror;
    out->max_x = cr.maxx;
    out->max_y = cr.maxy;
    out->max_channel = cr.maxc;
    return LM_OK;
}

} // namespace

extern "C" lm_result img_oiio_compare(const char *path_a, const char *path_b, cmp_oiio_result *out,
                                      lm_error *err)
{
    if (!out) return lm_fail(err, LM_ERR_INVALID_ARG, "cmp_oiio_compare: no result");
    *out = cmp_oiio_result{};
    if (!path_a || !path_a[0] || !path_b || !path_b[0])
        return lm_fail(err, LM_ERR_INVALID_ARG, "cmp_oiio_compare: no input path");
    try {
        return compare_impl(path_a, path_b, out, err);
    } catch (const std::bad_alloc &) {
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory comparing with %s", path_a,
                       path_b);
    } catch (const std::exception &e) {
        return lm_fail(err, LM_ERR_RUNTIME, "%s: error comparing with %s: %s", path_a, path_b,
                       e.what());
    } catch (...) {
        return lm_fail(err, LM_ERR_RUNTIME, "%s: unknown error comparing with %s", path_a, path_b);
    }
}
