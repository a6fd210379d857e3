#include "ig/terrain_io.hpp"

#include "base/check.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <jpeglib.h>
#include <ogr_srs_api.h>
#include <png.h>
#include <sys/stat.h>

#include <jerror.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <span>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "base/text.hpp"
#include "ig/error.hpp"
#include "ig/terrain_db_build.hpp"

// The magic bytes pick the reader (libpng, libjpeg, or GDAL for everything else); each reader
// returns its raster in file order, which is then turned north-up, converted to the map's integer
// heights and the colour image resampled onto the height grid. docs/formats.md has the rules.

namespace ig {
namespace {

static_assert(sizeof(Rgb8) == 3,
              "Rgb8 must be three packed bytes: images are read straight into it");

// Most bytes read from a pipe or other file that cannot seek: a map at the sample limit as
// uncompressed 32-bit floats.
constexpr std::uint64_t kMaxStreamBytes = std::uint64_t{4} * kMaxImageSamples;

// Deflate cannot expand data more than 1032-fold (a 258-byte match in two bits at best): a PNG
// whose header claims more pixel bytes than that of the whole file is truncated or corrupt.
constexpr std::uint64_t kDeflateMaxRatio = 1032;

// A Huffman-coded JPEG spends at least one bit on every 8 x 8 block of each component a scan
// holds, and a block of a component subsampled 4 x 4 spans 32 x 32 pixels: at most 8192 pixels
// per byte of file. (Arithmetic-coded files, rare, can go beyond; they are held to it too.)
constexpr std::uint64_t kJpegMaxPixelsPerByte = 8192;

[[noreturn]] void fail(const std::string& path, const std::string& what) {
    throw InputError(path + ": " + what);
}

std::string formatNumber(double v) {
    std::ostringstream s;
    s.precision(10);
    s << v;
    return s.str();
}

// Readable size of a byte count for messages ("1.8 GB").
std::string formatBytes(double bytes) {
    if (bytes >= 1e9) return base::number(bytes / 1e9, 3) + " GB";
    if (bytes >= 1e6) return base::number(bytes / 1e6, 3) + " MB";
    if (bytes >= 1e3) return base::number(bytes / 1e3, 3) + " kB";
    return base::number(bytes, 6) + " bytes";
}

void checkSize(const std::string& path, long long width, long long height, std::size_t maxSamples) {
    if (width <= 0 || height <= 0) fail(path, "image has no pixels");
    if (static_cast<unsigned long long>(width) * static_cast<unsigned long long>(height) >
            maxSamples ||
        width > (1LL << 30) || height > (1LL << 30)) {
        fail(path, "image too large (" + std::to_string(width) + " x " + std::to_string(height) +
                       " samples; at most " + std::to_string(maxSamples) + " supported)");
    }
}

// ---------------------------------------------------------------------------------------------
// Inputs: a file on disk, read by the decoders themselves, or bytes in memory (given by the
// caller, or read whole from a pipe, which libpng, libjpeg and GDAL cannot seek in). The magic
// bytes decide the reader; the extension only sharpens the message.

enum class FileKind { Png, Jpeg, Gdal };

struct ImageInput {
    std::string path;                     // names the input in messages; the file when on disk
    bool inMemory = false;                // bytes below, else the file at path
    std::span<const std::uint8_t> bytes;  // the whole file
    std::vector<std::uint8_t> storage;    // what was read from a pipe (bytes points into it)
    std::uint64_t size = 0;               // bytes in the file
    std::size_t maxSamples = kMaxImageSamples;
    FileKind kind = FileKind::Gdal;
    ImageInput() = default;
    ImageInput(const ImageInput&) = delete;
    ImageInput& operator=(const ImageInput&) = delete;
};

std::string lowerExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

// Reads the rest of a stream that cannot seek, at most kMaxStreamBytes.
void readStream(const std::string& path, std::FILE* f, std::vector<std::uint8_t>& out) {
    std::uint8_t buf[1 << 16];
    for (;;) {
        const std::size_t n = std::fread(buf, 1, sizeof buf, f);
        if (n == 0) break;
        if (out.size() + n > kMaxStreamBytes) {
            fail(path, "more than " + formatBytes(static_cast<double>(kMaxStreamBytes)) +
                           " read without reaching the end; not an image this loader takes");
        }
        out.insert(out.end(), buf, buf + n);
    }
    if (std::ferror(f)) fail(path, std::string("read failed: ") + std::strerror(errno));
}

FileKind sniffMagic(const std::string& path, const std::uint8_t* magic, std::size_t n) {
    if (n >= 8 && png_sig_cmp(magic, 0, sizeof magic) == 0) return FileKind::Png;
    if (n >= 3 && magic[0] == 0xFF && magic[1] == 0xD8 && magic[2] == 0xFF) return FileKind::Jpeg;
    if (n == 0) fail(path, "file is empty");
    const std::string ext = lowerExtension(path);
    if (ext == ".png") fail(path, "not a PNG file (bad signature)");
    if (ext == ".jpg" || ext == ".jpeg") fail(path, "not a JPEG file (bad signature)");
    return FileKind::Gdal;
}

// Finds out what `path` (or `bytes`, when given) holds; a file that cannot seek is read whole.
void openInput(const std::string& path, std::span<const std::uint8_t> bytes, std::size_t maxSamples,
               ImageInput& in) {
    if (path.empty()) throw InputError("terrain file name is empty");
    in.path = path;
    in.maxSamples = maxSamples;
    if (!bytes.empty()) {
        in.inMemory = true;
        in.bytes = bytes;
        in.size = bytes.size();
        in.kind = sniffMagic(path, bytes.data(), bytes.size());
        return;
    }
    // GDAL virtual file systems (/vsizip/, /vsicurl/, ...) are not local files.
    if (path.rfind("/vsi", 0) == 0) {
        in.kind = FileKind::Gdal;
        return;
    }
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) fail(path, "is a directory, not an image file");
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) fail(path, std::string("cannot open: ") + std::strerror(errno));
    const std::unique_ptr<std::FILE, int (*)(std::FILE*)> guard(f, std::fclose);
    struct stat st {};
    if (::fstat(::fileno(f), &st) == 0 && S_ISREG(st.st_mode)) {
        in.size = static_cast<std::uint64_t>(st.st_size);
        std::uint8_t magic[8] = {};
        const std::size_t n = std::fread(magic, 1, sizeof magic, f);
        in.kind = sniffMagic(path, magic, n);
        return;
    }
    // A pipe, terminal or device: the decoders seek or read twice, so hold it all.
    readStream(path, f, in.storage);
    in.inMemory = true;
    in.bytes = in.storage;
    in.size = in.storage.size();
    in.kind = sniffMagic(path, in.storage.data(), in.storage.size());
}

// Whether a PNG or JPEG comes with a georeference beside it (a world file such as photo.jgw,
// or GDAL's photo.jpg.aux.xml): then GDAL reads it, georeference included.
bool hasGeoSidecar(const std::string& path) {
    namespace fs = std::filesystem;
    const std::string ext = lowerExtension(path);
    std::vector<std::string> sidecars = {".wld"};
    if (ext == ".png") sidecars = {".pgw", ".pngw", ".wld"};
    if (ext == ".jpg" || ext == ".jpeg") sidecars = {".jgw", ".jpgw", ".jpegw", ".wld"};
    std::error_code ec;
    for (std::string e : sidecars) {
        if (fs::exists(fs::path(path).replace_extension(e), ec)) return true;
        for (char& c : e)
            c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
        if (fs::exists(fs::path(path).replace_extension(e), ec)) return true;
    }
    return fs::exists(path + ".aux.xml", ec);
}

// ---------------------------------------------------------------------------------------------
// Rasters as read, rows in file order, then normalised to north-up, east-right.

// Geotransform and the units of its coordinate system.
struct Georef {
    bool valid = false;    // the file has a geotransform
    bool rotated = false;  // with rotation/shear terms (not used for spacing or alignment)
    double gt[6] = {0, 1, 0, 0, 0, 1};
    bool geographic = false;    // coordinates are angles
    double degreesPerUnit = 1;  // geographic: size of one coordinate unit in degrees
    double metresPerUnit = 1;   // projected (or no SRS): size of one coordinate unit in metres
    std::shared_ptr<void> srs;  // OGRSpatialReferenceH (cloned), null when the file has none
};

struct HeightRaster {
    int width = 0, height = 0;
    bool integer = false;            // raw integer units (PNG/JPEG) in `raw`, else `values`
    std::vector<std::uint16_t> raw;  // integer images
    std::vector<double> values;      // GDAL rasters, metres after the user's scale/offset
    std::size_t filled = 0;          // samples without data, filled (values only)
    Georef geo;
};

struct ColorRaster {
    int width = 0, height = 0;
    std::vector<Rgb8> pixels;
    Georef geo;
};

template <typename T>
void flipRows(std::vector<T>& v, int width, int height) {
    for (int r = 0; r < height / 2; ++r) {
        auto a = v.begin() + static_cast<std::ptrdiff_t>(r) * width;
        auto b = v.begin() + static_cast<std::ptrdiff_t>(height - 1 - r) * width;
        std::swap_ranges(a, a + width, b);
    }
}

template <typename T>
void flipColumns(std::vector<T>& v, int width, int height) {
    for (int r = 0; r < height; ++r) {
        auto a = v.begin() + static_cast<std::ptrdiff_t>(r) * width;
        std::reverse(a, a + width);
    }
}

// Makes file row 0 the north edge and column 0 the west edge, adjusting the geotransform.
template <typename T>
void normaliseOrientation(std::vector<T>& v, int width, int height, Georef& geo) {
    if (!geo.valid || geo.rotated) return;
    if (geo.gt[1] < 0) {
        flipColumns(v, width, height);
        geo.gt[0] += geo.gt[1] * width;
        geo.gt[1] = -geo.gt[1];
    }
    if (geo.gt[5] > 0) {
        flipRows(v, width, height);
        geo.gt[3] += geo.gt[5] * height;
        geo.gt[5] = -geo.gt[5];
    }
}

