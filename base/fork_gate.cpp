#include "base/fork_gate.hpp"

#include <condition_variable>
#include <mutex>
#include <new>
#include <stdexcept>

namespace base {
namespace {

struct Gate {
    std::mutex mutex;
    std::condition_variable changed;
    int working = 0;
    bool closed = false;
};

// Never destroyed: background threads may still pass the gate while statics are destroyed.
Gate& gate() {
    alignas(Gate) static unsigned char storage[sizeof(Gate)];
    static Gate* const g = new (storage) Gate;
    return *g;
}

thread_local int tDepth = 0;

}  // namespace

ForkGate::Working::Working() {
    if (tDepth++ > 0) return;
    Gate& g = gate();
    std::unique_lock lock(g.mutex);
    g.changed.wait(lock, [&] { return !g.closed; });
    ++g.working;
}

ForkGate::Working::~Working() {
    if (--tDepth > 0) return;
    Gate& g = gate();
    const std::lock_guard lock(g.mutex);
    if (--g.working == 0) g.changed.notify_all();
}

ForkGate::Closed::Closed() {
    if (tDepth > 0) throw std::logic_error("ForkGate: closed by a thread that is working");
    Gate& g = gate();
    std::unique_lock lock(g.mutex);
    g.changed.wait(lock, [&] { return !g.closed; });  // one closer at a time
    g.closed = true;
    g.changed.wait(lock, [&] { return g.working == 0; });
}

ForkGate::Closed::~Closed() {
    Gate& g = gate();
    const std::lock_guard lock(g.mutex);
    g.closed = false;
    g.changed.notify_all();
}

std::thread ForkGate::startThread(std::function<void()> body) {
    const Working starting;
    std::mutex mutex;
    std::condition_variable ran;
    bool running = false;
    std::thread thread([&mutex, &ran, &running, body = std::move(body)] {
        {
            // Notified under the lock: the caller, once it sees `running`, may return and
            // destroy both before this thread could touch them again.
            const std::lock_guard lock(mutex);
            running = true;
            ran.notify_one();
        }
        body();
    });
    std::unique_lock lock(mutex);
    ran.wait(lock, [&] { return running; });
    return thread;
}

void ForkGate::resetInChild() {
    // The child's only thread: nothing else can touch the gate while it is made anew.
    Gate& g = gate();
    new (&g) Gate;
    tDepth = 0;
}

int ForkGate::working() {
    Gate& g = gate();
    const std::lock_guard lock(g.mutex);
    return g.working;
}

}  // namespace base
