/* image_oiio.cpp — image.h on top of OpenImageIO 2.4, in the lumesh_oiio.so module
 * (image_internal.h says why a module; image_module.c opens it).
 *
 * Writing: the descriptor is validated, the pixels are put into the file's
 * type (float for EXR, 8-bit for PNG) and OpenImageIO encodes the file into
 * memory. The bytes are then written here to "<path>.tmp-<pid>-<n>.<ext>"
 * beside the target, flushed to disk, closed and renamed onto the target. A
 * failure at any step removes the temporary file; the target is only ever
 * replaced by rename(), so an existing file survives any failure intact.
 * EXR files carry the caller's channel order in a header attribute.
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

#include <atomic>
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
#include <type_traits>
#include <vector>

#include <fcntl.h>
#include <limits.h>
#include <sys/stat.h>
#include <unistd.h>

namespace {

const int kMaxWriteChannels = 16;
const int kMaxPngChannels = 4;
const size_t kNameCap = sizeof(((img_image *)nullptr)->channel_names[0]); /* 32 */

/* Per-process counter for temporary names; with the pid and O_EXCL it makes
 * concurrent writers (threads or processes) pick distinct names. */
std::atomic<unsigned long> g_temp_counter{0};

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

bool ends_with_ext(const char *path, const char *ext)
{
    const char *slash = std::strrchr(path, '/');
    const char *dot = std::strrchr(path, '.');
    if (!dot || (slash && dot < slash)) return false;
    const char *p = dot + 1;
    size_t i = 0;
    for (; p[i] && ext[i]; ++i) {
        char c = p[i];
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        if (c != ext[i]) return false;
    }
    return p[i] == '\0' && ext[i] == '\0';
}

const char *format_label(img_format f) { return f == IMG_FORMAT_PNG8 ? "PNG" : "EXR"; }

lm_result validate(const img_write_desc *d, img_format *fmt, size_t *count, lm_error *err)
{
    if (!d) return lm_fail(err, LM_ERR_INVALID_ARG, "img_write: no descriptor");
    if (!d->path || !d->path[0])
        return lm_fail(err, LM_ERR_INVALID_ARG, "img_write: no output path");
    const char *path = d->path;

    /* C callers may store any value of the enum's underlying type; reading an
     * out-of-range value as img_format is undefined in C++, so look at the
     * bytes first. */
    std::underlying_type<img_format>::type raw;
    static_assert(sizeof raw == sizeof d->format, "enum layout");
    std::memcpy(&raw, &d->format, sizeof raw);
    long long fv = (long long)raw;
    if (fv < 0 || fv >= (long long)IMG_FORMAT_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: unknown image format %lld", path, fv);
    img_format f = (img_format)fv;
    if (f == IMG_FORMAT_FROM_EXTENSION) {
        if (ends_with_ext(path, "exr"))
            f = IMG_FORMAT_EXR_FLOAT;
        else if (ends_with_ext(path, "png"))
            f = IMG_FORMAT_PNG8;
        else
            return lm_fail(err, LM_ERR_INVALID_ARG,
                           "%s: unsupported image file extension (supported: .exr, .png)", path);
    }

    if (d->width <= 0 || d->height <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: invalid image size %dx%d", path, d->width,
                       d->height);
    int max_ch = f == IMG_FORMAT_PNG8 ? kMaxPngChannels : kMaxWriteChannels;
    if (d->channels < 1 || d->channels > max_ch)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: %d channels; %s takes 1 to %d", path,
                       d->channels, format_label(f), max_ch);
    /* width*height*channels floats must be addressable (and fit a ptrdiff_t). */
    size_t w = (size_t)d->width, h = (size_t)d->height, c = (size_t)d->channels;
    size_t limit = (size_t)PTRDIFF_MAX / sizeof(float);
    if (w > limit / h || w * h > limit / c)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: image of %dx%dx%d values is too large", path,
                       d->width, d->height, d->channels);

    if ((d->pixels != nullptr) == (d->pixels8 != nullptr))
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "%s: exactly one of pixels (float) and pixels8 (8-bit) must be given", path);
    if (d->pixels8 && f != IMG_FORMAT_PNG8)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: 8-bit pixels can only be written as PNG",
                       path);

    if (d->channel_names) {
        for (int i = 0; i < d->channels; ++i) {
            const char *n = d->channel_names[i];
            if (!n || !n[0])
                return lm_fail(err, LM_ERR_INVALID_ARG, "%s: channel %d has no name", path, i);
            if (std::strlen(n) >= kNameCap)
                return lm_fail(err, LM_ERR_INVALID_ARG,
                               "%s: channel name \"%.40s...\" is longer than %zu bytes", path, n,
                               kNameCap - 1);
            for (const char *q = n; *q; ++q)
                if ((unsigned char)*q < 0x20 || *q == 0x7f)
                    return lm_fail(err, LM_ERR_INVALID_ARG,
                                   "%s: channel %d name contains a control character", path, i);
            for (int j = 0; j < i; ++j)
                if (std::strcmp(n, d->channel_names[j]) == 0)
                    return lm_fail(err, LM_ERR_INVALID_ARG,
                                   "%s: channel name \"%s\" is used twice", path, n);
        }
    }
    *fmt = f;
    *count = w * h * c;
    return LM_OK;
}

