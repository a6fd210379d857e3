#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <fstream>

#include "io/gpio_sim.hpp"
#include "io/gpio_stick.hpp"
#include "io/stick.hpp"
#include "io/text_file.hpp"
#include "io_test_util.hpp"

namespace io {
namespace {

constexpr const char* kScript = R"(# a short demo flight
0.0 axis throttle 0.5
0.5 axis pitch 0.3        # pull up
1.0 axis roll -1 ramp 2   # roll left over two seconds
1.5 button trigger down
2.0 button trigger up
4.0 axis pitch 0
)";

std::unique_ptr<StickInput> script(const char* text) {
    std::string error;
    auto stick = makeScriptedStick(text, "demo.stick", &error);
    EXPECT_TRUE(stick) << error;
    return stick;
}

TEST(ScriptedStick, EventsHoldUntilTheNextOne) {
    auto stick = script(kScript);
    ASSERT_TRUE(stick);
    EXPECT_EQ(stick->sample(0.0).throttle, 0.5);
    EXPECT_EQ(stick->sample(0.49).pitch, 0.0);
    EXPECT_EQ(stick->sample(0.5).pitch, 0.3);
    EXPECT_EQ(stick->sample(3.99).pitch, 0.3);
    EXPECT_EQ(stick->sample(4.0).pitch, 0.0);
    EXPECT_EQ(stick->sample(100.0).throttle, 0.5);
    EXPECT_FALSE(stick->sample(1.49).trigger);
    EXPECT_TRUE(stick->sample(1.5).trigger);
    EXPECT_TRUE(stick->sample(1.99).trigger);
    EXPECT_FALSE(stick->sample(2.0).trigger);
    // Sampling is a pure function of t: going back in time gives the same answers.
    EXPECT_EQ(stick->sample(0.5).pitch, 0.3);
    EXPECT_EQ(stick->sample(-1.0).throttle, 0.0);
}

TEST(ScriptedStick, RampsAreLinearAndMonotonic) {
    auto stick = script(kScript);
    ASSERT_TRUE(stick);
    double previous = 1.0;
    for (double t = 0.0; t <= 4.0; t += 0.05) {
        const double roll = stick->sample(t).roll;
        EXPECT_LE(roll, previous + 1e-12) << t;
        EXPECT_GE(roll, -1.0);
        if (t >= 1.0 && t <= 3.0) {
            EXPECT_NEAR(roll, -(t - 1.0) / 2.0, 1e-9) << t;
        }
        previous = roll;
    }
    EXPECT_EQ(stick->sample(3.0).roll, -1.0);
}

TEST(ScriptedStick, RampStartsFromWhereTheAxisIs) {
    auto stick = script("0 axis yaw 1 ramp 1\n0.5 axis yaw 0 ramp 1\n");
    ASSERT_TRUE(stick);
    EXPECT_NEAR(stick->sample(0.5).yaw, 0.5, 1e-12);
    EXPECT_NEAR(stick->sample(1.0).yaw, 0.25, 1e-12);
    EXPECT_EQ(stick->sample(1.5).yaw, 0.0);
}

TEST(ScriptedStick, BadLinesNameTheLine) {
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"x axis pitch 0.1", "time"},
        {"-1 axis pitch 0.1", "time"},
        {"1.0", "missing event kind"},
        {"1.0 wiggle pitch 0.1", "unknown event kind"},
        {"1.0 axis elevator 0.1", "unknown axis"},
        {"1.0 axis pitch", "expected"},
        {"1.0 axis pitch 1.5", "[-1, 1]"},
        {"1.0 axis pitch nan", "[-1, 1]"},
        {"1.0 axis pitch 0.2 over 3", "ramp"},
        {"1.0 axis pitch 0.2 ramp -1", "ramp"},
        {"1.0 button fire down", "unknown button"},
        {"1.0 button trigger pressed", "down or up"},
        {"0.5 axis pitch 0.1 extra", "unexpected"},
        {"0.1 axis pitch 0.1", "earlier"},
    };
    for (const auto& [line, expect] : cases) {
        // Two good lines (a comment and an event at 0.2), then the bad one on line 3.
        const std::string text = "# header\n0.2 axis roll 0.1\n" + line + "\n0.9 axis roll 0\n";
        std::string error;
        EXPECT_EQ(makeScriptedStick(text, "flight.stick", &error), nullptr) << line;
        EXPECT_EQ(error.rfind("flight.stick:3: ", 0), 0u) << line << " -> " << error;
        EXPECT_NE(error.find(expect), std::string::npos) << line << " -> " << error;
    }
}