// ---------------------------------------------------------------------------------------------
// PNG via libpng. libpng reports errors by longjmp: every function that calls into it sets its
// own jump point and holds only trivially destructible locals; the owning objects live in the
// caller's frame, which is never jumped over.

struct PngErrorState {
    char message[256] = {};
};

[[noreturn]] void pngError(png_structp png, png_const_charp msg) {
    auto* state = static_cast<PngErrorState*>(png_get_error_ptr(png));
    std::snprintf(state->message, sizeof state->message, "%s", msg ? msg : "unknown error");
    png_longjmp(png, 1);
}

void pngWarning(png_structp, png_const_charp) {}

// Bytes in memory handed to libpng in the pieces it asks for.
struct PngMemorySource {
    std::span<const std::uint8_t> bytes;
    std::size_t at = 0;
};

void pngReadMemory(png_structp png, png_bytep out, png_size_t n) {
    auto* src = static_cast<PngMemorySource*>(png_get_io_ptr(png));
    if (n > src->bytes.size() - src->at) png_error(png, "unexpected end of data");
    std::memcpy(out, src->bytes.data() + src->at, n);
    src->at += n;
}

struct PngReader {
    std::FILE* file = nullptr;
    PngMemorySource memory;
    png_structp png = nullptr;
    png_infop info = nullptr;
    PngErrorState error;
    PngReader() = default;
    PngReader(const PngReader&) = delete;
    PngReader& operator=(const PngReader&) = delete;
    ~PngReader() {
        if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
        if (file) std::fclose(file);
    }
};

struct PngHeader {
    png_uint_32 width = 0, height = 0;
    int bitDepth = 0, colorType = 0, channels = 0;
};

bool pngReadHeader(png_structp png, png_infop info, PngHeader* header) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_read_info(png, info);
    header->width = png_get_image_width(png, info);
    header->height = png_get_image_height(png, info);
    header->bitDepth = png_get_bit_depth(png, info);
    header->colorType = png_get_color_type(png, info);
    header->channels = png_get_channels(png, info);
    return true;
}

// Sets the transforms that turn any PNG into 8-bit RGB (toRgb) or leaves samples as they are.
bool pngPrepare(png_structp png, png_infop info, bool toRgb, png_size_t* rowBytes) {
    if (setjmp(png_jmpbuf(png))) return false;
    if (toRgb) {
        const int colorType = png_get_color_type(png, info);
        const int bitDepth = png_get_bit_depth(png, info);
        if (colorType == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
        if ((colorType & PNG_COLOR_MASK_COLOR) == 0 && bitDepth < 8) {
            png_set_expand_gray_1_2_4_to_8(png);
        }
        if (bitDepth == 16) png_set_scale_16(png);
        if (colorType & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(png);
        if ((colorType & PNG_COLOR_MASK_COLOR) == 0) png_set_gray_to_rgb(png);
    }
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    *rowBytes = png_get_rowbytes(png, info);
    return true;
}

bool pngReadRows(png_structp png, png_bytepp rows) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_read_image(png, rows);
    png_read_end(png, nullptr);
    return true;
}

std::string pngColorTypeName(int colorType) {
    switch (colorType) {
        case PNG_COLOR_TYPE_GRAY:
            return "greyscale";
        case PNG_COLOR_TYPE_GRAY_ALPHA:
            return "greyscale with alpha";
        case PNG_COLOR_TYPE_PALETTE:
            return "palette (indexed colour)";
        case PNG_COLOR_TYPE_RGB:
            return "RGB";
        case PNG_COLOR_TYPE_RGB_ALPHA:
            return "RGB with alpha";
        default:
            return "unknown colour type";
    }
}

// Opens the input, reads its header, and checks the size it claims against the budget and the
// file's length before anything is allocated for the pixels. Throws InputError on failure.
void pngOpen(const ImageInput& in, PngReader& r, PngHeader& header) {
    const std::string& path = in.path;
    if (!in.inMemory) {
        r.file = std::fopen(path.c_str(), "rb");
        if (!r.file) fail(path, std::string("cannot open: ") + std::strerror(errno));
    }
    r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r.error, pngError, pngWarning);
    if (!r.png) fail(path, "out of memory opening PNG");
    r.info = png_create_info_struct(r.png);
    if (!r.info) fail(path, "out of memory opening PNG");
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
    // Fuzzing: mutated chunks reach the checks after the checksums (never in the product).
    png_set_crc_action(r.png, PNG_CRC_QUIET_USE, PNG_CRC_QUIET_USE);
    png_set_option(r.png, PNG_IGNORE_ADLER32, PNG_OPTION_ON);
#endif
    if (in.inMemory) {
        r.memory.bytes = in.bytes;
        png_set_read_fn(r.png, &r.memory, pngReadMemory);
    } else {
        png_init_io(r.png, r.file);
    }
    if (!pngReadHeader(r.png, r.info, &header)) {
        fail(path, std::string("corrupt or truncated PNG (") + r.error.message + ")");
    }
    checkSize(path, header.width, header.height, in.maxSamples);
    const std::uint64_t rowBytes =
        (std::uint64_t{header.width} * header.channels * header.bitDepth + 7) / 8;
    const std::uint64_t claimed = rowBytes * header.height;
    if (claimed > kDeflateMaxRatio * in.size + 1024) {
        fail(path, "PNG header claims " + std::to_string(header.width) + " x " +
                       std::to_string(header.height) + " pixels (" +
                       formatBytes(static_cast<double>(claimed)) +
                       " of image data) but the file has only " +
                       formatBytes(static_cast<double>(in.size)) +
                       ", which deflate cannot expand to more than 1032 times its size: the file "
                       "is truncated or corrupt");
    }
}

// Reads the image rows of an opened PNG into `pixels` (rowBytes per row, file order).
void pngReadPixels(const std::string& path, PngReader& r, std::size_t height, std::size_t rowBytes,
                   std::vector<std::uint8_t>& pixels) {
    pixels.resize(rowBytes * height);
    std::vector<png_bytep> rows(height);
    for (std::size_t y = 0; y < height; ++y)
        rows[y] = pixels.data() + y * rowBytes;
    if (!pngReadRows(r.png, rows.data())) {
        fail(path, std::string("corrupt or truncated PNG (") + r.error.message + ")");
    }
}

HeightRaster readPngHeights(const ImageInput& in) {
    const std::string& path = in.path;
    PngReader r;
    PngHeader header;
    pngOpen(in, r, header);
    if (header.colorType != PNG_COLOR_TYPE_GRAY) {
        fail(path, "height map must be an 8- or 16-bit greyscale PNG; this one is " +
                       pngColorTypeName(header.colorType));
    }
    if (header.bitDepth != 8 && header.bitDepth != 16) {
        fail(path, "height map must be an 8- or 16-bit greyscale PNG; this one has " +
                       std::to_string(header.bitDepth) + "-bit samples");
    }
    png_size_t rowBytes = 0;
    if (!pngPrepare(r.png, r.info, false, &rowBytes)) {
        fail(path, std::string("corrupt PNG (") + r.error.message + ")");
    }
    const std::size_t w = header.width, h = header.height;
    const std::size_t bytesPerSample = header.bitDepth / 8;
    if (rowBytes != w * bytesPerSample) fail(path, "unexpected PNG row layout");
    std::vector<std::uint8_t> pixels;
    pngReadPixels(path, r, h, rowBytes, pixels);

    HeightRaster out;
    out.width = static_cast<int>(w);
    out.height = static_cast<int>(h);
    out.integer = true;
    out.raw.resize(w * h);
    if (bytesPerSample == 1) {
        std::copy(pixels.begin(), pixels.end(), out.raw.begin());
    } else {
        for (std::size_t k = 0; k < w * h; ++k) {  // PNG stores 16-bit samples big-endian
            out.raw[k] = static_cast<std::uint16_t>((pixels[2 * k] << 8) | pixels[2 * k + 1]);
        }
    }
    return out;
}

ColorRaster readPngColors(const ImageInput& in) {
    const std::string& path = in.path;
    PngReader r;
    PngHeader header;
    pngOpen(in, r, header);
    png_size_t rowBytes = 0;
    if (!pngPrepare(r.png, r.info, true, &rowBytes)) {
        fail(path, std::string("corrupt PNG (") + r.error.message + ")");
    }
    const std::size_t w = header.width, h = header.height;
    if (rowBytes != w * 3) fail(path, "unexpected PNG row layout after conversion to RGB");
    std::vector<std::uint8_t> pixels;
    pngReadPixels(path, r, h, rowBytes, pixels);
    ColorRaster out;
    out.width = static_cast<int>(w);
    out.height = static_cast<int>(h);
    out.pixels.resize(w * h);
    std::memcpy(out.pixels.data(), pixels.data(), pixels.size());
    return out;
}

// ---------------------------------------------------------------------------------------------
// JPEG via libjpeg; errors longjmp exactly as with libpng (same frame discipline).

struct JpegErrorState {
    jpeg_error_mgr manager;  // first member: libjpeg hands back a pointer to it
    std::jmp_buf jump;
    char message[JMSG_LENGTH_MAX] = {};
    bool truncated = false;
};

[[noreturn]] void jpegErrorExit(j_common_ptr cinfo) {
    auto* state = reinterpret_cast<JpegErrorState*>(cinfo->err);
    (*cinfo->err->format_message)(cinfo, state->message);
    std::longjmp(state->jump, 1);
}

// Warnings are silent, except a premature end of data, which is an error here, raised at once:
// libjpeg would otherwise pad the rest of the image with grey (of any size the header claims).
void jpegEmitMessage(j_common_ptr cinfo, int level) {
    if (level < 0 && cinfo->err->msg_code == JWRN_JPEG_EOF) {
        reinterpret_cast<JpegErrorState*>(cinfo->err)->truncated = true;
        jpegErrorExit(cinfo);
    }
}

struct JpegReader {
    std::FILE* file = nullptr;
    jpeg_decompress_struct cinfo{};
    JpegErrorState error{};
    bool created = false;
    JpegReader() = default;
    JpegReader(const JpegReader&) = delete;
    JpegReader& operator=(const JpegReader&) = delete;
    ~JpegReader() {
        if (created) jpeg_destroy_decompress(&cinfo);
        if (file) std::fclose(file);
    }
};