/* The temporary file: removed on destruction unless committed. */
struct TempFile {
    std::string path;
    int fd = -1;
    bool live = false;
    TempFile() = default;
    TempFile(const TempFile &) = delete;
    TempFile &operator=(const TempFile &) = delete;
    ~TempFile()
    {
        if (fd >= 0) ::close(fd);
        if (live) ::unlink(path.c_str());
    }
};

/* Creates (O_EXCL) an empty "<dir>/<base>.tmp-<pid>-<n>.<ext>" beside target
 * and leaves it open for writing. A long base name is shortened so that the
 * temporary name stays within NAME_MAX even when the target's name is itself
 * near the limit. */
lm_result make_temp(const std::string &target, const char *ext, TempFile &tmp, lm_error *err)
{
    size_t slash = target.rfind('/');
    std::string dir = slash == std::string::npos ? std::string() : target.substr(0, slash + 1);
    std::string base = slash == std::string::npos ? target : target.substr(slash + 1);
    int last_errno = 0;
    std::string name;
    for (int attempt = 0; attempt < 64; ++attempt) {
        char suffix[96];
        unsigned long n = g_temp_counter.fetch_add(1, std::memory_order_relaxed);
        std::snprintf(suffix, sizeof suffix, ".tmp-%ld-%lu.%s", (long)getpid(), n, ext);
        size_t room = (size_t)NAME_MAX - std::strlen(suffix);
        std::string b = base;
        if (b.size() > room) {
            size_t cut = room;
            /* do not split a UTF-8 sequence */
            while (cut > 0 && ((unsigned char)b[cut] & 0xC0) == 0x80) --cut;
            b.resize(cut);
        }
        name = dir + b + suffix;
        int fd = ::open(name.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) {
            tmp.path = name;
            tmp.fd = fd;
            tmp.live = true;
            return LM_OK;
        }
        last_errno = errno;
        if (last_errno != EEXIST) break;
    }
    return lm_fail(err, LM_ERR_IO, "%s: cannot create temporary file %s: %s", target.c_str(),
                   name.c_str(), std::strerror(last_errno));
}

/* Writes the whole buffer, then flushes it to stable storage and closes, so
 * that every error (short write, EFBIG, ENOSPC, EIO on writeback) is seen
 * before the file replaces the target. */
lm_result write_file(const char *target, TempFile &tmp, const unsigned char *data, size_t size,
                     lm_error *err)
{
    size_t done = 0;
    while (done < size) {
        ssize_t n = ::write(tmp.fd, data + done, size - done);
        if (n < 0) {
            if (errno == EINTR) continue;
            return lm_fail(err, LM_ERR_IO, "%s: cannot write temporary file %s: %s", target,
                           tmp.path.c_str(), std::strerror(errno));
        }
        if (n == 0)
            return lm_fail(err, LM_ERR_IO, "%s: cannot write temporary file %s: no progress",
                           target, tmp.path.c_str());
        done += (size_t)n;
    }
    if (::fsync(tmp.fd) != 0 && errno != EINVAL && errno != EROFS) /* EINVAL: cannot sync */
        return lm_fail(err, LM_ERR_IO, "%s: cannot flush temporary file %s: %s", target,
                       tmp.path.c_str(), std::strerror(errno));
    int fd = tmp.fd;
    tmp.fd = -1;
    if (::close(fd) != 0)
        return lm_fail(err, LM_ERR_IO, "%s: cannot close temporary file %s: %s", target,
                       tmp.path.c_str(), std::strerror(errno));
    return LM_OK;
}

