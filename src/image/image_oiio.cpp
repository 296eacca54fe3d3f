/* image_oiio.cpp — image.h on top of OpenImageIO 2.4, in the lumesh_oiio.so module
 * (image_internal.h says why a module; image_module.c opens it).
 *
 * Writing (EXR only; the program writes PNGs itself, image_png_write.c): the
 * descriptor is checked (img_write_check), OpenImageIO encodes the file into
 * memory and lm_write_file (src/base/util.h) writes it beside the target and
 * renames it onto it, so an existing file survives any failure intact. EXR
 * files carry the caller's channel order in a header attribute.
 *
 * Reading: anything OpenImageIO reads, subimage 0, MIP level 0, converted to
 * float. Alpha is returned as stored (unassociated for PNG). Channels are in
 * the file's order as OpenImageIO reports it, or in the order img_write was
 * given for EXR files it wrote.
 *
 * Every C++ exception stops here and becomes an lm_result.
 */
#include "src/image/image.h"
#include "src/image/image_internal.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace {

const size_t kNameCap = sizeof(((img_image *)nullptr)->channel_names[0]); /* 32 */

struct FreeDeleter {
    void operator()(void *p) const noexcept { std::free(p); }
};

/* OIIO error text as one trimmed line, or a fallback when OIIO said nothing. */
std::string clean_error(std::string s)
{
    for (char &c : s)
        if (c == '\n' || c == '\r' || c == '\t') c = ' ';
    size_t end = s.find_last_not_of(' ');
    s.erase(end == std::string::npos ? 0 : end + 1);
    size_t begin = s.find_first_not_of(' ');
    s.erase(0, begin == std::string::npos ? s.size() : begin);
    return s.empty() ? std::string("unknown OpenImageIO error") : s;
}

std::string output_error(const OIIO::ImageOutput *out)
{
    std::string e = out ? out->geterror() : std::string();
    std::string g = OIIO::geterror(); /* always drain the thread's global error too */
    if (e.empty()) e = g;
    return clean_error(e);
}

std::string input_error(const OIIO::ImageInput *in)
{
    std::string e = in ? in->geterror() : std::string();
    std::string g = OIIO::geterror();
    if (e.empty()) e = g;
    return clean_error(e);
}


/* EXR stores channels sorted by name and OpenImageIO reorders them again on
 * reading, so the order the caller gave is kept in this header attribute
 * (names separated by '\n') and restored by img_read. */
const char *const kChannelOrderAttr = "lumesh:channelOrder";

/* EXR only: the program writes PNGs itself (image_png_write.c). */
lm_result write_impl(const img_write_desc *d, lm_error *err)
{
    img_format fmt = IMG_FORMAT_FROM_EXTENSION;
    size_t count = 0;
    lm_result r = img_write_check(d, &fmt, &count, err);
    if (r != LM_OK) return r;
    const char *path = d->path;
    if (fmt != IMG_FORMAT_EXR_FLOAT)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "%s: the image module writes EXR only (PNG: img_write)", path);
    const int nch = d->channels;

    OIIO::ImageSpec spec(d->width, d->height, nch, OIIO::TypeDesc::FLOAT);
    spec.channelnames.clear();
    static const char *const rgba[4] = {"R", "G", "B", "A"};
    for (int i = 0; i < nch; ++i) {
        if (d->channel_names)
            spec.channelnames.emplace_back(d->channel_names[i]);
        else if (nch <= 4)
            spec.channelnames.emplace_back(rgba[i]);
        else
            spec.channelnames.emplace_back("C" + std::to_string(i));
    }
    spec.alpha_channel = -1;
    spec.z_channel = -1;
    std::string order;
    for (int i = 0; i < nch; ++i) {
        if (spec.channelnames[i] == "A") spec.alpha_channel = i;
        if (i) order += '\n';
        order += spec.channelnames[i];
    }
    spec.attribute(kChannelOrderAttr, order);
    spec.attribute("compression", "zip");
    for (const char *const *a = d->attributes; a && a[0] && a[1]; a += 2) spec.attribute(a[0], a[1]);

    /* The file is encoded into memory and written out by lm_write_file, not by
     * the plugin: every write is checked and nothing touches the disk unless
     * encoding succeeded (OpenImageIO 2.4's PNG writer ignored failed writes). */
    std::vector<unsigned char> encoded;
    OIIO::Filesystem::IOVecOutput memout(encoded);
    auto out = OIIO::ImageOutput::create("openexr");
    if (!out)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "%s: OpenImageIO has no EXR writer: %s", path,
                       output_error(nullptr).c_str());
    if (!out->supports("ioproxy") || !out->set_ioproxy(&memout))
        return lm_fail(err, LM_ERR_UNSUPPORTED, "%s: this OpenImageIO's EXR writer cannot write to memory: %s",
                       path, output_error(out.get()).c_str());
    if (!out->open(path, spec))
        return lm_fail(err, LM_ERR_IO, "%s: cannot encode EXR: %s", path, output_error(out.get()).c_str());
    bool ok = out->write_image(OIIO::TypeDesc::FLOAT, d->pixels);
    ok = out->close() && ok;
    if (!ok) return lm_fail(err, LM_ERR_IO, "%s: cannot encode EXR: %s", path, output_error(out.get()).c_str());
    out.reset();
    if (encoded.empty()) return lm_fail(err, LM_ERR_IO, "%s: OpenImageIO produced an empty EXR file", path);
    (void)count;
    return lm_write_file(path, "exr", encoded.data(), encoded.size(), err);
}

