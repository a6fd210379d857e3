#include <time.h>
#include <gpiod.hpp>

#include <cerrno>
#include <chrono>
#include <system_error>

#include "io/gpio_stick.hpp"

namespace io {
namespace {

int errnoOf(const std::exception& e, int fallback) {
    if (const auto* se = dynamic_cast<const std::system_error*>(&e)) return -se->code().value();
    return -fallback;
}

class GpiodChipPort final : public GpioChipPort {
  public:
    int request(const std::string& chip, const std::vector<unsigned>& offsets, bool activeLow,
                const std::string& consumer, std::string* error) override {
        const std::string name = "gpiod chip '" + chip + "'";
        try {
            chip_.open(chip, gpiod::chip::OPEN_LOOKUP);
        } catch (const std::exception& e) {
            if (error) *error = name + ": cannot open: " + e.what();
            return errnoOf(e, ENODEV);
        }
        if (!chip_) {
            if (error) *error = name + ": no such chip";
            return -ENODEV;
        }
        const unsigned count = chip_.num_lines();
        for (unsigned o : offsets) {
            if (o >= count) {
                if (error) {
                    *error = name + ": line offset " + std::to_string(o) + " is beyond its " +
                             std::to_string(count) + " lines";
                }
                return -EINVAL;
            }
        }
        try {
            lines_ = chip_.get_lines(offsets);
            gpiod::line_request config;
            config.consumer = consumer;
            config.request_type = gpiod::line_request::EVENT_BOTH_EDGES;
            if (activeLow) config.flags = gpiod::line_request::FLAG_ACTIVE_LOW;
            lines_.request(config);
        } catch (const std::exception& e) {
            if (error) *error = name + ": cannot request lines: " + e.what();
            return errnoOf(e, EIO);
        }
        return 0;
    }

    int values(std::vector<int>* out) override {
        try {
            *out = lines_.get_values();
        } catch (const std::exception& e) {
            return errnoOf(e, EIO);
        }
        return 0;
    }

    int readEdges(std::int64_t timeoutNs, std::vector<GpioEdge>* out) override {
        try {
            gpiod::line_bulk ready = lines_.event_wait(std::chrono::nanoseconds(timeoutNs));
            for (unsigned i = 0; i < ready.size(); ++i) {
                for (const gpiod::line_event& ev : ready[i].event_read_multiple()) {
                    out->push_back({ready[i].offset(),
                                    ev.event_type == gpiod::line_event::RISING_EDGE,
                                    static_cast<std::int64_t>(ev.timestamp.count())});
                }
            }
        } catch (const std::exception& e) {
            return errnoOf(e, EIO);
        }
        return 0;
    }

    std::int64_t nowNs() override {
        timespec ts{};
        clock_gettime(CLOCK_MONOTONIC, &ts);
        return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
    }

  private:
    gpiod::chip chip_;
    gpiod::line_bulk lines_;
};

}  // namespace

std::unique_ptr<GpioChipPort> makeGpiodChipPort() {
    return std::make_unique<GpiodChipPort>();
}

}  // namespace io