bool jpegReadHeader(jpeg_decompress_struct* cinfo, JpegErrorState* error, std::FILE* file,
                    std::span<const std::uint8_t> bytes) {
    if (setjmp(error->jump)) return false;
    jpeg_create_decompress(cinfo);
    if (file) {
        jpeg_stdio_src(cinfo, file);
    } else {
        jpeg_mem_src(cinfo, bytes.data(), static_cast<unsigned long>(bytes.size()));
    }
    jpeg_read_header(cinfo, TRUE);
    // Grey stays grey (expanded to RGB by the caller); everything else is converted to RGB.
    cinfo->out_color_space = cinfo->num_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
    return true;
}

// Progressive files are read whole here, into coefficients for the whole image.
bool jpegStart(jpeg_decompress_struct* cinfo, JpegErrorState* error) {
    if (setjmp(error->jump)) return false;
    jpeg_start_decompress(cinfo);
    return true;
}

bool jpegReadRows(jpeg_decompress_struct* cinfo, JpegErrorState* error, std::uint8_t* pixels,
                  std::size_t rowBytes) {
    if (setjmp(error->jump)) return false;
    while (cinfo->output_scanline < cinfo->output_height) {
        JSAMPROW row = pixels + static_cast<std::size_t>(cinfo->output_scanline) * rowBytes;
        jpeg_read_scanlines(cinfo, &row, 1);
    }
    jpeg_finish_decompress(cinfo);
    return true;
}

// Reads a JPEG as 1 (grey) or 3 (RGB) channels, rows in file order.
std::vector<std::uint8_t> readJpeg(const ImageInput& in, int& width, int& height, int& channels) {
    const std::string& path = in.path;
    JpegReader r;
    if (!in.inMemory) {
        r.file = std::fopen(path.c_str(), "rb");
        if (!r.file) fail(path, std::string("cannot open: ") + std::strerror(errno));
    }
    r.cinfo.err = jpeg_std_error(&r.error.manager);
    r.error.manager.error_exit = jpegErrorExit;
    r.error.manager.emit_message = jpegEmitMessage;
    r.created = true;  // jpeg_destroy_decompress is safe even if creation fails part-way
    auto corrupt = [&] {
        if (r.error.truncated) fail(path, "truncated JPEG (premature end of data)");
        fail(path, std::string("corrupt JPEG (") + r.error.message + ")");
    };
    if (!jpegReadHeader(&r.cinfo, &r.error, r.file, in.bytes)) corrupt();
    // The size the header claims, against the budget and the file's length, before libjpeg
    // allocates for it.
    checkSize(path, r.cinfo.image_width, r.cinfo.image_height, in.maxSamples);
    const std::uint64_t claimed = std::uint64_t{r.cinfo.image_width} * r.cinfo.image_height;
    if (claimed > kJpegMaxPixelsPerByte * in.size) {
        fail(path, "JPEG header claims " + std::to_string(r.cinfo.image_width) + " x " +
                       std::to_string(r.cinfo.image_height) + " pixels but the file has only " +
                       formatBytes(static_cast<double>(in.size)) +
                       ", fewer than a JPEG needs for so many (at least a bit per 32 x 32 "
                       "pixels): the file is truncated or corrupt");
    }
    if (!jpegStart(&r.cinfo, &r.error)) corrupt();
    checkSize(path, r.cinfo.output_width, r.cinfo.output_height, in.maxSamples);
    channels = r.cinfo.output_components;
    if (channels != 1 && channels != 3) {
        fail(path, "unsupported JPEG with " + std::to_string(channels) + " channels");
    }
    width = static_cast<int>(r.cinfo.output_width);
    height = static_cast<int>(r.cinfo.output_height);
    const std::size_t rowBytes = static_cast<std::size_t>(width) * channels;
    std::vector<std::uint8_t> pixels(rowBytes * height);
    if (!jpegReadRows(&r.cinfo, &r.error, pixels.data(), rowBytes)) corrupt();
    return pixels;
}

HeightRaster readJpegHeights(const ImageInput& in) {
    const std::string& path = in.path;
    HeightRaster out;
    int channels = 0;
    std::vector<std::uint8_t> pixels = readJpeg(in, out.width, out.height, channels);
    if (channels != 1) {
        fail(path, "height map must be greyscale; this JPEG is colour (" +
                       std::to_string(channels) + " channels)");
    }
    out.integer = true;
    out.raw.assign(pixels.begin(), pixels.end());
    return out;
}

