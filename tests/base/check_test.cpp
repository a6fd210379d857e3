#include "base/check.hpp"

#include <gtest/gtest.h>

namespace {

int evaluations = 0;
int counted(int value) {
    ++evaluations;
    return value;
}

}  // namespace

TEST(Check, PassesWithoutEvaluatingTheMessage) {
    evaluations = 0;
    CHECK(counted(1) == 1) << counted(2);
    CHECK_LT(counted(1), 2) << counted(3);
    EXPECT_EQ(evaluations, 2);
}

TEST(CheckDeathTest, AbortsNamingFileLineConditionAndContext) {
    const int columns = 0;
    EXPECT_DEATH(CHECK(columns > 0) << "frame of " << columns << " columns",
                 "check_test.cpp:[0-9]+: check failed: columns > 0 frame of 0 columns");
    EXPECT_DEATH(CHECK_LE(3, columns), "check failed: .*\\(3 <= 0\\)");
}

TEST(CheckDeathTest, DcheckRunsOnlyWithoutNdebug) {
#ifdef NDEBUG
    evaluations = 0;
    DCHECK(counted(0) == 1);
    DCHECK_EQ(counted(0), 1);
    EXPECT_EQ(evaluations, 0);
#else
    EXPECT_DEATH(DCHECK_EQ(1, 2), "check failed");
#endif
}