void copy_name(char *dst, const std::string &src)
{
    size_t n = src.size() < kNameCap - 1 ? src.size() : kNameCap - 1;
    std::memcpy(dst, src.data(), n);
    dst[n] = '\0';
}

/* Puts the channels back in the order img_write was given, when the file
 * says what it was and it is a permutation of the channels found. */
void restore_channel_order(const OIIO::ImageSpec &spec, float *px, char (*names)[32],
                           size_t npixels)
{
    std::string order = spec.get_string_attribute(kChannelOrderAttr);
    if (order.empty()) return;
    const size_t nch = (size_t)spec.nchannels;
    std::vector<std::string> want;
    for (size_t start = 0;;) {
        size_t nl = order.find('\n', start);
        want.push_back(order.substr(start, nl == std::string::npos ? nl : nl - start));
        if (nl == std::string::npos) break;
        start = nl + 1;
    }
    if (want.size() != nch || spec.channelnames.size() != nch) return;
    std::vector<size_t> from(nch); /* output channel i comes from file channel from[i] */
    std::vector<bool> used(nch, false);
    bool identity = true;
    for (size_t i = 0; i < nch; ++i) {
        size_t k = 0;
        while (k < nch && (used[k] || spec.channelnames[k] != want[i])) ++k;
        if (k == nch) return; /* not a permutation: keep OpenImageIO's order */
        used[k] = true;
        from[i] = k;
        identity = identity && k == i;
    }
    if (identity) return;
    std::vector<float> pixel(nch);
    for (size_t p = 0; p < npixels; ++p) {
        float *v = px + p * nch;
        for (size_t i = 0; i < nch; ++i) pixel[i] = v[from[i]];
        std::memcpy(v, pixel.data(), nch * sizeof(float));
    }
    for (size_t i = 0; i < nch; ++i) copy_name(names[i], want[i]);
}