ColorRaster readJpegColors(const ImageInput& in) {
    ColorRaster out;
    int channels = 0;
    std::vector<std::uint8_t> pixels = readJpeg(in, out.width, out.height, channels);
    out.pixels.resize(static_cast<std::size_t>(out.width) * out.height);
    if (channels == 3) {
        std::memcpy(out.pixels.data(), pixels.data(), pixels.size());
    } else {
        for (std::size_t k = 0; k < out.pixels.size(); ++k) {
            out.pixels[k] = Rgb8{pixels[k], pixels[k], pixels[k]};
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// GDAL (GeoTIFF and every other raster format GDAL reads).

void gdalInit() {
    static std::once_flag once;
    std::call_once(once, [] { GDALAllRegister(); });
}

// Keeps GDAL from printing to stderr while we work; the last message goes into our own errors.
class QuietGdal {
  public:
    QuietGdal() {
        CPLPushErrorHandler(CPLQuietErrorHandler);
        CPLErrorReset();
    }
    ~QuietGdal() { CPLPopErrorHandler(); }
    QuietGdal(const QuietGdal&) = delete;
    QuietGdal& operator=(const QuietGdal&) = delete;
    static std::string lastError() {
        const char* m = CPLGetLastErrorMsg();
        return m && *m ? std::string(" (") + m + ")" : std::string();
    }
};

// A dataset, and the in-memory file (/vsimem/) it was opened from when the bytes were in memory.
struct GdalDataset {
    GDALDatasetH handle = nullptr;
    std::string memoryFile;
    GdalDataset() = default;
    GdalDataset(const GdalDataset&) = delete;
    GdalDataset& operator=(const GdalDataset&) = delete;
    ~GdalDataset() {
        if (handle) GDALClose(handle);
        if (!memoryFile.empty()) VSIUnlink(memoryFile.c_str());
    }
};

void gdalOpen(const ImageInput& in, GdalDataset& ds) {
    const std::string& path = in.path;
    gdalInit();
    std::string name = path;
    if (in.inMemory) {
        // A name of its own (loads may run at once), ending as the input's so that drivers
        // which go by the extension recognise it.
        static std::atomic<unsigned long> serial{0};
        ds.memoryFile = "/vsimem/vig_terrain_" + std::to_string(serial++) + "/" +
                        std::filesystem::path(path).filename().string();
        // GDAL opens it read-only and never writes through the pointer.
        VSILFILE* f = VSIFileFromMemBuffer(
            ds.memoryFile.c_str(), const_cast<GByte*>(in.bytes.data()), in.bytes.size(), FALSE);
        if (!f) fail(path, "cannot hand the data to GDAL" + QuietGdal::lastError());
        VSIFCloseL(f);
        name = ds.memoryFile;
    }
    ds.handle =
        GDALOpenEx(name.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr);
    if (!ds.handle) fail(path, "not a readable image or raster file" + QuietGdal::lastError());
    const int bands = GDALGetRasterCount(ds.handle);
    if (bands < 1) fail(path, "raster file has no bands");
    const int w = GDALGetRasterXSize(ds.handle), h = GDALGetRasterYSize(ds.handle);
    checkSize(path, w, h, in.maxSamples);
    // Reading one band reads whole blocks, of every band when they are interleaved: a header
    // claiming thousands of bands, or blocks far larger than the image, costs as much as a
    // raster of that many samples. Up to four bands of the largest image are accepted.
    int blockW = 0, blockH = 0;
    GDALGetBlockSize(GDALGetRasterBand(ds.handle, 1), &blockW, &blockH);
    const std::uint64_t budget = std::uint64_t{4} * in.maxSamples;
    if (std::uint64_t(w) * std::uint64_t(h) * std::uint64_t(bands) > budget ||
        std::uint64_t(std::max(blockW, 1)) * std::uint64_t(std::max(blockH, 1)) *
                std::uint64_t(bands) >
            budget) {
        fail(path, "raster of " + std::to_string(w) + " x " + std::to_string(h) + " samples in " +
                       std::to_string(bands) + " bands, stored in blocks of " +
                       std::to_string(blockW) + " x " + std::to_string(blockH) +
                       ": more samples than the " + std::to_string(budget) +
                       " accepted (four bands of the largest image)");
    }
}

Georef readGeoref(const std::string& path, GDALDatasetH ds) {
    Georef geo;
    double gt[6];
    if (GDALGetGeoTransform(ds, gt) != CE_None) return geo;
    const bool identity =
        gt[0] == 0 && gt[1] == 1 && gt[2] == 0 && gt[3] == 0 && gt[4] == 0 && gt[5] == 1;
    if (identity) return geo;
    for (double v : gt) {
        if (!std::isfinite(v)) fail(path, "geotransform has a non-finite term");
    }
    if (gt[1] * gt[5] - gt[2] * gt[4] == 0) fail(path, "geotransform is degenerate");
    geo.valid = true;
    std::copy(gt, gt + 6, geo.gt);
    geo.rotated = gt[2] != 0 || gt[4] != 0;
    OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
    if (srs) {
        geo.srs = std::shared_ptr<void>(OSRClone(srs), [](void* p) {
            if (p) OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(p));
        });
        if (OSRIsGeographic(srs)) {
            geo.geographic = true;
            geo.degreesPerUnit = OSRGetAngularUnits(srs, nullptr) * 180.0 / std::numbers::pi;
        } else {
            geo.metresPerUnit = OSRGetLinearUnits(srs, nullptr);
        }
        if (!(geo.degreesPerUnit > 0) || !(geo.metresPerUnit > 0)) {
            fail(path, "coordinate reference system has unusable units");
        }
    }
    return geo;
}

// Metres per unit of a band's vertical unit name (GDALGetRasterUnitType); 0 when unknown.
double verticalUnitMetres(std::string name) {
    std::transform(name.begin(), name.end(), name.begin(),
                   [](unsigned char c) { return c == '_' || c == '-' ? ' ' : std::tolower(c); });
    while (!name.empty() && name.back() == ' ')
        name.pop_back();
    while (!name.empty() && name.front() == ' ')
        name.erase(name.begin());
    for (const char* m : {"", "m", "metre", "meter", "metres", "meters"})
        if (name == m) return 1.0;
    for (const char* f : {"ft", "foot", "feet", "international foot", "foot international"})
        if (name == f) return 0.3048;
    for (const char* f : {"us survey foot", "us ft", "ftus", "foot us", "us foot", "survey foot"})
        if (name == f) return 1200.0 / 3937.0;
    if (name == "cm" || name == "centimetre" || name == "centimeter") return 0.01;
    if (name == "dm" || name == "decimetre" || name == "decimeter") return 0.1;
    if (name == "mm" || name == "millimetre" || name == "millimeter") return 0.001;
    if (name == "km" || name == "kilometre" || name == "kilometer") return 1000.0;
    return 0.0;
}

HeightRaster readGdalHeights(const ImageInput& in, double scale, double offset, bool userScale,
                             const std::optional<double>& voidHeight) {
    const std::string& path = in.path;
    QuietGdal quiet;
    GdalDataset ds;
    gdalOpen(in, ds);
    HeightRaster out;
    out.width = GDALGetRasterXSize(ds.handle);
    out.height = GDALGetRasterYSize(ds.handle);
    GDALRasterBandH band = GDALGetRasterBand(ds.handle, 1);
    const GDALColorInterp interp = GDALGetRasterColorInterpretation(band);
    if (interp == GCI_PaletteIndex ||
        (GDALGetRasterCount(ds.handle) >= 3 && interp == GCI_RedBand)) {
        fail(path, "height map must hold heights in one band; this file is a colour image");
    }
    const std::size_t w = out.width, h = out.height;
    out.values.resize(w * h);
    if (GDALRasterIO(band, GF_Read, 0, 0, out.width, out.height, out.values.data(), out.width,
                     out.height, GDT_Float64, 0, 0) != CE_None) {
        fail(path, "cannot read heights" + QuietGdal::lastError());
    }
    // What the values are: the band's own scale and offset (GDAL's raw * scale + offset), in its
    // vertical unit unless the user says how many metres a unit is.
    const double bandScale = GDALGetRasterScale(band, nullptr);    // 1 when the band has none
    const double bandOffset = GDALGetRasterOffset(band, nullptr);  // 0 likewise
    if (!std::isfinite(bandScale) || bandScale == 0.0 || !std::isfinite(bandOffset)) {
        fail(path, "band scale " + formatNumber(bandScale) + " / offset " +
                       formatNumber(bandOffset) + " cannot give heights");
    }
    double unit = 1.0;
    if (!userScale) {
        const char* unitName = GDALGetRasterUnitType(band);
        unit = verticalUnitMetres(unitName ? unitName : "");
        if (unit == 0.0) {
            fail(path, std::string("vertical unit '") + unitName +
                           "' is not one this reader knows (m, ft, US survey foot, cm, km...); "
                           "give --height-scale, metres per unit");
        }
    }
    const double toMetres = bandScale * unit, toMetresOffset = bandOffset * unit;
    // Samples without data: the band's mask (its no-data value, an alpha band or a mask file,
    // as GDAL reads them) and NaN, which float rasters often use without declaring it.
    std::vector<std::uint8_t> valid;
    const int maskFlags = GDALGetMaskFlags(band);
    if (!(maskFlags & GMF_ALL_VALID)) {
        valid.resize(w * h);
        if (GDALRasterIO(GDALGetMaskBand(band), GF_Read, 0, 0, out.width, out.height, valid.data(),
                         out.width, out.height, GDT_Byte, 0, 0) != CE_None) {
            fail(path, "cannot read the no-data mask" + QuietGdal::lastError());
        }
    }
    std::size_t voids = 0;
    for (std::size_t r = 0; r < h; ++r) {
        for (std::size_t c = 0; c < w; ++c) {
            const std::size_t k = r * w + c;
            double& v = out.values[k];
            auto where = [&] {
                return " at row " + std::to_string(r) + ", column " + std::to_string(c);
            };
            if (std::isnan(v) || (!valid.empty() && valid[k] == 0)) {
                if (valid.empty()) valid.assign(w * h, 1);
                valid[k] = 0;
                ++voids;
                continue;
            }
            if (!std::isfinite(v)) {
                fail(path, "non-finite height (" + formatNumber(v) + ")" + where());
            }
            v = (v * toMetres + toMetresOffset) * scale + offset;
            if (!std::isfinite(v)) fail(path, "height out of range after scaling" + where());
        }
    }
    if (voids == w * h) fail(path, "every sample is marked as having no data");
    if (voids > 0) {
        if (voidHeight) {
            for (std::size_t k = 0; k < w * h; ++k)
                if (!valid[k]) out.values[k] = *voidHeight;
            out.filled = voids;
        } else {
            out.filled = fillVoids(out.values, valid, out.width, out.height);
        }
    }
    out.geo = readGeoref(path, ds.handle);
    return out;
}

// Colour samples wider than 8 bits (16-bit or float satellite and aerial imagery): one linear
// stretch for all bands (so the colour balance is kept) from the 2nd to the 98th percentile of
// the valid samples to 0..255, clipping beyond, as image viewers show such files by default.
std::vector<Rgb8> readWideColors(const std::string& path, GDALDatasetH ds, int width, int height,
                                 int bands) {
    const std::size_t n = static_cast<std::size_t>(width) * height;
    std::vector<double> v(n * bands);
    std::vector<std::uint8_t> valid(n, 1);
    for (int b = 0; b < bands; ++b) {
        GDALRasterBandH band = GDALGetRasterBand(ds, b + 1);
        if (GDALRasterIO(band, GF_Read, 0, 0, width, height, v.data() + n * b, width, height,
                         GDT_Float64, 0, 0) != CE_None) {
            fail(path, "cannot read colours" + QuietGdal::lastError());
        }
        if (!(GDALGetMaskFlags(band) & GMF_ALL_VALID)) {
            std::vector<std::uint8_t> mask(n);
            if (GDALRasterIO(GDALGetMaskBand(band), GF_Read, 0, 0, width, height, mask.data(),
                             width, height, GDT_Byte, 0, 0) != CE_None) {
                fail(path, "cannot read the no-data mask" + QuietGdal::lastError());
            }
            for (std::size_t k = 0; k < n; ++k)
                valid[k] = valid[k] && mask[k];
        }
    }
    // Percentiles from at most about a million valid samples spread over the image.
    const std::size_t every = std::max<std::size_t>(1, n * bands / (1u << 20));
    std::vector<double> sample;
    for (std::size_t k = 0; k < n * bands; k += every) {
        if (valid[k % n] && std::isfinite(v[k])) sample.push_back(v[k]);
    }
    if (sample.empty()) fail(path, "colour image has no valid sample");
    auto percentile = [&](double p) {
        const auto at = sample.begin() + static_cast<std::ptrdiff_t>(p * (sample.size() - 1));
        std::nth_element(sample.begin(), at, sample.end());
        return *at;
    };
    const double lo = percentile(0.02), hi = percentile(0.98);
    const double gain = hi > lo ? 255.0 / (hi - lo) : 0.0;
    auto q = [&](double x) {
        if (!std::isfinite(x)) return std::uint8_t{0};
        return static_cast<std::uint8_t>(std::clamp((x - lo) * gain + 0.5, 0.0, 255.0));
    };
    std::vector<Rgb8> px(n);
    for (std::size_t k = 0; k < n; ++k) {
        const std::uint8_t r = q(v[k]);
        px[k] = bands == 3 ? Rgb8{r, q(v[n + k]), q(v[2 * n + k])} : Rgb8{r, r, r};
    }
    return px;
}

ColorRaster readGdalColors(const ImageInput& in) {
    const std::string& path = in.path;
    QuietGdal quiet;
    GdalDataset ds;
    gdalOpen(in, ds);
    ColorRaster out;
    out.width = GDALGetRasterXSize(ds.handle);
    out.height = GDALGetRasterYSize(ds.handle);
    const std::size_t n = static_cast<std::size_t>(out.width) * out.height;
    out.pixels.resize(n);
    const int bands = GDALGetRasterCount(ds.handle);
    GDALRasterBandH band1 = GDALGetRasterBand(ds.handle, 1);
    const GDALDataType type = GDALGetRasterDataType(band1);
    if (type != GDT_Byte) {
        out.pixels = readWideColors(path, ds.handle, out.width, out.height, bands >= 3 ? 3 : 1);
        out.geo = readGeoref(path, ds.handle);
        return out;
    }
    GDALColorTableH palette = GDALGetRasterColorTable(band1);
    if (bands >= 3) {
        int bandMap[3] = {1, 2, 3};
        if (GDALDatasetRasterIO(ds.handle, GF_Read, 0, 0, out.width, out.height, out.pixels.data(),
                                out.width, out.height, GDT_Byte, 3, bandMap, 3,
                                static_cast<GSpacing>(out.width) * 3, 1) != CE_None) {
            fail(path, "cannot read colours" + QuietGdal::lastError());
        }
    } else {
        std::vector<std::uint8_t> grey(n);
        if (GDALRasterIO(band1, GF_Read, 0, 0, out.width, out.height, grey.data(), out.width,
                         out.height, GDT_Byte, 0, 0) != CE_None) {
            fail(path, "cannot read colours" + QuietGdal::lastError());
        }
        Rgb8 lut[256];
        for (int v = 0; v < 256; ++v) {
            const auto g = static_cast<std::uint8_t>(v);
            lut[v] = Rgb8{g, g, g};
            if (palette && v < GDALGetColorEntryCount(palette)) {
                const GDALColorEntry* e = GDALGetColorEntry(palette, v);
                auto q = [](short s) {
                    return static_cast<std::uint8_t>(std::clamp<int>(s, 0, 255));
                };
                lut[v] = Rgb8{q(e->c1), q(e->c2), q(e->c3)};
            }
        }
        for (std::size_t k = 0; k < n; ++k)
            out.pixels[k] = lut[grey[k]];
    }
    out.geo = readGeoref(path, ds.handle);
    return out;
}

// ---------------------------------------------------------------------------------------------
// Loading, georeference and colour resampling.

// PNG and JPEG go to libpng and libjpeg, unless a georeference beside the file makes GDAL read
// them (only for files on disk: a world file sits beside a file).
bool ownDecoder(const ImageInput& in) {
    return in.kind != FileKind::Gdal && (in.inMemory || !hasGeoSidecar(in.path));
}

HeightRaster readHeights(const ImageInput& in, double scale, double offset, bool userScale,
                         const std::optional<double>& voidHeight) {
    if (ownDecoder(in)) return in.kind == FileKind::Png ? readPngHeights(in) : readJpegHeights(in);
    return readGdalHeights(in, scale, offset, userScale, voidHeight);
}

ColorRaster readColors(const ImageInput& in) {
    if (ownDecoder(in)) return in.kind == FileKind::Png ? readPngColors(in) : readJpegColors(in);
    return readGdalColors(in);
}

void checkPositive(const std::string& path, const char* what, double v) {
    if (!std::isfinite(v) || v <= 0) {
        fail(path,
             std::string(what) + " must be a positive finite number (got " + formatNumber(v) + ")");
    }
}

// Spacing in metres along x and y from a north-up geotransform (normalised: gt[1] > 0, gt[5] < 0).
void georefSpacing(const std::string& path, const Georef& geo, int height, double& sx, double& sy) {
    if (geo.geographic) {
        const double latDeg = (geo.gt[3] + geo.gt[5] * height * 0.5) * geo.degreesPerUnit;
        if (!(std::abs(latDeg) <= 90.0)) {
            fail(path, "georeferenced latitude out of range (" + formatNumber(latDeg) + " deg)");
        }
        const double lat = latDeg * std::numbers::pi / 180.0;
        sx = std::abs(geo.gt[1]) * geo.degreesPerUnit * metresPerDegreeLongitude(lat);
        sy = std::abs(geo.gt[5]) * geo.degreesPerUnit * metresPerDegreeLatitude(lat);
    } else {
        sx = std::abs(geo.gt[1]) * geo.metresPerUnit;
        sy = std::abs(geo.gt[5]) * geo.metresPerUnit;
    }
    if (!std::isfinite(sx) || !std::isfinite(sy) || sx <= 0 || sy <= 0) {
        fail(path, "georeference gives an unusable sample spacing (" + formatNumber(sx) + " x " +
                       formatNumber(sy) + " m); give the spacing explicitly");
    }
}

// Whether two north-up georeferenced grids cover the same extent to within one pixel.
bool extentsMatch(const Georef& a, int aw, int ah, const Georef& b, int bw, int bh) {
    const double tolX = std::max(a.gt[1], b.gt[1]);
    const double tolY = std::max(-a.gt[5], -b.gt[5]);
    return std::abs(a.gt[0] - b.gt[0]) <= tolX &&
           std::abs((a.gt[0] + a.gt[1] * aw) - (b.gt[0] + b.gt[1] * bw)) <= tolX &&
           std::abs(a.gt[3] - b.gt[3]) <= tolY &&
           std::abs((a.gt[3] + a.gt[5] * ah) - (b.gt[3] + b.gt[5] * bh)) <= tolY;
}

// Whether the extent of grid `outer` holds that of grid `inner` (both north-up), to within one
// pixel of `outer`.
bool extentCovers(const Georef& outer, int ow, int oh, const Georef& inner, int iw, int ih) {
    const double tolX = outer.gt[1], tolY = -outer.gt[5];
    return outer.gt[0] <= inner.gt[0] + tolX &&
           outer.gt[0] + outer.gt[1] * ow >= inner.gt[0] + inner.gt[1] * iw - tolX &&
           outer.gt[3] >= inner.gt[3] - tolY &&
           outer.gt[3] + outer.gt[5] * oh <= inner.gt[3] + inner.gt[5] * ih + tolY;
}

// A geotransform without a coordinate system: take the colour image's when it describes the same
// grid; otherwise treat coordinates as degrees when they can only be angles (pixels under 0.01
// units, the whole extent within longitude -180..180 and latitude -90..90), else as metres.
void resolveUnits(Georef& geo, int w, int h, const Georef* other, int ow, int oh) {
    if (!geo.valid || geo.rotated || geo.srs) return;
    if (other && other->valid && !other->rotated && other->srs &&
        extentsMatch(geo, w, h, *other, ow, oh)) {
        geo.srs = other->srs;
        geo.geographic = other->geographic;
        geo.degreesPerUnit = other->degreesPerUnit;
        geo.metresPerUnit = other->metresPerUnit;
        return;
    }
    const double x0 = geo.gt[0], x1 = geo.gt[0] + geo.gt[1] * w;
    const double y0 = geo.gt[3] + geo.gt[5] * h, y1 = geo.gt[3];
    geo.geographic =
        geo.gt[1] <= 0.01 && -geo.gt[5] <= 0.01 && x0 >= -180 && x1 <= 180 && y0 >= -90 && y1 <= 90;
}

// Colour pixel coordinate (pixel centres at integers) of height sample column/row `i`, u = a*i+b.
struct AxisMap {
    double a = 1, b = 0;
};

// The colour pixel coordinate of each height sample, per axis (u = a * i + b), where the files
// share a coordinate system or none is known; false when their systems differ (the mapping is
// then not separable: resampleReprojected).
bool colorMapping(const TerrainSource& src, const HeightRaster& hr, const ColorRaster& cr,
                  AxisMap& mx, AxisMap& my) {
    const Georef& hg = hr.geo;
    const Georef& cg = cr.geo;
    const std::string both = src.heightPath + " and " + src.colorPath;
    if (hg.valid && cg.valid && !hg.rotated && !cg.rotated) {
        if (hg.srs && cg.srs &&
            !OSRIsSame(static_cast<OGRSpatialReferenceH>(hg.srs.get()),
                       static_cast<OGRSpatialReferenceH>(cg.srs.get()))) {
            return false;
        }
        // The colour image may reach beyond the heights (an orthophoto of a wider area): the
        // part over the map is used.
        if (!extentsMatch(hg, hr.width, hr.height, cg, cr.width, cr.height) &&
            !extentCovers(cg, cr.width, cr.height, hg, hr.width, hr.height)) {
            const double hx0 = hg.gt[0], hx1 = hg.gt[0] + hg.gt[1] * hr.width;
            const double hy0 = hg.gt[3], hy1 = hg.gt[3] + hg.gt[5] * hr.height;
            const double cx0 = cg.gt[0], cx1 = cg.gt[0] + cg.gt[1] * cr.width;
            const double cy0 = cg.gt[3], cy1 = cg.gt[3] + cg.gt[5] * cr.height;
            std::ostringstream s;
            s.precision(10);
            s << both << ": the colour image does not cover the height map (heights x " << hx0
              << ".." << hx1 << ", y " << hy1 << ".." << hy0 << "; colours x " << cx0 << ".." << cx1
              << ", y " << cy1 << ".." << cy0 << ")";
            throw InputError(s.str());
        }
        // Pixel centres in both files: X = g0 + (i + 0.5) g1.
        mx.a = hg.gt[1] / cg.gt[1];
        mx.b = (hg.gt[0] - cg.gt[0]) / cg.gt[1] + 0.5 * mx.a - 0.5;
        my.a = hg.gt[5] / cg.gt[5];
        my.b = (hg.gt[3] - cg.gt[3]) / cg.gt[5] + 0.5 * my.a - 0.5;
        return true;
    }
    if (hr.width == cr.width && hr.height == cr.height) return true;  // one colour per sample
    const double heightAspect = static_cast<double>(hr.width - 1) / (hr.height - 1);
    const double colorAspect = static_cast<double>(cr.width) / cr.height;
    if (std::abs(colorAspect / heightAspect - 1.0) > 0.02) {
        throw InputError(both + ": aspect ratios differ by more than 2% (heights " +
                         std::to_string(hr.width) + " x " + std::to_string(hr.height) +
                         ", colours " + std::to_string(cr.width) + " x " +
                         std::to_string(cr.height) + ")");
    }
    // Sample i of n heights at fraction i/(n-1) of the extent; texel k of m at (k+0.5)/m.
    mx.a = static_cast<double>(cr.width) / (hr.width - 1);
    mx.b = -0.5;
    my.a = static_cast<double>(cr.height) / (hr.height - 1);
    my.b = -0.5;
    return true;
}

// Index and weight of the two texels around coordinate u on an axis of n texels.
struct Tap {
    int i0 = 0, i1 = 0;
    float w1 = 0;
};

std::vector<Tap> makeTaps(int samples, int texels, AxisMap m) {
    std::vector<Tap> taps(samples);
    for (int i = 0; i < samples; ++i) {
        const double u = std::clamp(m.a * i + m.b, 0.0, static_cast<double>(texels - 1));
        const int i0 = std::min(static_cast<int>(u), std::max(texels - 2, 0));
        taps[i] = Tap{i0, std::min(i0 + 1, texels - 1), static_cast<float>(u - i0)};
    }
    return taps;
}

// Bilinear blend of four texels (a, b on the upper row, c, d below), weights from tx, ty.
inline Rgb8 blendTexels(Rgb8 a, Rgb8 b, Rgb8 c, Rgb8 d, float tx, float ty) {
    const float w00 = (1 - tx) * (1 - ty), w10 = tx * (1 - ty);
    const float w01 = (1 - tx) * ty, w11 = tx * ty;
    auto mix = [&](std::uint8_t p, std::uint8_t q, std::uint8_t s, std::uint8_t t) {
        return static_cast<std::uint8_t>(w00 * p + w10 * q + w01 * s + w11 * t + 0.5f);
    };
    return Rgb8{mix(a.r, b.r, c.r, d.r), mix(a.g, b.g, c.g, d.g), mix(a.b, b.b, c.b, d.b)};
}

// Fills the map's colours (rows south first) by bilinear sampling of the north-up colour raster.
void resampleColors(const ColorRaster& cr, AxisMap mx, AxisMap my, TerrainMap& map) {
    const int w = map.width(), h = map.height();
    const std::vector<Tap> cols = makeTaps(w, cr.width, mx);
    const std::vector<Tap> rows = makeTaps(h, cr.height, my);
    const Rgb8* px = cr.pixels.data();
    const std::size_t stride = static_cast<std::size_t>(cr.width);
    for (int fileRow = 0; fileRow < h; ++fileRow) {
        const Tap ty = rows[fileRow];
        const Rgb8* r0 = px + ty.i0 * stride;
        const Rgb8* r1 = px + ty.i1 * stride;
        Rgb8* out = map.colors().data() + map.index(0, h - 1 - fileRow);
        for (int ix = 0; ix < w; ++ix) {
            const Tap tx = cols[ix];
            out[ix] = blendTexels(r0[tx.i0], r0[tx.i1], r1[tx.i0], r1[tx.i1], tx.w1, ty.w1);
        }
    }
}

// Fills the map's colours from a colour raster in another coordinate system: each height sample's
// centre is carried into the colour file's system by GDAL/PROJ on a lattice of every kLattice-th
// sample (and the last), bilinear in between (projections are smooth: far below a pixel over 16
// samples), then the colour is sampled bilinearly there.
void resampleReprojected(const TerrainSource& src, const HeightRaster& hr, const ColorRaster& cr,
                         TerrainMap& map) {
    constexpr int kLattice = 16;
    const std::string both = src.heightPath + " and " + src.colorPath;
    const Georef& hg = hr.geo;
    const Georef& cg = cr.geo;
    auto traditional = [](const Georef& g) {
        OGRSpatialReferenceH s = OSRClone(static_cast<OGRSpatialReferenceH>(g.srs.get()));
        OSRSetAxisMappingStrategy(s, OAMS_TRADITIONAL_GIS_ORDER);  // x = easting / longitude
        return std::unique_ptr<void, void (*)(void*)>(
            s, [](void* p) { OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(p)); });
    };
    const auto from = traditional(hg), to = traditional(cg);
    OGRCoordinateTransformationH ct = OCTNewCoordinateTransformation(
        static_cast<OGRSpatialReferenceH>(from.get()), static_cast<OGRSpatialReferenceH>(to.get()));
    if (!ct) {
        throw InputError(both + ": no transformation between their coordinate reference systems" +
                         QuietGdal::lastError());
    }
    const std::unique_ptr<void, void (*)(void*)> ctGuard(ct, [](void* p) {
        OCTDestroyCoordinateTransformation(static_cast<OGRCoordinateTransformationH>(p));
    });
    const int w = hr.width, h = hr.height;
    auto lattice = [](int n) {
        std::vector<int> at;
        for (int i = 0; i < n - 1; i += kLattice)
            at.push_back(i);
        at.push_back(n - 1);
        return at;
    };
    const std::vector<int> lx = lattice(w), ly = lattice(h);
    // Colour pixel coordinates at the lattice nodes.
    std::vector<double> u(lx.size() * ly.size()), v(u.size()), z(u.size(), 0.0);
    std::vector<int> ok(u.size());
    for (std::size_t j = 0; j < ly.size(); ++j) {
        for (std::size_t i = 0; i < lx.size(); ++i) {
            u[j * lx.size() + i] = hg.gt[0] + (lx[i] + 0.5) * hg.gt[1];
            v[j * lx.size() + i] = hg.gt[3] + (ly[j] + 0.5) * hg.gt[5];
        }
    }
    if (!OCTTransformEx(ct, static_cast<int>(u.size()), u.data(), v.data(), z.data(), ok.data()) ||
        std::find(ok.begin(), ok.end(), 0) != ok.end()) {
        throw InputError(both +
                         ": the height map's positions cannot be carried into the colour "
                         "image's coordinate reference system");
    }
    for (std::size_t k = 0; k < u.size(); ++k) {
        u[k] = (u[k] - cg.gt[0]) / cg.gt[1] - 0.5;
        v[k] = (v[k] - cg.gt[3]) / cg.gt[5] - 0.5;
    }
    const Rgb8* px = cr.pixels.data();
    const std::size_t stride = static_cast<std::size_t>(cr.width);
    std::size_t outside = 0;
    for (int fileRow = 0; fileRow < h; ++fileRow) {
        const std::size_t j = std::min<std::size_t>(fileRow / kLattice, ly.size() - 2);
        const double ty = ly.size() > 1 ? (fileRow - ly[j]) / double(ly[j + 1] - ly[j]) : 0.0;
        Rgb8* out = map.colors().data() + map.index(0, h - 1 - fileRow);
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t i = std::min<std::size_t>(ix / kLattice, lx.size() - 2);
            const double tx = (ix - lx[i]) / double(lx[i + 1] - lx[i]);
            auto at = [&](const std::vector<double>& f) {
                const std::size_t k = j * lx.size() + i;
                const double top = f[k] + (f[k + 1] - f[k]) * tx;
                const double bottom =
                    f[k + lx.size()] + (f[k + lx.size() + 1] - f[k + lx.size()]) * tx;
                return top + (bottom - top) * ty;
            };
            const double cu = at(u), cv = at(v);
            // Within one pixel of the colour image's edge counts as covered (as for one system).
            if (!(cu >= -1.5 && cv >= -1.5 && cu <= cr.width + 0.5 && cv <= cr.height + 0.5)) {
                ++outside;
                continue;
            }
            const double uc = std::clamp(cu, 0.0, cr.width - 1.0);
            const double vc = std::clamp(cv, 0.0, cr.height - 1.0);
            const int u0 = std::min(static_cast<int>(uc), std::max(cr.width - 2, 0));
            const int v0 = std::min(static_cast<int>(vc), std::max(cr.height - 2, 0));
            const int u1 = std::min(u0 + 1, cr.width - 1), v1 = std::min(v0 + 1, cr.height - 1);
            const Rgb8* r0 = px + v0 * stride;
            const Rgb8* r1 = px + v1 * stride;
            out[ix] = blendTexels(r0[u0], r0[u1], r1[u0], r1[u1], static_cast<float>(uc - u0),
                                  static_cast<float>(vc - v0));
        }
    }
    if (outside > 0) {
        throw InputError(both + ": the colour image does not cover the height map (" +
                         std::to_string(outside) + " height samples fall outside it)");
    }
}

}  // namespace

