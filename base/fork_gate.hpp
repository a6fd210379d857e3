// Forking without exec while other threads run.
//
// A child forked from a process with several threads has only the thread that forked; every
// lock another thread held at that instant stays held in the child for ever. The C library's
// allocator guards itself, but not every allocator does (AddressSanitizer's, as shipped with
// GCC 12, takes no lock around fork), and a program's own locks are held in the child as the
// fork found them. So the threads that work in the background while the program forks (tile
// loaders, the ground's pager, the truth writer, terrain queries) hold a ForkGate::Working for
// each piece of work (their set-up included) and none while they wait, and are started by
// ForkGate::startThread; the fork itself is made inside a ForkGate::Closed, which waits until no
// Working is held and holds new ones back until the fork has returned. A thread that never waits
// on the gate (the field thread) must not allocate or share a lock with the child while a fork
// may happen, and no background thread ends while one may (they end when their owner is
// destroyed, after the run).
#pragma once

#include <functional>
#include <thread>

namespace base {

class ForkGate {
  public:
    // Held by a background thread for one piece of work. Waits while the gate is closed.
    // Nests within one thread.
    class Working {
      public:
        Working();
        ~Working();
        Working(const Working&) = delete;
        Working& operator=(const Working&) = delete;
    };

    // Held around fork(): waits until no Working is held, then holds new ones back. Must not
    // be taken by a thread that holds a Working (it would wait on itself: std::logic_error).
    class Closed {
      public:
        Closed();
        ~Closed();
        Closed(const Closed&) = delete;
        Closed& operator=(const Closed&) = delete;
    };

    // Starts a thread that no fork finds half started (a thread's start takes the runtime's
    // locks, the sanitizers' among them): the caller waits, as one piece of work, until the
    // new thread runs `body`.
    static std::thread startThread(std::function<void()> body);

    // In the child, first thing after fork: the gate open and unheld, its lock new (a thread of
    // the parent may have held it at the fork).
    static void resetInChild();

    // How many Working are held now (tests).
    static int working();
};

}  // namespace base
