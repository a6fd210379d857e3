// The output-file policy: what a path leads to, how it is written, a run's paths checked
// together, and the stop signals.
#include "io/output_file.hpp"

#include "base/error.hpp"
#include "io/file_sinks.hpp"
#include "io/image_file.hpp"
#include "io/stop_signals.hpp"
#include "io_test_util.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

std::string readAll(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

std::string checkError(const std::string& path) {
    std::string error;
    return io::checkOutputPath(path, &error) == 0 ? "" : error;
}

std::string runPathsError(const std::vector<io::PathUse>& uses) {
    try {
        io::checkRunPaths(uses);
    } catch (const base::InputError& e) {
        return e.what();
    }
    return "";
}

TEST(CheckOutputPath, AcceptsAWritableFolderAndLeavesNothingBehind) {
    const fs::path dir = io::test::scratchDir();
    const std::string path = (dir / "stats.json").string();
    EXPECT_EQ(checkError(path), "");
    EXPECT_TRUE(fs::is_empty(dir));
    { std::ofstream(path) << "keep"; }
    EXPECT_EQ(checkError(path), "");
    EXPECT_EQ(readAll(path), "keep");
    EXPECT_EQ(checkError("-"), "");
    EXPECT_EQ(checkError("/dev/null"), "");
}

TEST(CheckOutputPath, RefusesWhatCannotBeWritten) {
    const fs::path dir = io::test::scratchDir();
    EXPECT_NE(checkError((dir / "missing" / "a.json").string()).find("does not exist"),
              std::string::npos);
    EXPECT_NE(checkError(dir.string()).find("is a folder"), std::string::npos);
    EXPECT_NE(checkError("").find("empty path"), std::string::npos);
    // A folder that takes no new files, even for a privileged user.
    EXPECT_NE(checkError("/proc/vig_stats.json").find("cannot create files in /proc"),
              std::string::npos);
}

TEST(OutputFile, ADeviceIsWrittenInPlaceNeverReplaced) {
    const fs::path dir = io::test::scratchDir();
    const fs::path node = dir / "null";
    if (::mknod(node.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0) {
        GTEST_SKIP() << "mknod needs privileges here";
    }
    const std::vector<std::uint8_t> px(16 * 8 * 3, 200);
    std::string error;
    ASSERT_EQ(io::writePng8(node.string(), 16, 8, 3, px, &error), 0) << error;
    ASSERT_EQ(io::writeTextFile(node.string(), "{}\n", &error), 0) << error;
    struct stat st {};
    ASSERT_EQ(::stat(node.c_str(), &st), 0);
    EXPECT_TRUE(S_ISCHR(st.st_mode)) << "the device node was replaced";
    EXPECT_FALSE(fs::exists(dir / "null.part"));
}

TEST(OutputFile, ASymlinkIsFollowedNotReplaced) {
    const fs::path dir = io::test::scratchDir();
    fs::create_directories(dir / "real");
    const fs::path target = dir / "real" / "stats.json";
    { std::ofstream(target) << "old"; }
    fs::create_symlink(target, dir / "link.json");
    std::string error;
    ASSERT_EQ(io::writeTextFile((dir / "link.json").string(), "new", &error), 0) << error;
    EXPECT_TRUE(fs::is_symlink(dir / "link.json"));
    EXPECT_EQ(readAll(target), "new");
    // A dangling link: the file is made where it points.
    fs::create_symlink(dir / "real" / "made.json", dir / "dangling.json");
    ASSERT_EQ(io::writeTextFile((dir / "dangling.json").string(), "made", &error), 0) << error;
    EXPECT_TRUE(fs::is_symlink(dir / "dangling.json"));
    EXPECT_EQ(readAll(dir / "real" / "made.json"), "made");
}

TEST(OutputFile, AFifoWithNoReaderIsRefusedNotWaitedOn) {
    const fs::path dir = io::test::scratchDir();
    const fs::path fifo = dir / "pipe";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
    io::OutputFile out;
    std::string error;
    EXPECT_NE(out.open(fifo.string(), &error), 0);
    EXPECT_NE(error.find("no reader"), std::string::npos) << error;
    EXPECT_FALSE(fs::exists(dir / "pipe.part"));
}

TEST(OutputFile, AnUncommittedFileLeavesTheOldOneAndNoPart) {
    const fs::path dir = io::test::scratchDir();
    const fs::path path = dir / "frame.png";
    { std::ofstream(path) << "old"; }
    {
        io::OutputFile out;
        std::string error;
        ASSERT_EQ(out.open(path.string(), &error), 0) << error;
        std::fputs("half", out.get());
    }
    EXPECT_EQ(readAll(path), "old");
    EXPECT_FALSE(fs::exists(dir / "frame.png.part"));
}

TEST(CheckRunPaths, AnOutputOnAnInputIsRefusedInAnySpelling) {
    const fs::path dir = io::test::scratchDir();
    const fs::path height = dir / "v.png";
    { std::ofstream(height) << "height map"; }
    fs::create_symlink(height, dir / "alias.png");
    const std::string plain = height.string();
    const std::string dotted = (dir / "." / "v.png").string();
    for (const std::string& out : {plain, dotted, (dir / "alias.png").string()}) {
        const std::string e = runPathsError(
            {{"--height", plain, io::PathRole::Input}, {"--out", out, io::PathRole::Output}});
        EXPECT_NE(e.find("same file as the input --height"), std::string::npos) << out << ": " << e;
    }
    EXPECT_EQ(readAll(height), "height map");
}

TEST(CheckRunPaths, TwoOutputsOnOneFileAndTwoOnStandardOutputAreRefused) {
    const fs::path dir = io::test::scratchDir();
    const std::string x = (dir / "x").string();
    EXPECT_NE(runPathsError({{"--out", "y4m-path", io::PathRole::Output},
                             {"--contact", "y4m-path", io::PathRole::Output}})
                  .find("--contact y4m-path: is the same file as --out"),
              std::string::npos);
    EXPECT_NE(
        runPathsError({{"--out", "-", io::PathRole::Output}, {"--json", "-", io::PathRole::Output}})
            .find("standard output is already taken by --out"),
        std::string::npos);
    // A device may take several outputs; distinct files are fine.
    EXPECT_EQ(runPathsError({{"--out", "/dev/null", io::PathRole::Output},
                             {"--json", "/dev/null", io::PathRole::Output}}),
              "");
    EXPECT_EQ(runPathsError({{"--out", x, io::PathRole::Output},
                             {"--json", x + ".json", io::PathRole::Output},
                             {"--height", "", io::PathRole::Input}}),
              "");
    EXPECT_TRUE(io::usesStdout({{"--json", "-", io::PathRole::Output}}));
    EXPECT_FALSE(io::usesStdout({{"--height", "-", io::PathRole::Input}}));
}

TEST(CheckOutputFolder, ANonEmptyFolderNeedsOverwrite) {
    const fs::path dir = io::test::scratchDir();
    std::string error;
    EXPECT_EQ(io::checkOutputFolder((dir / "new").string(), false, &error), 0);
    EXPECT_EQ(io::checkOutputFolder(dir.string(), false, &error), 0);
    { std::ofstream(dir / "frame_000000.png") << "earlier run"; }
    EXPECT_NE(io::checkOutputFolder(dir.string(), false, &error), 0);
    EXPECT_NE(error.find("not empty"), std::string::npos) << error;
    EXPECT_NE(error.find("--overwrite"), std::string::npos) << error;
    EXPECT_EQ(io::checkOutputFolder(dir.string(), true, &error), 0);
}

// The first signal asks for a stop; the second cuts a record stream to whole records, renames
// it into place and ends the process with 128 + the first signal.
TEST(StopSignals, ASecondSignalLeavesWholeRecords) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const fs::path dir = io::test::scratchDir();
    const fs::path path = dir / "v.y4m";
    EXPECT_EXIT(
        {
            io::installStopSignals();
            io::OutputFile out;
            std::string error;
            if (out.open(path.string(), &error) != 0) std::_Exit(1);
            std::fputs("HEADER\n", out.get());                  // 7 bytes
            out.keepWholeRecordsOnAbort(7, 10);                 // records of 10 bytes
            std::fputs("0123456789abcdefghij0123", out.get());  // two whole and a torn one
            std::fflush(out.get());
            std::raise(SIGINT);
            if (!io::stopRequested() || io::exitStatusForStop() != 130) std::_Exit(2);
            std::raise(SIGTERM);
            std::_Exit(3);
        },
        ::testing::ExitedWithCode(130), "");
    EXPECT_EQ(readAll(path), "HEADER\n0123456789abcdefghij");
    EXPECT_FALSE(fs::exists(dir / "v.y4m.part"));
}

TEST(StopSignals, EndAtOnceRemovesUnfinishedFiles) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const fs::path dir = io::test::scratchDir();
    const fs::path path = dir / "stats.json";
    EXPECT_EXIT(
        {
            io::installStopSignals(true);
            io::OutputFile out;
            std::string error;
            if (out.open(path.string(), &error) != 0) std::_Exit(1);
            std::fputs("{\"half\":", out.get());
            std::fflush(out.get());
            std::raise(SIGTERM);
            std::_Exit(3);
        },
        ::testing::ExitedWithCode(143), "");
    EXPECT_FALSE(fs::exists(path));
    EXPECT_FALSE(fs::exists(dir / "stats.json.part"));
}

TEST(PngSink, RefusesAFolderWithAnEarlierRunUnlessOverwrite) {
    const fs::path dir = io::test::scratchDir();
    { std::ofstream(dir / "frame_000099.png") << "earlier"; }
    const io::VideoFormat format{16, 8, io::PixelFormat::Rgb8};
    std::string error;
    io::PngSink refused(dir.string(), 1);
    EXPECT_NE(refused.open(format, &error), 0);
    EXPECT_NE(error.find("not empty"), std::string::npos) << error;
    io::PngSink allowed(dir.string(), 1, true);
    EXPECT_EQ(allowed.open(format, &error), 0) << error;
    EXPECT_EQ(allowed.close(&error), 0) << error;
}

}  // namespace
