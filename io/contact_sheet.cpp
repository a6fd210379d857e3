#include "io/contact_sheet.hpp"

#include <algorithm>
#include <cerrno>

#include "io/image_file.hpp"

namespace io {
namespace {

constexpr int kGap = 4;  // pixels between cells and around the grid
constexpr std::uint8_t kBackground = 32;

// Source range [begin, end) of destination cell `i` of `n` over `size` samples (never empty).
void cellRange(int i, int n, int size, int* begin, int* end) {
    *begin = std::min(static_cast<int>(static_cast<long long>(i) * size / n), size - 1);
    *end = std::max(*begin + 1, static_cast<int>(static_cast<long long>(i + 1) * size / n));
}

}  // namespace

ContactSheet::ContactSheet(int columns, int rows, int thumbWidth)
    : columns_(std::max(1, columns)),
      rows_(std::max(1, rows)),
      thumbWidth_(std::max(1, thumbWidth)) {}

ContactSheet::~ContactSheet() = default;

void ContactSheet::offer(const VideoFormat& format, const std::uint8_t* frame, std::size_t stride) {
    if (!frame || !checkVideoFormat(format).empty()) return;
    const std::uint64_t number = offered_++;
    const std::size_t capacity = static_cast<std::size_t>(columns_) * rows_;
    if (number % every_ != 0) return;
    if (thumbs_.size() == capacity) {
        // Keep every other thumbnail and halve the rate from now on.
        std::size_t kept = 0;
        for (std::size_t i = 0; i < thumbs_.size(); i += 2, ++kept) {
            if (i != kept) thumbs_[kept] = std::move(thumbs_[i]);  // never self-move
        }
        thumbs_.resize(kept);
        every_ *= 2;
        if (number % every_ != 0) return;
    }
    if (thumbHeight_ == 0) {
        thumbHeight_ = std::max(1, static_cast<int>(static_cast<long long>(thumbWidth_) *
                                                    format.height / format.width));
    }
    const int w = format.width, h = format.height, tw = thumbWidth_, th = thumbHeight_;
    Thumb thumb{number, std::vector<std::uint8_t>(static_cast<std::size_t>(tw) * th * 3)};
    rowRgb_.resize(static_cast<std::size_t>(w) * 3);
    sums_.resize(static_cast<std::size_t>(tw) * 3);
    for (int ty = 0; ty < th; ++ty) {
        int y0, y1;
        cellRange(ty, th, h, &y0, &y1);
        std::fill(sums_.begin(), sums_.end(), 0u);
        for (int y = y0; y < y1; ++y) {
            rowToRgb(format.format, frame + static_cast<std::size_t>(y) * stride, w,
                     rowRgb_.data());
            for (int tx = 0; tx < tw; ++tx) {
                int x0, x1;
                cellRange(tx, tw, w, &x0, &x1);
                for (int x = x0; x < x1; ++x) {
                    for (int c = 0; c < 3; ++c)
                        sums_[3 * tx + c] += rowRgb_[3 * x + c];
                }
            }
        }
        for (int tx = 0; tx < tw; ++tx) {
            int x0, x1;
            cellRange(tx, tw, w, &x0, &x1);
            const std::uint32_t n = static_cast<std::uint32_t>((x1 - x0) * (y1 - y0));
            for (int c = 0; c < 3; ++c) {
                thumb.rgb[(static_cast<std::size_t>(ty) * tw + tx) * 3 + c] =
                    static_cast<std::uint8_t>((sums_[3 * tx + c] + n / 2) / n);
            }
        }
    }
    thumbs_.push_back(std::move(thumb));
}

void ContactSheet::offerField(const VideoFormat& format, const FieldBuffer& field) {
    if (!checkVideoFormat(format).empty()) return;
    if (!weaver_ || weaver_->format().width != format.width ||
        weaver_->format().height != format.height || weaver_->format().format != format.format) {
        weaver_ = std::make_unique<FieldWeaver>(format);
    }
    weaver_->add(field, [&](const std::uint8_t* frame, std::size_t stride) {
        offer(format, frame, stride);
    });
}

std::vector<std::uint64_t> ContactSheet::frameNumbers() const {
    std::vector<std::uint64_t> numbers;
    for (const Thumb& t : thumbs_)
        numbers.push_back(t.number);
    return numbers;
}

int ContactSheet::write(const std::string& path, std::string* error) {
    if (thumbs_.empty()) {
        if (error) *error = path + ": contact sheet has no frames";
        return -ENODATA;
    }
    const int cols = std::min<int>(columns_, static_cast<int>(thumbs_.size()));
    const int usedRows = (static_cast<int>(thumbs_.size()) + cols - 1) / cols;
    const int width = kGap + cols * (thumbWidth_ + kGap);
    const int height = kGap + usedRows * (thumbHeight_ + kGap);
    std::vector<std::uint8_t> sheet(static_cast<std::size_t>(width) * height * 3, kBackground);
    for (std::size_t i = 0; i < thumbs_.size(); ++i) {
        const int cx = kGap + static_cast<int>(i % cols) * (thumbWidth_ + kGap);
        const int cy = kGap + static_cast<int>(i / cols) * (thumbHeight_ + kGap);
        for (int y = 0; y < thumbHeight_; ++y) {
            std::copy_n(thumbs_[i].rgb.data() + static_cast<std::size_t>(y) * thumbWidth_ * 3,
                        static_cast<std::size_t>(thumbWidth_) * 3,
                        sheet.data() + (static_cast<std::size_t>(cy + y) * width + cx) * 3);
        }
    }
    return writePng8(path, width, height, 3, sheet, error);
}

}  // namespace io
