// prep/interrupt.hpp — what a build undoes when SIGINT or SIGTERM stops it.
//
// A command that makes things on disk over a long run (a tileset build)
// calls watch_interrupts() before it starts any thread: SIGINT and SIGTERM
// are then blocked in every thread and one watcher thread waits for them
// (sigwait). When one comes, the watcher runs every registered cleanup,
// newest first, runs the handler a library installed for that signal, if
// any (prep/write.hpp's temp-file removal), prints what it did and ends the
// process with exit code 128 + the signal's number (130 for SIGINT, 143 for
// SIGTERM: prep::ExitCode::interrupted / terminated), the code a shell
// reports for a process that a signal stopped.
//
// Cleanups run on the watcher thread while the build's other threads may
// still be working: a cleanup must not wait for them and must tolerate
// files that come and go (rename a folder away before removing it).
// Without watch_interrupts() (the library used in-process, as by the
// tests) an OnInterrupt does nothing.
#pragma once

#include <functional>
#include <string>

namespace prep {

// Blocks SIGINT and SIGTERM in the calling thread (every thread it starts
// inherits the mask) and starts the watcher. Call once, from main's thread,
// before any other thread exists. Idempotent.
void watch_interrupts();

// Registers `cleanup` (with a line that says what it undoes, printed when it
// runs) for as long as the object lives. Thread-safe.
class OnInterrupt {
 public:
  OnInterrupt(std::string what, std::function<void()> cleanup);
  ~OnInterrupt();
  OnInterrupt(const OnInterrupt&) = delete;
  OnInterrupt& operator=(const OnInterrupt&) = delete;

 private:
  unsigned long id_ = 0;
};

}  // namespace prep
