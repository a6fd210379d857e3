#include "base/text.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

TEST(Quoted, EscapesWhatIsNotPrintable) {
    EXPECT_EQ(base::quoted("abc"), "'abc'");
    EXPECT_EQ(base::quoted(std::string("a\0b\n", 4)), "'a\\x00b\\x0a'");
    EXPECT_EQ(base::quoted("it's"), "'it\\x27s'");
    EXPECT_EQ(base::quoted("\xff"), "'\\xff'");
}

TEST(Quoted, CutsLongInputAndSaysHowLong) {
    const std::string big(10 * 1024 * 1024, 'x');
    const std::string q = base::quoted(big);
    EXPECT_LT(q.size(), 260u);
    EXPECT_NE(q.find("(10485760 bytes)"), std::string::npos);
    EXPECT_EQ(base::quoted("abcdef", 3), "'abc...' (6 bytes)");
}

TEST(Number, ReadableForEveryMagnitude) {
    EXPECT_EQ(base::number(0.25), "0.25");
    EXPECT_EQ(base::number(-3.0), "-3");
    EXPECT_EQ(base::number(1e300), "1e+300");
    EXPECT_EQ(base::number(99.94, 3), "99.9");
    EXPECT_EQ(base::number(NAN), "nan");
    EXPECT_EQ(base::number(INFINITY), "inf");
}