namespace {

// One level of the void-fill pyramid: each sample the mean of the valid ones among the 2 x 2
// finer samples it covers, valid when any of them is.
struct FillLevel {
    int w = 0, h = 0;
    std::vector<double> v;
    std::vector<std::uint8_t> ok;
};

FillLevel coarsenValid(const double* v, const std::uint8_t* ok, int w, int h) {
    FillLevel c;
    c.w = (w + 1) / 2;
    c.h = (h + 1) / 2;
    c.v.assign(static_cast<std::size_t>(c.w) * c.h, 0.0);
    c.ok.assign(c.v.size(), 0);
    for (int cy = 0; cy < c.h; ++cy) {
        for (int cx = 0; cx < c.w; ++cx) {
            double sum = 0.0;
            int n = 0;
            for (int y = 2 * cy; y < std::min(2 * cy + 2, h); ++y) {
                for (int x = 2 * cx; x < std::min(2 * cx + 2, w); ++x) {
                    const std::size_t k = static_cast<std::size_t>(y) * w + x;
                    if (ok[k]) {
                        sum += v[k];
                        ++n;
                    }
                }
            }
            const std::size_t k = static_cast<std::size_t>(cy) * c.w + cx;
            c.v[k] = n > 0 ? sum / n : 0.0;
            c.ok[k] = n > 0;
        }
    }
    return c;
}

// Gives the invalid samples of a w x h level the bilinear interpolation of the (filled) coarser
// level: coarse sample k covers fine samples 2k and 2k + 1, so fine x sits at (x - 0.5) / 2.
void pullFromCoarse(double* v, const std::uint8_t* ok, int w, int h, const FillLevel& c) {
    auto axis = [](int fine, int count, int& i0, int& i1, double& t) {
        const double f = std::clamp((fine - 0.5) * 0.5, 0.0, count - 1.0);
        i0 = static_cast<int>(f);
        i1 = std::min(i0 + 1, count - 1);
        t = f - i0;
    };
    for (int y = 0; y < h; ++y) {
        int y0, y1;
        double ty;
        axis(y, c.h, y0, y1, ty);
        const double* r0 = c.v.data() + static_cast<std::size_t>(y0) * c.w;
        const double* r1 = c.v.data() + static_cast<std::size_t>(y1) * c.w;
        for (int x = 0; x < w; ++x) {
            const std::size_t k = static_cast<std::size_t>(y) * w + x;
            if (ok[k]) continue;
            int x0, x1;
            double tx;
            axis(x, c.w, x0, x1, tx);
            const double a = r0[x0] + (r0[x1] - r0[x0]) * tx;
            const double b = r1[x0] + (r1[x1] - r1[x0]) * tx;
            v[k] = a + (b - a) * ty;
        }
    }
}

}  // namespace