// A 10 MB bad line (or raw binary) is quoted, escaped and cut, not echoed whole.
TEST(ScriptedStick, LongOrBinaryBadInputIsQuotedBriefly) {
    std::string binary(4096, '\0');
    for (std::size_t k = 0; k < binary.size(); ++k)
        binary[k] = static_cast<char>(k * 131 + 7);
    const std::string cases[] = {
        std::string(10 << 20, '9') + "x axis pitch 0\n",
        "0 axis pitch " + std::string(10 << 20, '1') + "\n",
        "0 " + std::string(10 << 20, 'k') + "\n",
        binary,
        "0 axis " + binary + "\n",
    };
    for (const std::string& text : cases) {
        std::string error;
        EXPECT_EQ(makeScriptedStick(text, "big.stick", &error), nullptr);
        EXPECT_LE(error.size(), 320u) << error.substr(0, 400);
        EXPECT_EQ(error.rfind("big.stick:1: ", 0), 0u) << error.substr(0, 400);
        EXPECT_TRUE(std::all_of(error.begin(), error.end(), [](unsigned char c) {
            return c >= 0x20 && c < 0x7f;
        })) << error.substr(0, 400);
    }
}

TEST(ScriptedStick, EmptyScriptIsNeutral) {
    auto stick = script("# nothing\n\n   \n");
    ASSERT_TRUE(stick);
    const StickState s = stick->sample(1.0);
    EXPECT_EQ(s.pitch, 0.0);
    EXPECT_EQ(s.roll, 0.0);
    EXPECT_EQ(s.throttle, 0.0);
    EXPECT_FALSE(s.trigger);
}

TEST(MakeStick, ReadsScriptFilesAndRejectsBadSpecs) {
    const auto dir = test::scratchDir();
    const auto path = dir / "s.stick";
    std::ofstream(path) << "0 axis pitch 0.25\r\n1 axis pitch -0.25\r\n";
    std::string error;
    auto stick = makeStick("script:" + path.string(), &error);
    ASSERT_TRUE(stick) << error;
    EXPECT_EQ(stick->sample(0.5).pitch, 0.25);
    EXPECT_EQ(stick->sample(1.5).pitch, -0.25);

    EXPECT_EQ(makeStick("script:" + (dir / "none.stick").string(), &error), nullptr);
    EXPECT_NE(error.find("none.stick"), std::string::npos) << error;
    for (const char* spec : {"", "script:", "joystick:0", "gpiod:", "gpiod:chip0:1,2"}) {
        error.clear();
        EXPECT_EQ(makeStick(spec, &error), nullptr) << spec;
        EXPECT_FALSE(error.empty()) << spec;
    }
    std::ofstream(dir / "bad.stick") << "0 axis pitch 0\n1 axis pitch 2\n";
    EXPECT_EQ(makeStick("script:" + (dir / "bad.stick").string(), &error), nullptr);
    EXPECT_NE(error.find("bad.stick:2:"), std::string::npos) << error;
    // A folder given for the script is refused (it used to read as an empty, neutral script).
    EXPECT_EQ(makeStick("script:" + dir.string(), &error), nullptr);
    EXPECT_NE(error.find("is a folder"), std::string::npos) << error;
}

TEST(ReadTextFile, ReadsAllOfItAndSaysWhyNot) {
    const auto dir = test::scratchDir();
    const auto path = dir / "t.txt";
    std::string big(200000, 'x');
    big += "\nend\n";
    std::ofstream(path, std::ios::binary) << big;
    std::string text, error;
    EXPECT_EQ(readTextFile(path.string(), text, &error), 0) << error;
    EXPECT_EQ(text, big);
    EXPECT_EQ(readTextFile((dir / "none.txt").string(), text, &error), -ENOENT);
    EXPECT_NE(error.find("cannot open"), std::string::npos) << error;
    EXPECT_EQ(readTextFile(dir.string(), text, &error), -EISDIR);
    EXPECT_EQ(error, "is a folder, not a file");
}

