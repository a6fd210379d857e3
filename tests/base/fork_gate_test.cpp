#include "base/fork_gate.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>

namespace {

using namespace std::chrono_literals;

}  // namespace

TEST(ForkGate, ClosingWaitsForTheWorkUnderWayAndHoldsNewWorkBack) {
    std::atomic<int> stage{0};
    std::thread worker([&] {
        {
            const base::ForkGate::Working working;
            stage = 1;
            std::this_thread::sleep_for(100ms);
            stage = 2;
        }
        while (stage.load() < 3)
            std::this_thread::yield();
        const base::ForkGate::Working again;  // waits while the gate is closed
        stage = 5;
    });
    while (stage.load() < 1)
        std::this_thread::yield();
    {
        const base::ForkGate::Closed closed;
        EXPECT_EQ(stage.load(), 2);  // the work under way ended first
        EXPECT_EQ(base::ForkGate::working(), 0);
        stage = 3;
        std::this_thread::sleep_for(50ms);
        EXPECT_EQ(stage.load(), 3);  // new work waits
        stage = 4;
    }
    worker.join();
    EXPECT_EQ(stage.load(), 5);
    EXPECT_EQ(base::ForkGate::working(), 0);
}

TEST(ForkGate, WorkNestsAndAWorkingThreadCannotClose) {
    {
        const base::ForkGate::Working outer;
        {
            const base::ForkGate::Working inner;
            EXPECT_EQ(base::ForkGate::working(), 1);
        }
        EXPECT_EQ(base::ForkGate::working(), 1);
        EXPECT_THROW(base::ForkGate::Closed{}, std::logic_error);
    }
    EXPECT_EQ(base::ForkGate::working(), 0);
    const base::ForkGate::Closed closed;  // and now it can
}

TEST(ForkGate, AChildForkedWhileClosedFindsItOpen) {
    pid_t pid = -1;
    {
        const base::ForkGate::Closed closed;
        pid = fork();
        if (pid == 0) {
            base::ForkGate::resetInChild();
            // Work on a thread of the child's own, as a renderer's tile loader would.
            std::thread t([] { const base::ForkGate::Working working; });
            t.join();
            _exit(base::ForkGate::working() == 0 ? 0 : 1);
        }
    }
    ASSERT_GT(pid, 0);
    int status = 0;
    // A child that found the gate closed would wait for ever: give it 10 s.
    for (int i = 0; i < 1000 && waitpid(pid, &status, WNOHANG) == 0; ++i)
        std::this_thread::sleep_for(10ms);
    if (waitpid(pid, &status, WNOHANG) == 0) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        FAIL() << "the child waited on the gate";
    }
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST(ForkGate, AThreadIsNotStartedWhileClosedAndRunsOnceStarted) {
    std::atomic<bool> ran{false};
    std::atomic<bool> started{false};
    std::thread t;
    std::thread starter;
    {
        const base::ForkGate::Closed closed;
        starter = std::thread([&] {
            t = base::ForkGate::startThread([&] { ran = true; });
            started = true;
        });
        std::this_thread::sleep_for(50ms);
        EXPECT_FALSE(started.load());  // its start waits for the gate
    }
    starter.join();
    EXPECT_TRUE(started.load());
    t.join();
    EXPECT_TRUE(ran.load());
    EXPECT_EQ(base::ForkGate::working(), 0);
}
