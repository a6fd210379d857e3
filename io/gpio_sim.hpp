// A simulated GPIO chip behind the GpioChipPort seam: tests set levels and inject timed edges.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "io/gpio_stick.hpp"

namespace io {

class SimulatedGpioChip final : public GpioChipPort {
  public:
    SimulatedGpioChip(std::string name, unsigned lineCount);

    int request(const std::string& chip, const std::vector<unsigned>& offsets, bool activeLow,
                const std::string& consumer, std::string* error) override;
    int values(std::vector<int>* out) override;
    int readEdges(std::int64_t timeoutNs, std::vector<GpioEdge>* out) override;
    std::int64_t nowNs() override { return nowNs_; }

    // Test side: physical level changes at `timeNs` (queued as an edge if the line is requested
    // and the level changes), and the chip's clock.
    void drive(unsigned offset, bool high, std::int64_t timeNs);
    void setNow(std::int64_t timeNs) { nowNs_ = timeNs; }
    const std::vector<unsigned>& requested() const { return requested_; }
    const std::string& consumer() const { return consumer_; }
    int waits() const { return waits_; }

  private:
    std::string name_;
    std::vector<bool> high_;
    std::vector<unsigned> requested_;
    std::deque<GpioEdge> pending_;
    std::string consumer_;
    std::int64_t nowNs_ = 0;
    bool activeLow_ = false;
    int waits_ = 0;
};

}  // namespace io