TEST(GpioStickSpec, ParsesOffsetsAndOptions) {
    std::string error;
    auto c = parseGpioStickSpec("gpiochip0:5,6,13,19,26,-,21:active-low", &error);
    ASSERT_TRUE(c) << error;
    EXPECT_EQ(c->chip, "gpiochip0");
    EXPECT_TRUE(c->activeLow);
    const std::array<int, kStickLineCount> want = {5, 6, 13, 19, 26, -1, 21};
    EXPECT_EQ(c->offsets, want);
    c = parseGpioStickSpec("/dev/gpiochip1:0,1,2,3,4,5,6", &error);
    ASSERT_TRUE(c) << error;
    EXPECT_EQ(c->chip, "/dev/gpiochip1");
    EXPECT_FALSE(c->activeLow);
    for (const char* bad :
         {"gpiochip0", ":1,2,3,4,5,6,7", "gpiochip0:1,2,3,4,5,6", "gpiochip0:1,2,3,4,5,6,7,8",
          "gpiochip0:1,2,3,4,5,6,x", "gpiochip0:1,2,3,4,5,6,1", "gpiochip0:-,-,-,-,-,-,-",
          "gpiochip0:1,2,3,4,5,6,7:pull-up", "gpiochip0:1,2,3,,5,6,7"}) {
        error.clear();
        EXPECT_FALSE(parseGpioStickSpec(bad, &error)) << bad;
        EXPECT_NE(error.find(bad), std::string::npos) << error;
    }
}

constexpr std::int64_t kMs = 1000000;

// A stick on simulated chip "sim0": up 1, down 2, left 3, right 4, trigger 5, throttle+ 6,
// throttle- 7.
struct SimStick {
    SimulatedGpioChip* chip;
    std::unique_ptr<GpioStick> stick;
    std::string error;

    explicit SimStick(bool activeLow = false) {
        GpioStickConfig config;
        config.chip = "sim0";
        config.offsets = {1, 2, 3, 4, 5, 6, 7};
        config.activeLow = activeLow;
        auto port = std::make_unique<SimulatedGpioChip>("sim0", 8);
        chip = port.get();
        if (activeLow) {
            for (unsigned o = 0; o < 8; ++o)
                chip->drive(o, true, 0);  // released = high
        }
        stick = std::make_unique<GpioStick>(config, std::move(port));
    }
    StickState at(std::int64_t ns) {
        chip->setNow(ns);
        return stick->sample(0.0);
    }
};

TEST(GpioStick, LinesMapToTheStick) {
    SimStick s;
    ASSERT_EQ(s.stick->open(&s.error), 0) << s.error;
    EXPECT_EQ(s.chip->requested(), (std::vector<unsigned>{1, 2, 3, 4, 5, 6, 7}));
    EXPECT_EQ(s.chip->consumer(), "vig-stick");
    struct Case {
        unsigned line;
        double pitch, roll;
        bool trigger;
    };
    std::int64_t t = 100 * kMs;
    for (const Case c : {Case{1, 1, 0, false}, Case{2, -1, 0, false}, Case{3, 0, -1, false},
                         Case{4, 0, 1, false}, Case{5, 0, 0, true}}) {
        s.chip->drive(c.line, true, t);
        const StickState on = s.at(t + 50 * kMs);
        EXPECT_EQ(on.pitch, c.pitch) << c.line;
        EXPECT_EQ(on.roll, c.roll) << c.line;
        EXPECT_EQ(on.trigger, c.trigger) << c.line;
        s.chip->drive(c.line, false, t + 100 * kMs);
        const StickState off = s.at(t + 200 * kMs);
        EXPECT_EQ(off.pitch, 0.0);
        EXPECT_EQ(off.roll, 0.0);
        EXPECT_FALSE(off.trigger);
        t += 300 * kMs;
    }
    // Opposite directions together cancel.
    s.chip->drive(1, true, t);
    s.chip->drive(2, true, t);
    EXPECT_EQ(s.at(t + 50 * kMs).pitch, 0.0);
}

TEST(GpioStick, BouncesShorterThanTheDebounceTimeAreIgnored) {
    SimStick s;
    ASSERT_EQ(s.stick->open(&s.error), 0) << s.error;
    // A contact that chatters for 3 ms, then settles closed.
    std::int64_t t = 1000 * kMs;
    for (int i = 0; i < 6; ++i)
        s.chip->drive(5, i % 2 == 0, t + i * kMs / 2);
    s.chip->drive(5, true, t + 3 * kMs);
    EXPECT_FALSE(s.at(t + 3 * kMs + 9 * kMs).trigger);  // settled 9 ms: not yet
    EXPECT_TRUE(s.at(t + 3 * kMs + 10 * kMs).trigger);  // 10 ms: pressed
    // A glitch open shorter than the debounce time does not release it.
    t += 100 * kMs;
    s.chip->drive(5, false, t);
    s.chip->drive(5, true, t + 4 * kMs);
    EXPECT_TRUE(s.at(t + 50 * kMs).trigger);
    EXPECT_GE(s.stick->edgesSeen(), 9u);
    // Sweep: while a single pulse of width w is still held, it reads pressed only once it has
    // lasted longer than the debounce time.
    for (int w : {1, 5, 9, 10, 11, 30}) {
        SimStick p;
        ASSERT_EQ(p.stick->open(&p.error), 0) << p.error;
        p.chip->drive(4, true, 10 * kMs);
        p.chip->drive(4, false, (10 + w) * kMs);
        const StickState during = p.at((10 + w) * kMs - 1);
        EXPECT_EQ(during.roll, w > 10 ? 1.0 : 0.0) << w;
        EXPECT_EQ(p.at(200 * kMs).roll, 0.0) << w;
    }
}

