// SIGINT / SIGTERM: undo what the build made, then exit 128 + signal
// (prep/files.hpp).
#include "prep/files.hpp"

#include <signal.h>
#include <unistd.h>

#include <cstdio>
#include <map>
#include <mutex>
#include <thread>
#include <utility>

namespace prep {

namespace {

struct Registry {
  std::mutex mutex;
  std::map<unsigned long, std::pair<std::string, std::function<void()>>> cleanups;
  unsigned long next = 1;
  bool watching = false;
};

Registry& registry() {
  // Never destroyed: the watcher may still use it while statics go.
  static Registry* r = new Registry;
  return *r;
}

sigset_t stop_signals() {
  sigset_t s;
  sigemptyset(&s);
  sigaddset(&s, SIGINT);
  sigaddset(&s, SIGTERM);
  return s;
}

[[noreturn]] void on_signal(int sig) {
  Registry& r = registry();
  // Held to the end: a cleanup being registered or removed meanwhile waits,
  // and the process ends before it could run.
  r.mutex.lock();
  const char* name = sig == SIGINT ? "SIGINT" : "SIGTERM";
  std::fprintf(stderr, "\ndecalprep: stopped by %s\n", name);
  for (auto it = r.cleanups.rbegin(); it != r.cleanups.rend(); ++it) {
    try {
      it->second.second();
      std::fprintf(stderr, "decalprep: %s\n", it->second.first.c_str());
    } catch (...) {
      std::fprintf(stderr, "decalprep: could not finish: %s\n", it->second.first.c_str());
    }
  }
  // A handler a library installed for this signal (the package writer's
  // removal of its named temp files) would never run while the signal is
  // blocked: run it here. It may re-raise the signal, which stays pending.
  struct sigaction current {};
  if (::sigaction(sig, nullptr, &current) == 0 && !(current.sa_flags & SA_SIGINFO) &&
      current.sa_handler != SIG_DFL && current.sa_handler != SIG_IGN)
    current.sa_handler(sig);
  std::fflush(stderr);
  ::_exit(128 + sig);
}

}  // namespace

void watch_interrupts() {
  Registry& r = registry();
  {
    std::lock_guard lock(r.mutex);
    if (r.watching) return;
    r.watching = true;
  }
  const sigset_t set = stop_signals();
  ::pthread_sigmask(SIG_BLOCK, &set, nullptr);
  std::thread([set] {
    int sig = 0;
    while (::sigwait(&set, &sig) != 0) {
    }
    on_signal(sig);
  }).detach();
}

OnInterrupt::OnInterrupt(std::string what, std::function<void()> cleanup) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  if (!r.watching) return;
  id_ = r.next++;
  r.cleanups.emplace(id_, std::make_pair(std::move(what), std::move(cleanup)));
}

OnInterrupt::~OnInterrupt() {
  if (id_ == 0) return;
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  r.cleanups.erase(id_);
}

}  // namespace prep
