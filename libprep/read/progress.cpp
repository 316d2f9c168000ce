// Console progress for long reads: a redrawn bar on a terminal, plain lines
// (one per 10 %) when stderr is a file or a pipe, so CI logs stay readable.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <memory>

#include "prep/read.hpp"

namespace prep {

ProgressFn make_console_progress() {
  struct State {
    bool tty = isatty(fileno(stderr)) != 0;
    std::string label;
    int last_step = -1;  // 10 % steps (plain) or 2 % steps (bar)
  };
  auto state = std::make_shared<State>();
  return [state](double fraction, const std::string& label) {
    State& s = *state;
    if (label != s.label) {
      if (s.tty && !s.label.empty() && s.last_step < 50) std::fputc('\n', stderr);
      s.label = label;
      s.last_step = -1;
    }
    if (fraction < 0) return;  // unknown total: nothing to draw yet
    fraction = std::fmin(1.0, fraction);
    if (s.tty) {
      int step = static_cast<int>(fraction * 50);
      if (step == s.last_step) return;
      s.last_step = step;
      char bar[51];
      for (int i = 0; i < 50; ++i) bar[i] = i < step ? '#' : '.';
      bar[50] = 0;
      std::fprintf(stderr, "\r%-28.28s [%s] %3d%%", label.c_str(), bar,
                   static_cast<int>(fraction * 100));
      if (step == 50) std::fputc('\n', stderr);
    } else {
      int step = static_cast<int>(fraction * 10);
      if (step == s.last_step) return;
      s.last_step = step;
      std::fprintf(stderr, "%s: %d%%\n", label.c_str(), step * 10);
    }
    std::fflush(stderr);
  };
}

}  // namespace prep
