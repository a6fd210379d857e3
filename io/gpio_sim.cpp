#include "io/gpio_sim.hpp"

#include <algorithm>
#include <cerrno>

namespace io {

SimulatedGpioChip::SimulatedGpioChip(std::string name, unsigned lineCount)
    : name_(std::move(name)), high_(lineCount, false) {}

int SimulatedGpioChip::request(const std::string& chip, const std::vector<unsigned>& offsets,
                               bool activeLow, const std::string& consumer, std::string* error) {
    if (chip != name_) {
        if (error) *error = "gpiod chip '" + chip + "': cannot open: No such file or directory";
        return -ENOENT;
    }
    if (!requested_.empty()) {
        if (error) *error = "gpiod chip '" + chip + "': lines already requested";
        return -EBUSY;
    }
    for (unsigned o : offsets) {
        if (o >= high_.size()) {
            if (error) {
                *error = "gpiod chip '" + chip + "': line offset " + std::to_string(o) +
                         " is beyond its " + std::to_string(high_.size()) + " lines";
            }
            return -EINVAL;
        }
    }
    requested_ = offsets;
    activeLow_ = activeLow;
    consumer_ = consumer;
    return 0;
}

int SimulatedGpioChip::values(std::vector<int>* out) {
    if (requested_.empty()) return -EPERM;
    out->clear();
    for (unsigned o : requested_)
        out->push_back(high_[o] != activeLow_ ? 1 : 0);
    return 0;
}

int SimulatedGpioChip::readEdges(std::int64_t, std::vector<GpioEdge>* out) {
    if (requested_.empty()) return -EPERM;
    ++waits_;
    while (!pending_.empty() && pending_.front().timeNs <= nowNs_) {
        out->push_back(pending_.front());
        pending_.pop_front();
    }
    return 0;
}

void SimulatedGpioChip::drive(unsigned offset, bool high, std::int64_t timeNs) {
    if (offset >= high_.size() || high_[offset] == high) return;
    high_[offset] = high;
    if (std::find(requested_.begin(), requested_.end(), offset) == requested_.end()) return;
    pending_.push_back({offset, high != activeLow_, timeNs});
}

}  // namespace io