lm_result read_impl(const char *path, img_image *out, lm_error *err)
{
    struct stat st;
    if (::stat(path, &st) != 0)
        return lm_fail(err, LM_ERR_IO, "%s: cannot open: %s", path, std::strerror(errno));
    if (S_ISDIR(st.st_mode))
        return lm_fail(err, LM_ERR_IO, "%s: is a directory, not an image", path);
    if (!S_ISREG(st.st_mode)) /* a FIFO would block the open below */
        return lm_fail(err, LM_ERR_IO, "%s: is not a regular file (a pipe, device or socket)", path);
    int fd = ::open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return lm_fail(err, LM_ERR_IO, "%s: cannot open: %s", path, std::strerror(errno));
    ::close(fd);

    /* The file is there and readable: from here on a failure is its content. */
    if (lm_result framing = img_check_png(path, err); framing != LM_OK) return framing;
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(path, &config);
    if (!in)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read image: %s", path,
                       input_error(nullptr).c_str());

    const OIIO::ImageSpec &spec = in->spec();
    if (spec.deep)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "%s: deep images are not supported", path);
    if (spec.depth > 1)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "%s: volume images (depth %d) are not supported",
                       path, spec.depth);
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: image has size %dx%d with %d channels", path,
                       spec.width, spec.height, spec.nchannels);
    size_t w = (size_t)spec.width, h = (size_t)spec.height, c = (size_t)spec.nchannels;
    /* At most 2^28 values (1 GiB as float; 8192x8192 RGBA) and 2^21 a row: a
     * broken header can claim any size, and OpenImageIO allocates what it claims
     * before it finds the pixels missing. Found by fuzzing: a 700-byte EXR of
     * 3932164x3 pixels, 7 channels, for which OpenImageIO asked 28 GB (a chunk
     * of 256 such rows; EXR chunks hold up to 256). */
    const size_t limit = (size_t)1 << 28, row_limit = (size_t)1 << 21;
    if (w > row_limit / c || w * c * h > limit)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: image of %dx%dx%d values is larger than lumesh reads (2^28 values, 2^21 a row)",
                       path, spec.width, spec.height, spec.nchannels);
    size_t count = w * h * c;

    std::unique_ptr<float, FreeDeleter> px((float *)std::malloc(count * sizeof(float)));
    std::unique_ptr<char[32], FreeDeleter> names((char(*)[32])std::calloc(c, kNameCap));
    if (!px || !names)
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory for a %dx%dx%d image", path,
                       spec.width, spec.height, spec.nchannels);

    for (int i = 0; i < spec.nchannels; ++i) {
        if ((size_t)i < spec.channelnames.size() && !spec.channelnames[i].empty())
            copy_name(names.get()[i], spec.channelnames[i]);
        else
            copy_name(names.get()[i], "C" + std::to_string(i));
    }

    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.get()))
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read pixels: %s", path,
                       input_error(in.get()).c_str());
    in->close();
    in->geterror(); /* nothing may stay pending */

    restore_channel_order(spec, px.get(), names.get(), w * h);
    out->attribute_count = 0;
    for (const OIIO::ParamValue &p : spec.extra_attribs) {
        std::string name = p.name().string();
        if (name.rfind("lumesh:", 0) != 0 || name == kChannelOrderAttr || p.type() != OIIO::TypeDesc::STRING ||
            out->attribute_count >= IMG_ATTRIBUTES_MAX)
            continue;
        std::string value = p.get_string();
        std::snprintf(out->attributes[out->attribute_count][0], IMG_ATTRIBUTE_CAP, "%s", name.c_str());
        std::snprintf(out->attributes[out->attribute_count][1], IMG_ATTRIBUTE_CAP, "%s", value.c_str());
        out->attribute_count++;
    }

    out->width = spec.width;
    out->height = spec.height;
    out->channels = spec.nchannels;
    out->pixels = px.release();
    out->channel_names = names.release();
    return LM_OK;
}

} // namespace

extern "C" lm_result img_oiio_write(const img_write_desc *desc, lm_error *err)
{
    const char *path = desc && desc->path ? desc->path : "(no path)";
    try {
        return write_impl(desc, err);
    } catch (const std::bad_alloc &) {
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory writing the image", path);
    } catch (const std::exception &e) {
        return lm_fail(err, LM_ERR_RUNTIME, "%s: error writing the image: %s", path, e.what());
    } catch (...) {
        return lm_fail(err, LM_ERR_RUNTIME, "%s: unknown error writing the image", path);
    }
}

extern "C" lm_result img_oiio_read(const char *path, img_image *out, lm_error *err)
{
    if (!out) return lm_fail(err, LM_ERR_INVALID_ARG, "img_read: no output image");
    *out = img_image{};
    if (!path || !path[0]) return lm_fail(err, LM_ERR_INVALID_ARG, "img_read: no input path");
    try {
        return read_impl(path, out, err);
    } catch (const std::bad_alloc &) {
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory reading the image", path);
    } catch (const std::exception &e) {
        return lm_fail(err, LM_ERR_RUNTIME, "%s: error reading the image: %s", path, e.what());
    } catch (...) {
        return lm_fail(err, LM_ERR_RUNTIME, "%s: unknown error reading the image", path);
    }
}

/* The module's entry point (image_internal.h): the one symbol it exports. */
extern "C" __attribute__((visibility("default"))) const img_oiio_api *lumesh_oiio_api(void)
{
    static const img_oiio_api api = {IMG_OIIO_API_VERSION, IMG_OIIO_API_SIZES, img_oiio_write, img_oiio_read,
                                     img_oiio_compare};
    return &api;
}