/* EXR stores channels sorted by name and OpenImageIO reorders them again on
 * reading, so the order the caller gave is kept in this header attribute
 * (names separated by '\n') and restored by img_read. */
const char *const kChannelOrderAttr = "lumesh:channelOrder";

lm_result write_impl(const img_write_desc *d, lm_error *err)
{
    img_format fmt = IMG_FORMAT_FROM_EXTENSION;
    size_t count = 0;
    lm_result r = validate(d, &fmt, &count, err);
    if (r != LM_OK) return r;
    const char *path = d->path;
    const bool png = fmt == IMG_FORMAT_PNG8;
    const int nch = d->channels;
    const char *label = format_label(fmt);

    /* Pixels in the file's type. */
    std::vector<uint8_t> bytes;
    const void *data = nullptr;
    if (png) {
        if (d->pixels8) {
            data = d->pixels8;
        } else {
            bytes.resize(count);
            for (size_t i = 0; i < count; ++i) {
                float v = d->pixels[i];
                /* NaN fails both tests and ends at 0. */
                v = v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f;
                bytes[i] = (uint8_t)(v * 255.0f + 0.5f);
            }
            data = bytes.data();
        }
    } else {
        data = d->pixels;
    }

    OIIO::ImageSpec spec(d->width, d->height, nch,
                         png ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT);
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
    if (png) {
        /* PNG has no channel names: gray, gray+alpha, RGB, RGBA by count. */
        if (nch == 2 || nch == 4) spec.alpha_channel = nch - 1;
        /* The data is written exactly as given: no un-premultiplication. */
        spec.attribute("oiio:UnassociatedAlpha", 1);
    } else {
        std::string order;
        for (int i = 0; i < nch; ++i) {
            if (spec.channelnames[i] == "A") spec.alpha_channel = i;
            if (i) order += '\n';
            order += spec.channelnames[i];
        }
        spec.attribute(kChannelOrderAttr, order);
        spec.attribute("compression", "zip");
        for (const char *const *a = d->attributes; a && a[0] && a[1]; a += 2) spec.attribute(a[0], a[1]);
    }

    /* The file is encoded into memory and written out here, not by the
     * plugin: OpenImageIO 2.4's PNG writer ignores failed writes (a full disk
     * gives a truncated PNG and success), and this way every write is checked
     * and nothing touches the disk unless encoding succeeded. */
    std::vector<unsigned char> encoded;
    OIIO::Filesystem::IOVecOutput memout(encoded);
    auto out = OIIO::ImageOutput::create(png ? "png" : "openexr");
    if (!out)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "%s: OpenImageIO has no %s writer: %s", path,
                       label, output_error(nullptr).c_str());
    if (!out->supports("ioproxy") || !out->set_ioproxy(&memout))
        return lm_fail(err, LM_ERR_UNSUPPORTED,
                       "%s: this OpenImageIO's %s writer cannot write to memory: %s", path, label,
                       output_error(out.get()).c_str());

    if (!out->open(path, spec))
        return lm_fail(err, LM_ERR_IO, "%s: cannot encode %s: %s", path, label,
                       output_error(out.get()).c_str());
    bool ok = out->write_image(png ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT, data);
    ok = out->close() && ok;
    if (!ok)
        return lm_fail(err, LM_ERR_IO, "%s: cannot encode %s: %s", path, label,
                       output_error(out.get()).c_str());
    out.reset();
    if (encoded.empty())
        return lm_fail(err, LM_ERR_IO, "%s: OpenImageIO produced an empty %s file", path, label);

    TempFile tmp;
    r = make_temp(path, png ? "png" : "exr", tmp, err);
    if (r != LM_OK) return r;
    r = write_file(path, tmp, encoded.data(), encoded.size(), err);
    if (r != LM_OK) return r;
    if (std::rename(tmp.path.c_str(), path) != 0)
        return lm_fail(err, LM_ERR_IO, "%s: cannot move %s into place: %s", path,
                       tmp.path.c_str(), std::strerror(errno));
    tmp.live = false;
    return LM_OK;
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
