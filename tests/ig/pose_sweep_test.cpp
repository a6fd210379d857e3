#include "ig/pose_sweep.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "ig/error.hpp"
#include "ig/synthetic.hpp"

namespace ig {
namespace {

TEST(PoseList, ReadsPosesCommentsAndHeightsAboveTheTerrain) {
    const TerrainMap map = makeSyntheticTerrain(32, 5, 20.0);
    std::vector<int> lines;
    const std::vector<Pose> poses = parsePoseList(
        "# x,y,z,yaw,pitch,roll\n100,200,+50,90,-10,0\n\n 300 , 400 , 900 , 0 , 0 , 5 # end\n", map,
        "p.txt", &lines);
    ASSERT_EQ(poses.size(), 2u);
    EXPECT_EQ(lines, (std::vector<int>{2, 4}));
    EXPECT_DOUBLE_EQ(poses[0].position.z, map.surfaceHeight(100, 200) + 50);
    EXPECT_DOUBLE_EQ(poses[0].yaw, degToRad(90));
    EXPECT_DOUBLE_EQ(poses[1].position.x, 300);
    EXPECT_DOUBLE_EQ(poses[1].roll, degToRad(5));
}

TEST(PoseList, BadLinesNameTheLineAndQuoteBriefly) {
    const TerrainMap map = makeSyntheticTerrain(16, 5, 20.0);
    std::string binary(4096, '\0');
    for (std::size_t k = 0; k < binary.size(); ++k)
        binary[k] = static_cast<char>(k * 131 + 7);
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"1,2,3,4,5\n", "p.txt line 1: expected x,y,z,yaw,pitch,roll"},
        {"# c\n1,2,3,4,5,x\n", "p.txt line 2 roll: 'x' is not a finite number"},
        {"1,2,1e999,4,5,6\n", "p.txt line 1 z"},
        {"1,2,3,nan,5,6\n", "p.txt line 1 yaw"},
        {"# nothing\n", "p.txt: no poses"},
        {std::string(10 << 20, '5') + "x,0,0,0,0,0\n", "p.txt line 1 x: '555"},
        {std::string(10 << 20, ',') + "\n", "p.txt line 1: expected"},
        {binary, "p.txt line 1"},
    };
    for (const auto& [text, expect] : cases) {
        try {
            parsePoseList(text, map, "p.txt");
            ADD_FAILURE() << "accepted: " << text.substr(0, 100);
        } catch (const InputError& e) {
            const std::string msg = e.what();
            EXPECT_NE(msg.find(expect), std::string::npos) << msg.substr(0, 400);
            EXPECT_LE(msg.size(), 1024u) << msg.substr(0, 400);
            EXPECT_TRUE(std::all_of(msg.begin(), msg.end(), [](unsigned char c) {
                return c >= 0x20 && c < 0x7f;
            })) << msg.substr(0, 400);
            if (text.size() > 1000000) {
                EXPECT_LE(msg.size(), 300u) << msg;
            }
        }
    }
}

}  // namespace
}  // namespace ig