std::size_t fillVoids(std::vector<double>& values, const std::vector<std::uint8_t>& valid, int w,
                      int h) {
    const std::size_t n = static_cast<std::size_t>(std::max(w, 0)) * std::max(h, 0);
    CHECK(w > 0 && h > 0 && values.size() == n && valid.size() == n)
        << "fillVoids: grid sizes disagree";
    const auto voids = static_cast<std::size_t>(std::count(valid.begin(), valid.end(), 0));
    if (voids == 0) return 0;
    CHECK_LT(voids, n) << "fillVoids: no valid sample to fill from";
    // Push: coarser levels until one has no hole (at the latest the 1 x 1 one).
    std::vector<FillLevel> levels;
    const double* v = values.data();
    const std::uint8_t* ok = valid.data();
    int lw = w, lh = h;
    for (;;) {
        levels.push_back(coarsenValid(v, ok, lw, lh));
        const FillLevel& c = levels.back();
        if (std::find(c.ok.begin(), c.ok.end(), 0) == c.ok.end()) break;
        v = c.v.data();
        ok = c.ok.data();
        lw = c.w;
        lh = c.h;
    }
    // Pull: each level's holes from the one above it, coarsest first.
    for (std::size_t l = levels.size() - 1; l > 0; --l) {
        FillLevel& fine = levels[l - 1];
        pullFromCoarse(fine.v.data(), fine.ok.data(), fine.w, fine.h, levels[l]);
    }
    pullFromCoarse(values.data(), valid.data(), w, h, levels.front());
    return voids;
}