TEST(GpioStick, ThrottleIntegratesTheHeldTime) {
    SimStick s;
    ASSERT_EQ(s.stick->open(&s.error), 0) << s.error;
    // Hold throttle+ from 0.1 s to 0.9 s (debounced: 0.11 .. 0.91): +0.8 s * 0.5/s = +0.4.
    s.chip->drive(6, true, 100 * kMs);
    EXPECT_NEAR(s.at(500 * kMs).throttle, 0.39 * 0.5, 1e-9);
    s.chip->drive(6, false, 900 * kMs);
    const double afterUp = s.at(2000 * kMs).throttle;
    EXPECT_NEAR(afterUp, 0.4, 1e-9);
    // Sampling more or less often does not change the integral.
    SimStick dense;
    ASSERT_EQ(dense.stick->open(&dense.error), 0);
    dense.chip->drive(6, true, 100 * kMs);
    dense.chip->drive(6, false, 900 * kMs);
    double last = 0;
    for (std::int64_t t = 0; t <= 2000 * kMs; t += 7 * kMs)
        last = dense.at(t).throttle;
    EXPECT_NEAR(last, afterUp, 1e-9);
    // Held long enough, the throttle saturates at +1, and throttle- brings it down.
    s.chip->drive(6, true, 3000 * kMs);
    EXPECT_EQ(s.at(10000 * kMs).throttle, 1.0);
    s.chip->drive(6, false, 10000 * kMs);
    s.chip->drive(7, true, 10000 * kMs);
    EXPECT_NEAR(s.at(11010 * kMs).throttle, 0.5, 1e-9);
}

TEST(GpioStick, ActiveLowLinesReadPressedWhenLow) {
    SimStick s(true);
    ASSERT_EQ(s.stick->open(&s.error), 0) << s.error;
    EXPECT_EQ(s.at(10 * kMs).pitch, 0.0);
    s.chip->drive(1, false, 20 * kMs);  // pulled low: pressed
    EXPECT_EQ(s.at(40 * kMs).pitch, 1.0);
}

TEST(GpioStick, HeldAtStartCountsAsPressed) {
    SimStick s;
    s.chip->drive(5, true, 0);
    ASSERT_EQ(s.stick->open(&s.error), 0) << s.error;
    EXPECT_TRUE(s.at(1 * kMs).trigger);
}

TEST(GpioStick, BadChipOrOffsetIsAClearError) {
    GpioStickConfig config;
    config.chip = "nochip";
    config.offsets = {1, 2, 3, 4, 5, 6, 7};
    GpioStick missing(config, std::make_unique<SimulatedGpioChip>("sim0", 8));
    std::string error;
    EXPECT_LT(missing.open(&error), 0);
    EXPECT_NE(error.find("nochip"), std::string::npos) << error;
    config.chip = "sim0";
    config.offsets = {1, 2, 3, 4, 5, 6, 40};
    GpioStick beyond(config, std::make_unique<SimulatedGpioChip>("sim0", 8));
    EXPECT_LT(beyond.open(&error), 0);
    EXPECT_NE(error.find("40"), std::string::npos) << error;
    EXPECT_EQ(beyond.sample(1.0).pitch, 0.0);
}

// The real libgpiod backend: a chip that does not exist is an error naming it (no hardware
// needed); with a /dev/gpiochip* present, an out-of-range offset is refused by name.
TEST(GpiodChipPort, RealLibrary) {
    std::string error;
    EXPECT_EQ(makeStick("gpiod:no-such-chip-xyz:1,2,3,4,5,6,7", &error), nullptr);
    EXPECT_NE(error.find("no-such-chip-xyz"), std::string::npos) << error;
    std::string chip;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator("/dev", ec)) {
        if (e.path().filename().string().rfind("gpiochip", 0) == 0) chip = e.path().string();
    }
    if (chip.empty()) GTEST_SKIP() << "no /dev/gpiochip*";
    auto port = makeGpiodChipPort();
    EXPECT_LT(port->request(chip, {100000}, false, "vig-test", &error), 0);
    EXPECT_NE(error.find("100000"), std::string::npos) << error;
}

}  // namespace
}  // namespace io