double metresPerDegreeLatitude(double latitude) {
    return 111132.954 - 559.822 * std::cos(2 * latitude) + 1.175 * std::cos(4 * latitude);
}

double metresPerDegreeLongitude(double latitude) {
    return 111412.84 * std::cos(latitude) - 93.5 * std::cos(3 * latitude);
}

TerrainMap loadTerrain(const TerrainSource& src) {
    const std::string& path = src.heightPath;
    if (path.empty()) throw InputError("height map: no file given");
    if (src.spacing) checkPositive(path, "spacing", *src.spacing);
    if (src.heightScale) checkPositive(path, "height scale", *src.heightScale);
    if (src.heightOffset && !std::isfinite(*src.heightOffset)) {
        fail(path, "height offset must be finite (got " + formatNumber(*src.heightOffset) + ")");
    }
    const double userScale = src.heightScale.value_or(1.0);
    const double userOffset = src.heightOffset.value_or(0.0);

    if (src.voidHeight && !std::isfinite(*src.voidHeight)) {
        fail(path, "void height must be finite (got " + formatNumber(*src.voidHeight) + ")");
    }
    HeightRaster hr;
    {
        ImageInput in;
        openInput(path, src.heightBytes, src.maxSamples, in);
        hr = readHeights(in, userScale, userOffset, src.heightScale.has_value(), src.voidHeight);
    }
    if (hr.width < 2 || hr.height < 2) {
        fail(path, "height map needs at least 2 x 2 samples (has " + std::to_string(hr.width) +
                       " x " + std::to_string(hr.height) + ")");
    }
    if (hr.integer) {
        normaliseOrientation(hr.raw, hr.width, hr.height, hr.geo);
    } else {
        normaliseOrientation(hr.values, hr.width, hr.height, hr.geo);
    }

    ColorRaster cr;
    const bool hasColor = !src.colorPath.empty();
    if (hasColor) {
        ImageInput in;
        openInput(src.colorPath, src.colorBytes, src.maxSamples, in);
        cr = readColors(in);
        normaliseOrientation(cr.pixels, cr.width, cr.height, cr.geo);
    }
    resolveUnits(hr.geo, hr.width, hr.height, hasColor ? &cr.geo : nullptr, cr.width, cr.height);
    if (hasColor) resolveUnits(cr.geo, cr.width, cr.height, &hr.geo, hr.width, hr.height);

    double sx = kDefaultSpacing, sy = kDefaultSpacing;
    if (src.spacing) {
        sx = sy = *src.spacing;
    } else if (hr.geo.valid) {
        if (hr.geo.rotated) {
            fail(path, "georeference is rotated or sheared; give the sample spacing explicitly");
        }
        georefSpacing(path, hr.geo, hr.height, sx, sy);
    }

    const std::size_t w = hr.width, h = hr.height;
    double scale = userScale, offset = userOffset;
    std::vector<std::uint16_t> raw;
    if (hr.integer) {
        raw = std::move(hr.raw);
    } else {
        // Quantise to 16 bits over the map's own range: exact to within scale / 2.
        const auto [lo, hi] = std::minmax_element(hr.values.begin(), hr.values.end());
        const double minV = *lo, maxV = *hi;
        offset = minV;
        scale = maxV > minV ? (maxV - minV) / 65535.0 : 1.0;
        raw.resize(w * h);
        for (std::size_t k = 0; k < w * h; ++k) {
            const double q = std::round((hr.values[k] - minV) / scale);
            raw[k] = static_cast<std::uint16_t>(std::clamp(q, 0.0, 65535.0));
        }
        hr.values = {};
    }

    TerrainMap map(hr.width, hr.height, sx, sy, scale, offset);
    for (std::size_t fileRow = 0; fileRow < h; ++fileRow) {
        std::copy_n(raw.begin() + fileRow * w, w, map.rawHeights().begin() + (h - 1 - fileRow) * w);
    }
    raw = {};
    map.updateRange();
    map.setFilledSamples(hr.filled);
    if (hr.geo.valid && hr.geo.srs) {
        // As the streaming source gives a database's header: sample (0, 0) is the south-west
        // pixel's centre.
        Georeference g;
        g.originX = hr.geo.gt[0] + 0.5 * hr.geo.gt[1];
        g.originY = hr.geo.gt[3] + (static_cast<double>(h) - 0.5) * hr.geo.gt[5];
        char* wkt = nullptr;
        if (OSRExportToWkt(static_cast<OGRSpatialReferenceH>(hr.geo.srs.get()), &wkt) ==
                OGRERR_NONE &&
            wkt) {
            g.crs = wkt;
        }
        CPLFree(wkt);
        map.setGeoreference(std::move(g));
    }

    if (!hasColor) {
        map.shadeFromHeights();
        return map;
    }
    AxisMap mx, my;
    if (colorMapping(src, hr, cr, mx, my)) {
        resampleColors(cr, mx, my, map);
    } else {
        resampleReprojected(src, hr, cr, map);
    }
    return map;
}

std::optional<std::array<double, 2>> geodeticOrigin(const Georeference& g) {
    if (!g.present()) return std::nullopt;
    OGRSpatialReferenceH from = OSRNewSpatialReference(g.crs.c_str());
    OGRSpatialReferenceH to = OSRNewSpatialReference(nullptr);
    const std::unique_ptr<void, void (*)(void*)> fromGuard(from, [](void* p) {
        if (p) OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(p));
    });
    const std::unique_ptr<void, void (*)(void*)> toGuard(to, [](void* p) {
        if (p) OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(p));
    });
    if (!from || !to || OSRSetWellKnownGeogCS(to, "WGS84") != OGRERR_NONE) return std::nullopt;
    OSRSetAxisMappingStrategy(from, OAMS_TRADITIONAL_GIS_ORDER);  // x = easting / longitude
    OSRSetAxisMappingStrategy(to, OAMS_TRADITIONAL_GIS_ORDER);
    const QuietGdal quiet;
    OGRCoordinateTransformationH ct = OCTNewCoordinateTransformation(from, to);
    if (!ct) return std::nullopt;
    double x = g.originX, y = g.originY;
    const bool ok = OCTTransform(ct, 1, &x, &y, nullptr) != 0;
    OCTDestroyCoordinateTransformation(ct);
    if (!ok || !std::isfinite(x) || !std::isfinite(y) || std::abs(y) > 90.0) return std::nullopt;
    return std::array<double, 2>{y, x};
}

TerrainMap loadPugetSound() {
    TerrainSource src;
    src.heightPath = VIG_DATA_DIR "/puget-sound-1k/ps_height_1k.png";
    src.colorPath = VIG_DATA_DIR "/puget-sound-1k/ps_texture_1k.png";
    src.spacing = 160.0;
    src.heightScale = 0.1;
    return loadTerrain(src);
}

TerrainMap loadGoleta() {
    TerrainSource src;
    src.heightPath = VIG_DATA_DIR "/goleta-512/sba_elev32_wgs84_512x512.tif";
    src.colorPath = VIG_DATA_DIR "/goleta-512/sba_rgb_wgs84_512x512.tif";
    return loadTerrain(src);
}

// ---------------------------------------------------------------------------------------------
// Streaming reader for the database builder: the same heights and colours loadTerrain gives,
// window by window, for the files that need nothing of the whole map but its height range.

namespace {

// Largest raster the streaming reader opens, samples.
constexpr std::size_t kMaxStreamSamples = std::size_t{1} << 36;

class GdalRowSource final : public TerrainRowSource {
  public:
    // Opens the files; sets `why` and leaves ok() false when they need the whole-map loader.
    GdalRowSource(const TerrainSource& src, std::string& why) : src_(src) {
        const std::string& path = src.heightPath;
        if (path.empty()) throw InputError("height map: no file given");
        if (!src.heightBytes.empty() || !src.colorBytes.empty()) {
            why = "data held in memory";
            return;
        }
        if (src.spacing) checkPositive(path, "spacing", *src.spacing);
        if (src.heightScale) checkPositive(path, "height scale", *src.heightScale);
        if (src.colorPath.empty()) {
            why = "no colour image (the heights are shaded over the whole map)";
            return;
        }
        ImageInput hin;
        openInput(path, {}, kMaxStreamSamples, hin);
        if (ownDecoder(hin)) {
            why = "PNG and JPEG heights are decoded whole";
            return;
        }
        ImageInput cin;
        openInput(src.colorPath, {}, kMaxStreamSamples, cin);
        if (ownDecoder(cin)) {
            why = "PNG and JPEG colours are decoded whole";
            return;
        }
        gdalOpen(hin, heights_);
        gdalOpen(cin, colors_);
        width_ = GDALGetRasterXSize(heights_.handle);
        height_ = GDALGetRasterYSize(heights_.handle);
        if (width_ < 2 || height_ < 2) {
            fail(path, "height map needs at least 2 x 2 samples (has " + std::to_string(width_) +
                           " x " + std::to_string(height_) + ")");
        }
        band_ = GDALGetRasterBand(heights_.handle, 1);
        const GDALColorInterp interp = GDALGetRasterColorInterpretation(band_);
        if (interp == GCI_PaletteIndex ||
            (GDALGetRasterCount(heights_.handle) >= 3 && interp == GCI_RedBand)) {
            fail(path, "height map must hold heights in one band; this file is a colour image");
        }
        const double bandScale = GDALGetRasterScale(band_, nullptr);
        const double bandOffset = GDALGetRasterOffset(band_, nullptr);
        if (!std::isfinite(bandScale) || bandScale == 0.0 || !std::isfinite(bandOffset)) {
            fail(path, "band scale " + formatNumber(bandScale) + " / offset " +
                           formatNumber(bandOffset) + " cannot give heights");
        }
        double unit = 1.0;
        if (!src.heightScale) {
            const char* unitName = GDALGetRasterUnitType(band_);
            unit = verticalUnitMetres(unitName ? unitName : "");
            if (unit == 0.0) {
                fail(path, std::string("vertical unit '") + unitName +
                               "' is not one this reader knows (m, ft, US survey foot, cm, "
                               "km...); give --height-scale, metres per unit");
            }
        }
        toMetres_ = bandScale * unit;
        toMetresOffset_ = bandOffset * unit;
        userScale_ = src.heightScale.value_or(1.0);
        userOffset_ = src.heightOffset.value_or(0.0);
        masked_ = !(GDALGetMaskFlags(band_) & GMF_ALL_VALID);

        // Colours: 8-bit, one colour per height sample.
        const int cbands = GDALGetRasterCount(colors_.handle);
        GDALRasterBandH c1 = GDALGetRasterBand(colors_.handle, 1);
        if (GDALGetRasterDataType(c1) != GDT_Byte) {
            why = "colours wider than 8 bits are stretched over the whole image";
            return;
        }
        if (GDALGetRasterXSize(colors_.handle) != width_ ||
            GDALGetRasterYSize(colors_.handle) != height_) {
            why = "the colour image is resampled to the height grid";
            return;
        }
        geo_ = readGeoref(path, heights_.handle);
        Georef cgeo = readGeoref(src.colorPath, colors_.handle);
        if (geo_.valid != cgeo.valid ||
            (geo_.valid && !std::equal(geo_.gt, geo_.gt + 6, cgeo.gt)) ||
            (geo_.srs && cgeo.srs &&
             !OSRIsSame(static_cast<OGRSpatialReferenceH>(geo_.srs.get()),
                        static_cast<OGRSpatialReferenceH>(cgeo.srs.get())))) {
            why = "the colour image lies on another grid (it is resampled)";
            return;
        }
        if (geo_.valid && (geo_.rotated || geo_.gt[1] < 0 || geo_.gt[5] > 0)) {
            why = "the raster is not north-up (it is flipped or rotated whole)";
            return;
        }
        resolveUnits(geo_, width_, height_, &cgeo, width_, height_);
        sx_ = sy_ = kDefaultSpacing;
        if (src.spacing) {
            sx_ = sy_ = *src.spacing;
        } else if (geo_.valid) {
            georefSpacing(path, geo_, height_, sx_, sy_);
        }
        if (cbands >= 3) {
            greyLut_.clear();
        } else {
            GDALColorTableH palette = GDALGetRasterColorTable(c1);
            greyLut_.resize(256);
            for (int v = 0; v < 256; ++v) {
                const auto g = static_cast<std::uint8_t>(v);
                greyLut_[v] = Rgb8{g, g, g};
                if (palette && v < GDALGetColorEntryCount(palette)) {
                    const GDALColorEntry* e = GDALGetColorEntry(palette, v);
                    auto q = [](short sv) {
                        return static_cast<std::uint8_t>(std::clamp<int>(sv, 0, 255));
                    };
                    greyLut_[v] = Rgb8{q(e->c1), q(e->c2), q(e->c3)};
                }
            }
        }
        // The height range, window by window (float heights are quantised over it).
        bool any = false;
        std::vector<double> v;
        for (int r0 = 0; r0 < height_; r0 += kRows) {
            const int rows = std::min(kRows, height_ - r0);
            if (!readValues(r0, rows, v)) {
                if (!src.voidHeight) {
                    why =
                        "samples without data are interpolated over the whole map (give "
                        "--void-height to stream it)";
                    return;
                }
            }
            for (double x : v) {
                if (!any) {
                    minV_ = maxV_ = x;
                    any = true;
                }
                minV_ = std::min(minV_, x);
                maxV_ = std::max(maxV_, x);
            }
            voids_ += lastVoids_;
        }
        if (voids_ == static_cast<std::uint64_t>(width_) * height_) {
            fail(path, "every sample is marked as having no data");
        }
        scale_ = maxV_ > minV_ ? (maxV_ - minV_) / 65535.0 : 1.0;
        ok_ = true;
    }

    bool ok() const { return ok_; }

    TerrainDbInfo info() const override {
        TerrainDbInfo i;
        i.width = width_;
        i.height = height_;
        i.spacingX = sx_;
        i.spacingY = sy_;
        i.heightScale = scale_;
        i.heightOffset = minV_;
        i.originX = i.originY = std::numeric_limits<double>::quiet_NaN();
        if (geo_.valid) {
            i.originX = geo_.gt[0] + 0.5 * geo_.gt[1];
            i.originY = geo_.gt[3] + (height_ - 0.5) * geo_.gt[5];
        }
        if (geo_.srs) {
            char* wkt = nullptr;
            if (OSRExportToWkt(static_cast<OGRSpatialReferenceH>(geo_.srs.get()), &wkt) ==
                    OGRERR_NONE &&
                wkt) {
                i.crs = wkt;
            }
            CPLFree(wkt);
        }
        return i;
    }

    void readRows(int y0, int rows, std::uint16_t* heights, Rgb8* colors) override {
        // Map rows [y0, y0 + rows) are file rows [height - y0 - rows, height - y0), reversed.
        const int f0 = height_ - y0 - rows;
        std::vector<double> v;
        readValues(f0, rows, v);
        const std::size_t w = static_cast<std::size_t>(width_);
        for (int r = 0; r < rows; ++r) {
            const double* src = v.data() + static_cast<std::size_t>(rows - 1 - r) * w;
            std::uint16_t* out = heights + static_cast<std::size_t>(r) * w;
            for (std::size_t c = 0; c < w; ++c) {
                const double q = std::round((src[c] - minV_) / scale_);
                out[c] = static_cast<std::uint16_t>(std::clamp(q, 0.0, 65535.0));
            }
        }
        const std::size_t n = w * static_cast<std::size_t>(rows);
        std::vector<Rgb8> px(n);
        QuietGdal quiet;
        CPLErr err;
        if (greyLut_.empty()) {
            int bandMap[3] = {1, 2, 3};
            err = GDALDatasetRasterIO(colors_.handle, GF_Read, 0, f0, width_, rows, px.data(),
                                      width_, rows, GDT_Byte, 3, bandMap, 3,
                                      static_cast<GSpacing>(width_) * 3, 1);
        } else {
            std::vector<std::uint8_t> grey(n);
            err = GDALRasterIO(GDALGetRasterBand(colors_.handle, 1), GF_Read, 0, f0, width_, rows,
                               grey.data(), width_, rows, GDT_Byte, 0, 0);
            for (std::size_t k = 0; k < n; ++k)
                px[k] = greyLut_[grey[k]];
        }
        if (err != CE_None) fail(src_.colorPath, "cannot read colours" + QuietGdal::lastError());
        for (int r = 0; r < rows; ++r) {
            std::copy_n(px.begin() + static_cast<std::ptrdiff_t>(rows - 1 - r) * width_, width_,
                        colors + static_cast<std::size_t>(r) * w);
        }
    }

  private:
    static constexpr int kRows = 256;

    // File rows [r0, r0 + rows) in metres (voids: the void height); false when there were
    // voids and no void height to give them.
    bool readValues(int r0, int rows, std::vector<double>& v) {
        const std::string& path = src_.heightPath;
        QuietGdal quiet;
        const std::size_t w = static_cast<std::size_t>(width_), n = w * rows;
        v.resize(n);
        if (GDALRasterIO(band_, GF_Read, 0, r0, width_, rows, v.data(), width_, rows, GDT_Float64,
                         0, 0) != CE_None) {
            fail(path, "cannot read heights" + QuietGdal::lastError());
        }
        std::vector<std::uint8_t> valid;
        if (masked_) {
            valid.resize(n);
            if (GDALRasterIO(GDALGetMaskBand(band_), GF_Read, 0, r0, width_, rows, valid.data(),
                             width_, rows, GDT_Byte, 0, 0) != CE_None) {
                fail(path, "cannot read the no-data mask" + QuietGdal::lastError());
            }
        }
        lastVoids_ = 0;
        for (std::size_t k = 0; k < n; ++k) {
            double& x = v[k];
            if (std::isnan(x) || (masked_ && valid[k] == 0)) {
                ++lastVoids_;
                x = src_.voidHeight.value_or(0.0);
                continue;
            }
            auto where = [&] {
                return " at row " + std::to_string(r0 + k / w) + ", column " +
                       std::to_string(k % w);
            };
            if (!std::isfinite(x))
                fail(path, "non-finite height (" + formatNumber(x) + ")" + where());
            x = (x * toMetres_ + toMetresOffset_) * userScale_ + userOffset_;
            if (!std::isfinite(x)) fail(path, "height out of range after scaling" + where());
        }
        return lastVoids_ == 0 || src_.voidHeight.has_value();
    }

    TerrainSource src_;
    GdalDataset heights_, colors_;
    GDALRasterBandH band_ = nullptr;
    Georef geo_;
    int width_ = 0, height_ = 0;
    double sx_ = 0, sy_ = 0;
    double toMetres_ = 1, toMetresOffset_ = 0, userScale_ = 1, userOffset_ = 0;
    bool masked_ = false, ok_ = false;
    double minV_ = 0, maxV_ = 0, scale_ = 1;
    std::uint64_t voids_ = 0, lastVoids_ = 0;
    std::vector<Rgb8> greyLut_;
};

}  // namespace

std::unique_ptr<TerrainRowSource> gdalRowSource(const TerrainSource& source, std::string& why) {
    gdalInit();
    auto s = std::make_unique<GdalRowSource>(source, why);
    if (!s->ok()) return nullptr;
    return s;
}

}  // namespace ig
